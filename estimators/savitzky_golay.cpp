#include "estimators/savitzky_golay.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

int savitzky_golay_window_samples(double window_s, double sample_rate_hz) {
  return 2 * static_cast<int>(std::lround(window_s * sample_rate_hz / 2.0)) + 1;
}

namespace {

void check_window(int window, int order, int derivative, double step, int position) {
  if (window < 1 || order < 0 || order >= window || derivative < 0 || !(step > 0.0) ||
      position < 0 || position >= window) {
    throw InputError("Savitzky-Golay: need window >= 1, 0 <= order < window (got window " +
                     std::to_string(window) + ", order " + std::to_string(order) +
                     "), derivative >= 0, step > 0 and the position inside the window");
  }
}

// The least-squares polynomial through a window, in z = (i - (window - 1) / 2) / scale with
// scale = max(1, (window - 1) / 2) (|z| <= 1 keeps the Vandermonde matrix well conditioned):
// its coefficients are a = fit x, fit ((order + 1) x window). One factorization serves every
// position and derivative: the fitted polynomial does not depend on where it is evaluated.
struct PolynomialFit {
  double scale = 1.0;
  Eigen::MatrixXd fit;
};

PolynomialFit polynomial_fit(int window, int order) {
  PolynomialFit f;
  f.scale = std::max(1.0, (window - 1) / 2.0);
  const double centre = (window - 1) / 2.0;
  Eigen::MatrixXd v(window, order + 1);
  for (int i = 0; i < window; ++i) {
    const double z = (i - centre) / f.scale;
    double p = 1.0;
    for (int k = 0; k <= order; ++k) {
      v(i, k) = p;
      p *= z;
    }
  }
  f.fit = v.colPivHouseholderQr().solve(Eigen::MatrixXd::Identity(window, window));
  return f;
}

// Weights of the derivative-th derivative at sample `position`:
// sum_{k >= d} k! / (k - d)! z^(k - d) fit.row(k) / (scale step)^d.
Eigen::VectorXd evaluate(const PolynomialFit& f, int derivative, double step, int position) {
  const int window = static_cast<int>(f.fit.cols());
  const int order = static_cast<int>(f.fit.rows()) - 1;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(window);
  if (derivative > order) return c;
  const double z = (position - (window - 1) / 2.0) / f.scale;
  double power = 1.0;  // z^(k - d)
  for (int k = derivative; k <= order; ++k) {
    double falling = 1.0;  // k! / (k - d)!
    for (int m = 0; m < derivative; ++m) falling *= k - m;
    c += (falling * power) * f.fit.row(k).transpose();
    power *= z;
  }
  return c / std::pow(f.scale * step, derivative);
}

}  // namespace

Eigen::VectorXd savitzky_golay_coefficients(int window, int order, int derivative, double step,
                                            int position) {
  check_window(window, order, derivative, step, position);
  return evaluate(polynomial_fit(window, order), derivative, step, position);
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
                     std::to_string(w) + ") for a window of " + number_text(options.window_s) +
                     " s (" + std::to_string(w) + " samples)");
  }
  if (samples < w) {
    throw InputError("Savitzky-Golay: " + std::to_string(samples) +
                     " samples are fewer than one window of " + std::to_string(w) + " samples (" +
                     number_text(options.window_s) + " s)");
  }
  const double step = 1.0 / sample_rate_hz;
  const int half = w / 2;
  SavitzkyGolayResult r;
  r.window_samples = w;
  const PolynomialFit fit = polynomial_fit(w, options.polynomial_order);
  Eigen::MatrixXd* out[3] = {&r.value, &r.first_derivative, &r.second_derivative};
  for (int d = 0; d < 3; ++d) {
    Eigen::MatrixXd& y = *out[d];
    y.resize(samples, x.cols());
    const Eigen::VectorXd centre = evaluate(fit, d, step, half);
    for (int i = half; i < samples - half; ++i) {
      y.row(i) = centre.transpose() * x.middleRows(i - half, w);
    }
    for (int pos = 0; pos < half; ++pos) {
      y.row(pos) = evaluate(fit, d, step, pos).transpose() * x.topRows(w);
      y.row(samples - 1 - pos) = evaluate(fit, d, step, w - 1 - pos).transpose() * x.bottomRows(w);
    }
  }
  return r;
}

}  // namespace stiffid::estimators
