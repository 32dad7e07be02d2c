#pragma once
// Effective number of parameters of a penalized (or Bayesian, Gaussian-prior) least-squares fit:
// the trace of its influence, tr(N^+ D) with D = J_d^T J_d the data part of the normal matrix and
// N = D + Q, Q = J_p^T J_p the penalty or prior part (Hastie & Tibshirani's degrees of freedom of
// a linear smoother; for a ridge penalty Q = lambda I it is sum_i s_i^2 / (s_i^2 + lambda), s_i
// the singular values of J_d). A parameter counts 1 when the data alone determine it, 0 when only
// the prior does, and 0 when neither does (a direction in the null space of N).

#include <Eigen/Core>

namespace stiffid::estimators {

/// tr(N^+ D), N = D + Q; D and Q symmetric positive semi-definite, P x P (only their lower
/// triangles are read). In [0, rank N] whatever the conditioning: N is scaled to unit diagonal
/// (which leaves the trace unchanged), factored by LDLT when its pivots stay above 1e-10 of the
/// largest, and pseudo-inverted through its eigen-decomposition otherwise, eigenvalues below
/// 1e-10 of the largest counted as zero (an LDLT of a numerically singular N gives traces like
/// 6e9 or -2e15). A parameter whose row of N is zero counts 0; one the data see, however weakly
/// against the other parameters' scale, and no prior does, counts 1.
double effective_parameters(const Eigen::Ref<const Eigen::MatrixXd>& data_normal,
                            const Eigen::Ref<const Eigen::MatrixXd>& prior_normal);

}  // namespace stiffid::estimators
