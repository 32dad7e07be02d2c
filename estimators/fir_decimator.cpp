#include "estimators/fir_decimator.hpp"

#include <cassert>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

FirDecimator::FirDecimator(double input_rate_hz, double output_rate_hz) {
  if (!(input_rate_hz > 0.0) || !(output_rate_hz > 0.0))
    throw InputError("decimation: rates must be positive, got " + std::to_string(input_rate_hz) +
                     " Hz in, " + std::to_string(output_rate_hz) + " Hz out");
  factor_ = std::max(1, static_cast<int>(std::lround(input_rate_hz / output_rate_hz)));
  output_rate_hz_ = input_rate_hz / factor_;
  if (factor_ == 1) {
    taps_ = Eigen::VectorXd::Ones(1);
    return;
  }
  constexpr double kAttenuationDb = 60.0;
  const double cutoff = 0.4 * output_rate_hz_ / input_rate_hz;       // cycles per input sample
  const double transition = 2.0 * M_PI * 0.4 * output_rate_hz_ / input_rate_hz;  // rad/sample
  const int order = static_cast<int>(std::ceil((kAttenuationDb - 7.95) / (2.285 * transition)));
  half_length_ = (order + 1) / 2;
  const double beta = 0.1102 * (kAttenuationDb - 8.7);
  const double norm = std::cyl_bessel_i(0.0, beta);
  taps_.resize(2 * half_length_ + 1);
  for (int n = -half_length_; n <= half_length_; ++n) {
    const double x = static_cast<double>(n) / half_length_;
    const double window = std::cyl_bessel_i(0.0, beta * std::sqrt(1.0 - x * x)) / norm;
    const double arg = 2.0 * M_PI * cutoff * n;
    const double sinc = n == 0 ? 2.0 * cutoff : std::sin(arg) / (M_PI * n);
    taps_(n + half_length_) = sinc * window;
  }
  taps_ /= taps_.sum();
}

Eigen::MatrixXd FirDecimator::filter_at(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                        const Eigen::Ref<const Eigen::VectorXi>& index) const {
  Eigen::MatrixXd y(index.size(), x.cols());
  const int length = static_cast<int>(taps_.size());
  for (Eigen::Index i = 0; i < index.size(); ++i) {
    const int first = index(i) - half_length_;
    assert(first >= 0 && first + length <= x.rows());
    y.row(i) = taps_.transpose() * x.middleRows(first, length);
  }
  return y;
}

}  // namespace stiffid::estimators
