#include "estimators/correlation.hpp"

#include <limits>
#include <string>

#include "data/error.hpp"
#include "estimators/fft.hpp"

namespace stiffid::estimators {

int smooth_fft_length(int minimum) {
  if (minimum <= 2) return 2;
  for (long n = minimum; n <= std::numeric_limits<int>::max(); ++n) {
    long m = n;
    for (const long p : {2L, 3L, 5L, 7L}) {
      while (m % p == 0) m /= p;
    }
    if (m == 1) return static_cast<int>(n);
  }
  throw InputError("FFT length: no 7-smooth length >= " + std::to_string(minimum) +
                   " fits in an int");
}

PaddedSpectra::PaddedSpectra(const Eigen::Ref<const Eigen::MatrixXd>& signals, int max_lag,
                             bool remove_mean)
    : samples_(static_cast<int>(signals.rows())),
      channels_(static_cast<int>(signals.cols())),
      max_lag_(max_lag) {
  if (max_lag < 0) {
    throw InputError("correlation: max_lag must be >= 0 samples, got " + std::to_string(max_lag));
  }
  if (samples_ < 1 || channels_ < 1) {
    throw InputError("correlation: need at least one sample and one channel, got " +
                     std::to_string(samples_) + " x " + std::to_string(channels_));
  }
  fft_length_ = smooth_fft_length(samples_ + max_lag_);
  means_ = remove_mean ? Eigen::RowVectorXd(signals.colwise().mean())
                       : Eigen::RowVectorXd::Zero(channels_);
  Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(fft_length_, channels_);
  padded.topRows(samples_) = signals.rowwise() - means_;
  RealFft fft(fft_length_, channels_);
  spectra_ = fft.forward(padded);
}

Eigen::MatrixXd PaddedSpectra::correlate(const std::vector<ChannelPair>& pairs) const {
  const int count = static_cast<int>(pairs.size());
  const int lags = 2 * max_lag_ + 1;
  if (count == 0) return Eigen::MatrixXd(lags, 0);
  // R_pq[f] = conj(X_p[f]) X_q[f] is the DFT of r(d) = sum_k p(k) q(k + d), stored at d mod n;
  // n >= S + L keeps lags |d| <= L free of circular wrap-around.
  Eigen::MatrixXcd products(spectra_.rows(), count);
  for (int c = 0; c < count; ++c) {
    const ChannelPair& pair = pairs[c];
    if (pair.first < 0 || pair.first >= channels_ || pair.second < 0 || pair.second >= channels_) {
      throw InputError("correlation: channel pair (" + std::to_string(pair.first) + ", " +
                       std::to_string(pair.second) + ") out of range 0.." +
                       std::to_string(channels_ - 1));
    }
    products.col(c) = spectra_.col(pair.first).conjugate().cwiseProduct(spectra_.col(pair.second));
  }
  RealFft fft(fft_length_, count);
  const Eigen::MatrixXd circular = fft.inverse(products);
  Eigen::MatrixXd phi(lags, count);
  const double scale = 1.0 / samples_;
  // Row d + L: d >= 0 from the head of the circular result, d < 0 from its tail.
  phi.bottomRows(max_lag_ + 1) = circular.topRows(max_lag_ + 1) * scale;
  phi.topRows(max_lag_) = circular.bottomRows(max_lag_) * scale;
  return phi;
}

Correlations correlate(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                       const CorrelationOptions& options) {
  const PaddedSpectra spectra(signals, options.max_lag, options.remove_mean);
  const int channels = spectra.channels();
  std::vector<ChannelPair> pairs;
  for (int p = 0; p < channels; ++p) {
    for (int q = p; q < channels; ++q) pairs.push_back({p, q});
  }
  const Eigen::MatrixXd upper = spectra.correlate(pairs);

  Correlations result;
  result.max_lag = options.max_lag;
  result.channels = channels;
  result.samples = spectra.samples();
  result.phi.resize(upper.rows(), static_cast<Eigen::Index>(channels) * channels);
  for (int c = 0; c < static_cast<int>(pairs.size()); ++c) {
    const auto [p, q] = pairs[c];
    result.phi.col(p + channels * q) = upper.col(c);
    result.phi.col(q + channels * p) = upper.col(c).reverse();  // phi_qp(d) = phi_pq(-d)
  }
  return result;
}

}  // namespace stiffid::estimators
