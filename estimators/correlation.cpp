#include "estimators/correlation.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include "data/error.hpp"
#include "data/parallel.hpp"
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

int block_fft_length(int samples, int span) {
  if (samples < 1 || span < 0) {
    throw InputError("block FFT length: need samples >= 1 and span >= 0, got " +
                     std::to_string(samples) + " and " + std::to_string(span));
  }
  const long target = std::max(4L * span, 256L);
  long n = 256;
  while (n < target) n *= 2;
  const long whole = static_cast<long>(samples) + span;
  if (whole <= n) return smooth_fft_length(static_cast<int>(whole));
  if (n > std::numeric_limits<int>::max()) throw InputError("block FFT length: span too long");
  return static_cast<int>(n);
}

BlockedSignals::BlockedSignals(const Eigen::Ref<const Eigen::MatrixXd>& signals, int max_lag,
                               bool remove_mean) {
  add(signals);
  finish(max_lag, remove_mean);
}

BlockedSignals::BlockedSignals(const Eigen::Ref<const Eigen::MatrixXd>& first,
                               const Eigen::Ref<const Eigen::MatrixXd>& second, int max_lag,
                               bool remove_mean) {
  add(first);
  add(second);
  finish(max_lag, remove_mean);
}

void BlockedSignals::add(const Eigen::Ref<const Eigen::MatrixXd>& signals) {
  if (samples_ >= 0 && signals.rows() != samples_) {
    throw InputError("correlation: channels of " + std::to_string(samples_) + " and " +
                     std::to_string(signals.rows()) + " samples");
  }
  samples_ = static_cast<int>(signals.rows());
  for (Eigen::Index c = 0; c < signals.cols(); ++c) columns_.push_back(signals.col(c).data());
}

void BlockedSignals::finish(int max_lag, bool remove_mean) {
  max_lag_ = max_lag;
  if (max_lag < 0) {
    throw InputError("correlation: max_lag must be >= 0 samples, got " + std::to_string(max_lag));
  }
  if (samples_ < 1 || columns_.empty()) {
    throw InputError("correlation: need at least one sample and one channel, got " +
                     std::to_string(std::max(samples_, 0)) + " x " +
                     std::to_string(columns_.size()));
  }
  means_ = Eigen::RowVectorXd::Zero(channels());
  if (remove_mean) {
    for (int c = 0; c < channels(); ++c) {
      means_(c) = Eigen::Map<const Eigen::VectorXd>(columns_[c], samples_).mean();
    }
  }
}

void BlockedSignals::copy_centred(int c, int from, int length, Eigen::Ref<Eigen::VectorXd> out,
                                  int at) const {
  out.segment(at, length) =
      (Eigen::Map<const Eigen::VectorXd>(columns_[c] + from, length).array() - means_(c)).matrix();
}

namespace {

// Fixed groups of consecutive blocks (their number does not depend on the thread count).
constexpr int kBlockGroups = 4;

// Distinct values of `v` in increasing order, and each value's position among them.
std::vector<int> distinct(std::vector<int> v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}
int position(const std::vector<int>& sorted, int value) {
  return static_cast<int>(std::lower_bound(sorted.begin(), sorted.end(), value) - sorted.begin());
}

}  // namespace

Eigen::MatrixXd BlockedSignals::correlate(const std::vector<ChannelPair>& pairs) const {
  const int count = static_cast<int>(pairs.size());
  const int lags = 2 * max_lag_ + 1;
  const int s = samples();
  if (count == 0) return Eigen::MatrixXd(lags, 0);
  std::vector<int> firsts, seconds;
  for (const ChannelPair& pair : pairs) {
    if (pair.first < 0 || pair.first >= channels() || pair.second < 0 ||
        pair.second >= channels()) {
      throw InputError("correlation: channel pair (" + std::to_string(pair.first) + ", " +
                       std::to_string(pair.second) + ") out of range 0.." +
                       std::to_string(channels() - 1));
    }
    firsts.push_back(pair.first);
    seconds.push_back(pair.second);
  }
  firsts = distinct(firsts);
  seconds = distinct(seconds);
  // Block b: p over [b B, b B + B) zero-padded to n, q over [b B - L, b B + B + L) (zero outside
  // the record). With n >= B + 2L the circular correlation c(m) = sum_k p_b(k) q_b(k + m) has no
  // wrap-around for m = 0..2L and holds sum_k p(bB + k) q(bB + k + m - L): lag d = m - L.
  // The blocks are summed in up to kBlockGroups fixed groups of consecutive blocks in parallel,
  // each in block order, then the groups in order: the same result at any thread count.
  const int n = block_fft_length(s, 2 * max_lag_);
  const int block = n - 2 * max_lag_;
  const int blocks = (s + block - 1) / block;
  const int groups = std::min(blocks, kBlockGroups);
  std::vector<Eigen::MatrixXcd> group_sums(groups);
  data::parallel_for_groups(blocks, groups, [&](std::size_t g, int begin, int end) {
    RealFft first_fft(n, static_cast<int>(firsts.size()));
    RealFft second_fft(n, static_cast<int>(seconds.size()));
    Eigen::MatrixXd p_block(n, firsts.size());
    Eigen::MatrixXd q_block(n, seconds.size());
    Eigen::MatrixXcd& sums = group_sums[g];
    sums = Eigen::MatrixXcd::Zero(first_fft.bins(), count);
    for (int b = begin; b < end; ++b) {
      const int start = b * block;
      const int length = std::min(block, s - start);
      // Only the rows no sample is copied into are zeroed.
      p_block.bottomRows(n - length).setZero();
      for (std::size_t c = 0; c < firsts.size(); ++c) {
        copy_centred(firsts[c], start, length, p_block.col(c), 0);
      }
      // q's window [start - L, start - L + n) clipped to the record: rows [at, at + to - from).
      const int from = std::max(start - max_lag_, 0);
      const int to = std::min(start - max_lag_ + n, s);
      const int at = from - (start - max_lag_);
      q_block.topRows(at).setZero();
      q_block.bottomRows(n - at - (to - from)).setZero();
      for (std::size_t c = 0; c < seconds.size(); ++c) {
        copy_centred(seconds[c], from, to - from, q_block.col(c), at);
      }
      const Eigen::MatrixXcd p_spectra = first_fft.forward(p_block);
      const Eigen::MatrixXcd q_spectra = second_fft.forward(q_block);
      for (int c = 0; c < count; ++c) {
        sums.col(c) += p_spectra.col(position(firsts, pairs[c].first))
                           .conjugate()
                           .cwiseProduct(q_spectra.col(position(seconds, pairs[c].second)));
      }
    }
  });
  for (int g = 1; g < groups; ++g) group_sums[0] += group_sums[g];
  RealFft inverse(n, count);
  return inverse.inverse(group_sums[0]).topRows(lags) / static_cast<double>(s);
}

Eigen::MatrixXd BlockedSignals::convolve(const Eigen::Ref<const Eigen::MatrixXd>& kernels,
                                         int first_lag, int outputs) const {
  const int taps = static_cast<int>(kernels.rows());
  if (outputs < 1 || kernels.cols() % outputs != 0 || kernels.cols() / outputs > channels() ||
      taps < 1) {
    throw InputError("convolution: " + std::to_string(kernels.cols()) + " kernels of " +
                     std::to_string(taps) + " taps do not make " + std::to_string(outputs) +
                     " outputs of at most " + std::to_string(channels()) + " channels");
  }
  const int inputs = static_cast<int>(kernels.cols()) / outputs;
  const int s = samples();
  // Overlap-save in u = t - first_lag, where y = g * x (linear convolution over taps a = 0..K-1):
  // the outputs u in [u0, u0 + B) need x over [u0 - K + 1, u0 + B), a window of n = B + K - 1
  // samples (zero outside the record); entries m = K-1..n-1 of its circular convolution with the
  // zero-padded kernel are y at u = u0 + m - (K - 1). Output blocks are disjoint, so they run in
  // parallel and each output sample is computed once, the same way at any thread count.
  const int n = block_fft_length(s, std::max(taps - 1, 2 * max_lag_));
  const int block = n - taps + 1;
  RealFft kernel_fft(n, inputs * outputs);
  Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(n, inputs * outputs);
  padded.topRows(taps) = kernels;
  const Eigen::MatrixXcd kernel_spectra = kernel_fft.forward(padded);
  Eigen::MatrixXd y(s, outputs);
  const int blocks = (s + block - 1) / block;
  const int groups = std::min(blocks, kBlockGroups);
  data::parallel_for_groups(blocks, groups, [&](std::size_t, int begin, int end) {
    RealFft input_fft(n, inputs);
    RealFft output_fft(n, outputs);
    Eigen::MatrixXd x_window(n, inputs);
    Eigen::MatrixXcd products(input_fft.bins(), outputs);
    for (int b = begin; b < end; ++b) {
      const int t0 = b * block;  // first output sample of the block
      const int length = std::min(block, s - t0);
      const long w0 = static_cast<long>(t0) - first_lag - (taps - 1);  // x index of window row 0
      const long from = std::max(w0, 0L);
      const long to = std::min(w0 + n, static_cast<long>(s));
      if (to > from) {  // rows [from - w0, to - w0) hold samples, the others are zero
        x_window.topRows(from - w0).setZero();
        x_window.bottomRows(n - (to - w0)).setZero();
        for (int i = 0; i < inputs; ++i) {
          copy_centred(i, static_cast<int>(from), static_cast<int>(to - from), x_window.col(i),
                       static_cast<int>(from - w0));
        }
      } else {
        x_window.setZero();
      }
      const Eigen::MatrixXcd x_spectra = input_fft.forward(x_window);
      products.setZero();
      for (int j = 0; j < outputs; ++j) {
        for (int i = 0; i < inputs; ++i) {
          products.col(j) += x_spectra.col(i).cwiseProduct(kernel_spectra.col(i + inputs * j));
        }
      }
      y.middleRows(t0, length) = output_fft.inverse(products).middleRows(taps - 1, length);
    }
  });
  return y;
}

Correlations correlate(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                       const CorrelationOptions& options) {
  const BlockedSignals spectra(signals, options.max_lag, options.remove_mean);
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
