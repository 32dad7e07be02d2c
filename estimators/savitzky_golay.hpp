#pragma once
// Savitzky-Golay smoothing and differentiation of uniformly sampled data (Savitzky & Golay 1964;
// Numerical Recipes 14.8, Piovesan et al. 2012 ref 75): at every sample, a least-squares
// polynomial of order p over a window of W = 2h + 1 samples, evaluated (or differentiated) there.
// Matches scipy.signal.savgol_coeffs / savgol_filter(mode="interp").

#include <Eigen/Core>

namespace stiffid::estimators {

struct SavitzkyGolayOptions {
  double window_s = 0.25;    ///< window length, s (rounded to an odd number of samples)
  int polynomial_order = 3;  ///< p, 0 <= p < window samples
};

/// Odd window length in samples for `window_s` at `sample_rate_hz`: 2 round(window_s fs / 2) + 1.
int savitzky_golay_window_samples(double window_s, double sample_rate_hz);

/// Weights c (length `window`) such that sum_i c[i] x[i] is the `derivative`-th derivative, at
/// sample `position` (0-based, inside the window), of the order-`order` least-squares polynomial
/// through x[0..window-1] sampled every `step` (units of x per step^derivative). With position =
/// window / 2 this is scipy.signal.savgol_coeffs(window, order, derivative, step, use="dot").
/// Throws InputError unless window >= 1, 0 <= order < window, derivative >= 0, step > 0.
Eigen::VectorXd savitzky_golay_coefficients(int window, int order, int derivative, double step,
                                            int position);

struct SavitzkyGolayResult {
  int window_samples = 0;
  Eigen::MatrixXd value;              ///< (S x C) smoothed samples, units of x
  Eigen::MatrixXd first_derivative;   ///< (S x C) units of x per s
  Eigen::MatrixXd second_derivative;  ///< (S x C) units of x per s^2
};

/// Smooths each column of x (S x C, sampled at `sample_rate_hz`) and differentiates it once and
/// twice. Interior samples use the centred window; the first and last W/2 samples use the
/// polynomial fitted to the first (last) W samples, evaluated at their positions (scipy's
/// mode="interp"). Throws InputError when S < W or the options are out of range.
SavitzkyGolayResult savitzky_golay(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                   double sample_rate_hz, const SavitzkyGolayOptions& options);

}  // namespace stiffid::estimators
