#pragma once
// Digital Butterworth low-pass filters in second-order sections, designed like
// scipy.signal.butter(order, cutoff_hz, fs=sample_rate_hz, output="sos") (analog prototype,
// pre-warped bilinear transform) and applied causally like scipy.signal.sosfilt (zero initial
// state). Used for Perreault's band-limited random forces; usable by any module to its right.

#include <Eigen/Core>

namespace stiffid::models {

/// Second-order sections (K x 6), one row [b0 b1 b2 a0 a1 a2] (a0 = 1) per section, K = ceil(order
/// / 2), of a low-pass Butterworth filter with -3 dB cut-off `cutoff_hz` at `sample_rate_hz`.
/// Throws InputError when order < 1 or the cut-off is not in (0, sample_rate_hz / 2).
Eigen::MatrixXd butterworth_lowpass_sos(int order, double cutoff_hz, double sample_rate_hz);

/// Causal filtering of x (S) by the cascade of sections (K x 6), zero initial state.
Eigen::VectorXd sos_filter(const Eigen::MatrixXd& sos, const Eigen::VectorXd& x);

}  // namespace stiffid::models
