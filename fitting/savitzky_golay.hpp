#pragma once
// Savitzky-Golay smoothing and derivatives (Savitzky & Golay 1964) on a block of samples, with the
// ends handled by evaluating the polynomial fitted to the first and last full window (as
// scipy.signal.savgol_filter with mode="interp"), so that only samples inside the block are used:
// the regressions differentiate the response inside their window and never across the onset.
// Fitting-local: replace by estimators/savitzky_golay.* if that module provides one.

#include <Eigen/Core>

namespace stiffid::fitting {

struct SavitzkyGolayResult {
  Eigen::MatrixXd value;   ///< (S x C) smoothed samples, units of x
  Eigen::MatrixXd first;   ///< (S x C) first derivative, units of x per s
  Eigen::MatrixXd second;  ///< (S x C) second derivative, units of x per s^2
};

/// Least-squares polynomial of degree `order` over `window` samples (odd, order < window <= S)
/// at spacing dt_s, evaluated with its derivatives at every sample. Throws InputError on a bad
/// window or order.
SavitzkyGolayResult savitzky_golay(const Eigen::MatrixXd& x, int window, int order, double dt_s);

}  // namespace stiffid::fitting
