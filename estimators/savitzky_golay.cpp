#include "estimators/savitzky_golay.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

int savitzky_golay_window_samples(double window_s, double sample_rate_hz) {
  return 2 * static_cast<int>(std::lround(window_s * sample_rate_hz / 2.0)) + 1;
}

Eigen::VectorXd savitzky_golay_coefficients(int window, int order, int derivative, double step,
                                            int position) {
  if (window < 1 || order < 0 || order >= window || derivative < 0 || !(step > 0.0) ||
      position < 0 || position >= window) {
    throw InputError("Savitzky-Golay: need window >= 1, 0 <= order < window (got window " +
                     std::to_string(window) + ", order " + std::to_string(order) +
                     "), derivative >= 0, step > 0 and the position inside the window");
  }
  if (derivative > order) return Eigen::VectorXd::Zero(window);
  // Polynomial in z = (i - position) / scale; scaling keeps the Vandermonde matrix well
  // conditioned. The derivative-th coefficient times derivative! / (scale step)^derivative.
  const double scale = std::max(1.0, (window - 1) / 2.0);
  Eigen::MatrixXd v(window, order + 1);
  for (int i = 0; i < window; ++i) {
    const double z = (i - position) / scale;
    double p = 1.0;
    for (int k = 0; k <= order; ++k) {
      v(i, k) = p;
      p *= z;
    }
  }
  const Eigen::MatrixXd pinv =
      v.colPivHouseholderQr().solve(Eigen::MatrixXd::Identity(window, window));
  double factor = 1.0;
  for (int k = 2; k <= derivative; ++k) factor *= k;
  factor /= std::pow(scale * step, derivative);
  return pinv.row(derivative).transpose() * factor;
}

SavitzkyGolayResult savitzky_golay(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                   double sample_rate_hz, const SavitzkyGolayOptions& options) {
  if (!(sample_rate_hz > 0.0) || !(options.window_s > 0.0)) {
    throw InputError("Savitzky-Golay: sample rate and window (s) must be positive");
  }
  const int w = savitzky_golay_window_samples(options.window_s, sample_rate_hz);
  const int samples = static_cast<int>(x.rows());
  if (options.polynomial_order < 0 || options.polynomial_order >= w) {
    throw InputError("Savitzky-Golay: polynomial order " +
                     std::to_string(options.polynomial_order) + " must be in [0, " +
                     std::to_string(w) + ") for a window of " + std::to_string(options.window_s) +
                     " s (" + std::to_string(w) + " samples)");
  }
  if (samples < w) {
    throw InputError("Savitzky-Golay: " + std::to_string(samples) +
                     " samples are fewer than one window of " + std::to_string(w) + " samples (" +
                     std::to_string(options.window_s) + " s)");
  }
  const double step = 1.0 / sample_rate_hz;
  const int half = w / 2;
  SavitzkyGolayResult r;
  r.window_samples = w;
  Eigen::MatrixXd* out[3] = {&r.value, &r.first_derivative, &r.second_derivative};
  for (int d = 0; d < 3; ++d) {
    Eigen::MatrixXd& y = *out[d];
    y.resize(samples, x.cols());
    const Eigen::VectorXd centre =
        savitzky_golay_coefficients(w, options.polynomial_order, d, step, half);
    for (int i = half; i < samples - half; ++i) {
      y.row(i) = centre.transpose() * x.middleRows(i - half, w);
    }
    for (int pos = 0; pos < half; ++pos) {
      const Eigen::VectorXd c = savitzky_golay_coefficients(w, options.polynomial_order, d, step, pos);
      y.row(pos) = c.transpose() * x.topRows(w);
      const Eigen::VectorXd e =
          savitzky_golay_coefficients(w, options.polynomial_order, d, step, w - 1 - pos);
      y.row(samples - 1 - pos) = e.transpose() * x.bottomRows(w);
    }
  }
  return r;
}

}  // namespace stiffid::estimators
