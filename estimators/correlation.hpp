#pragma once
// Biased auto- and cross-correlations of sampled channels through blocked FFTs
// (Perreault et al. 1999, eq 8), and the blocked convolutions the IRF estimator uses to predict
// outputs.
//
// Convention (as scipy/numpy users write it, and as the shared reference cases use it):
//   phi_pq(d) = 1/S sum_k p(k) q(k + d),   d = -L..L samples,
// with S the number of samples, the sum over the k where both samples exist (a biased estimate:
// always divided by S), and each channel's mean removed first (CorrelationOptions::remove_mean).
// Then phi_qp(d) = phi_pq(-d), and phi_pp(0) is the variance of p. Values are in the product of
// the two channels' units (e.g. N m for a force and a position).

#include <Eigen/Core>
#include <vector>

namespace stiffid::estimators {

/// Two channels (columns of a signal matrix) whose correlation phi_{first,second} is wanted.
struct ChannelPair {
  int first = 0;   ///< column index of p in phi_pq
  int second = 0;  ///< column index of q in phi_pq
};

struct CorrelationOptions {
  int max_lag = 0;          ///< L, samples (>= 0): lags -L..L are returned
  bool remove_mean = true;  ///< subtract each channel's mean before correlating
};

/// Smallest FFT length >= `minimum` whose prime factors are 2, 3, 5 and 7 only (fast in FFTW).
int smooth_fft_length(int minimum);

/// FFT length for block (overlap-add) products whose result spans `span` samples (>= 0) over a
/// record of `samples`: the smallest power of two >= max(4 span, 256), or the smooth length
/// >= samples + span when that is shorter (then the whole record is one block).
int block_fft_length(int samples, int span);

/// A record of C channels, optionally mean-removed, correlated and convolved in blocks: FFTs of a
/// fixed length n = block_fft_length(S, span) ~ 4-8 x the lag span (not ~S), whose per-block
/// spectral products are summed (overlap-add). The work is O(S log L) per channel, and the buffers
/// are a few hundred kB whatever the record's length (a 10-minute 1 kHz record with 600 lags uses
/// 8192-point FFTs instead of ~600,000-point ones: no large buffers to page-fault, and the
/// transforms run in cache). The results are the linear (never circular) sums of eq 8.
class BlockedSignals {
 public:
  /// Views `signals` (S x C, one channel per column, S >= 1 samples): no copy is made, so the
  /// caller keeps them alive and unchanged while this object is used (pass a matrix or a block
  /// of one, not an expression). `max_lag` L >= 0 samples. Throws InputError when max_lag < 0 or
  /// when there is no sample or no channel.
  BlockedSignals(const Eigen::Ref<const Eigen::MatrixXd>& signals, int max_lag,
                 bool remove_mean = true);
  /// Views the channels of `first` followed by those of `second` (both S rows), likewise.
  BlockedSignals(const Eigen::Ref<const Eigen::MatrixXd>& first,
                 const Eigen::Ref<const Eigen::MatrixXd>& second, int max_lag,
                 bool remove_mean = true);

  int samples() const { return samples_; }                            ///< S, samples
  int channels() const { return static_cast<int>(columns_.size()); }  ///< C
  int max_lag() const { return max_lag_; }                            ///< L, samples
  /// (C) channel means that were removed (zeros when remove_mean is false), channel units.
  const Eigen::RowVectorXd& means() const { return means_; }
  /// Channel c with its mean removed (S), channel units: an expression over the viewed samples.
  auto centred(int c) const {
    return (Eigen::Map<const Eigen::VectorXd>(columns_[c], samples_).array() - means_(c)).matrix();
  }

  /// ((2L+1) x P) column p holds phi_{pairs[p].first, pairs[p].second}(d) at row d + L (eq 8),
  /// from the sum over blocks of conj(X_p) Q_q (X_p a block of p zero-padded, Q_q the matching
  /// window of q widened by L on each side) and one batched inverse FFT of all P sums. Throws
  /// InputError on a channel index out of range.
  Eigen::MatrixXd correlate(const std::vector<ChannelPair>& pairs) const;

  /// (S x M) y_j(t) = sum_i sum_{a=0}^{K-1} kernels(a, i + N j) x_i(t - first_lag - a) for
  /// t = 0..S-1, with x_i centred channel i (i = 0..N-1, N = kernels.cols() / outputs) and zero
  /// outside the record: the discrete convolution of eq 1 with kernels supported on lags
  /// first_lag..first_lag+K-1 samples, by overlap-save of blocks. The blocks use the FFT length
  /// of correlate() (span 2L) whenever the kernel is no longer than that (an IRF's always is):
  /// one FFT size per object, so the process plans it once (FFTW's first plan of a size costs
  /// 3-8 ms on the benchmark machine). Throws InputError when the kernel columns do not match
  /// `outputs` and the channels.
  Eigen::MatrixXd convolve(const Eigen::Ref<const Eigen::MatrixXd>& kernels, int first_lag,
                           int outputs) const;

 private:
  void add(const Eigen::Ref<const Eigen::MatrixXd>& signals);
  void finish(int max_lag, bool remove_mean);
  // centred(c).segment(from, length) into out.segment(at, length).
  void copy_centred(int c, int from, int length, Eigen::Ref<Eigen::VectorXd> out, int at) const;

  int max_lag_ = 0;
  int samples_ = -1;
  std::vector<const double*> columns_;  ///< [C] first sample of each viewed channel
  Eigen::RowVectorXd means_;
};

/// All auto- and cross-correlations of a set of C channels over lags -L..L.
struct Correlations {
  int max_lag = 0;   ///< L, samples
  int channels = 0;  ///< C
  int samples = 0;   ///< S, the 1/S normalisation of eq 8
  /// ((2L+1) x C*C) column p + C*q holds phi_pq(d) at row d + L, in units of p times units of q.
  Eigen::MatrixXd phi;

  /// phi_pq(d) for d = -L..L ((2L+1)).
  Eigen::VectorXd pair(int p, int q) const { return phi.col(p + channels * q); }
  /// phi_pq(lag), |lag| <= L.
  double at(int p, int q, int lag) const { return phi(lag + max_lag, p + channels * q); }
};

/// Biased correlations (eq 8) of every ordered pair of columns of `signals` (S x C): the C(C+1)/2
/// pairs p <= q by BlockedSignals::correlate; the pairs q > p follow from phi_qp(d) = phi_pq(-d).
/// O(C^2 S log L), never O(S L).
Correlations correlate(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                       const CorrelationOptions& options);

}  // namespace stiffid::estimators
