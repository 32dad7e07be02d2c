#include "estimators/decimate.hpp"

#include <boost/math/special_functions/bessel.hpp>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

DecimationOptions short_filter_decimation(int factor) {
  DecimationOptions options;
  options.factor = factor;
  options.half_taps_per_factor = 5;
  return options;
}

int filter_reach_samples(const DecimationOptions& options) {
  return options.factor > 1 ? options.half_taps_per_factor * options.factor : 0;
}

DecimationResult decimate(const Eigen::Ref<const Eigen::MatrixXd>& x, double sample_rate_hz,
                          const DecimationOptions& options) {
  if (options.factor < 1 || !(sample_rate_hz > 0.0) || options.half_taps_per_factor < 1) {
    throw InputError("decimation: factor must be >= 1 and the sample rate positive, got " +
                     std::to_string(options.factor));
  }
  const int d = options.factor;
  DecimationResult r;
  r.factor = d;
  r.sample_rate_hz = sample_rate_hz / d;
  if (d == 1) {
    r.samples = x;
    return r;
  }
  const int half = filter_reach_samples(options);
  const double fc = options.cutoff_fraction * 0.5 / d;  // cycles per input sample
  Eigen::VectorXd h(2 * half + 1);
  const double i0 = boost::math::cyl_bessel_i(0, options.kaiser_beta);
  for (int n = -half; n <= half; ++n) {
    const double sinc = n == 0 ? 1.0 : std::sin(2.0 * M_PI * fc * n) / (2.0 * M_PI * fc * n);
    const double q = static_cast<double>(n) / half;
    const double w =
        boost::math::cyl_bessel_i(0, options.kaiser_beta * std::sqrt(1.0 - q * q)) / i0;
    h(n + half) = sinc * w;
  }
  h /= h.sum();
  const int samples = static_cast<int>(x.rows());
  const int out = (samples + d - 1) / d;
  r.samples.resize(out, x.cols());
  r.edge_samples = (half + d - 1) / d;
  for (int i = 0; i < out; ++i) {
    const int c = i * d;
    const int lo = std::max(-half, -c), hi = std::min(half, samples - 1 - c);
    const double gain = h.segment(lo + half, hi - lo + 1).sum();
    r.samples.row(i) =
        h.segment(lo + half, hi - lo + 1).transpose() * x.middleRows(c + lo, hi - lo + 1) / gain;
  }
  return r;
}

}  // namespace stiffid::estimators
