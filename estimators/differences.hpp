#pragma once
// First derivative of uniformly sampled data by central differences.

#include <Eigen/Core>

namespace stiffid::estimators {

/// d/dt of each column of x (rows: samples dt_s apart, s): central differences
/// (x[i+1] - x[i-1]) / (2 dt) inside, one-sided at the first and last rows; x's units per s.
/// Zero for a single row.
Eigen::MatrixXd central_differences(const Eigen::Ref<const Eigen::MatrixXd>& x, double dt_s);

}  // namespace stiffid::estimators
