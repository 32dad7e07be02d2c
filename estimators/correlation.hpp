#pragma once
// Biased auto- and cross-correlations of sampled channels through zero-padded FFTs
// (Perreault et al. 1999, eq 8), and the padded spectra they come from, which the IRF estimator
// reuses for convolutions.
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
  int max_lag = 0;           ///< L, samples (>= 0): lags -L..L are returned
  bool remove_mean = true;   ///< subtract each channel's mean before correlating
};

/// Smallest FFT length >= `minimum` whose prime factors are 2, 3, 5 and 7 only (fast in FFTW).
int smooth_fft_length(int minimum);

/// One batched real FFT of all channels, each (optionally) mean-removed and zero-padded to
/// `fft_length() >= samples + max_lag`, so that products of these spectra give linear (not
/// circular) correlations for lags |d| <= max_lag and linear convolutions with kernels supported
/// on [-max_lag, max_lag] samples. Holds the spectra only: cheap to query many pair sets.
class PaddedSpectra {
 public:
  /// `signals`: (S x C) one channel per column, S >= 1 samples. Throws InputError when
  /// max_lag < 0 or when there is no sample or no channel.
  PaddedSpectra(const Eigen::Ref<const Eigen::MatrixXd>& signals, int max_lag,
                bool remove_mean = true);

  int samples() const { return samples_; }        ///< S, samples
  int channels() const { return channels_; }      ///< C
  int max_lag() const { return max_lag_; }        ///< L, samples
  int fft_length() const { return fft_length_; }  ///< n >= S + L, smooth
  /// (C) channel means that were removed (zeros when remove_mean is false), channel units.
  const Eigen::RowVectorXd& means() const { return means_; }
  /// (n/2+1 x C) one-sided spectra X_c[f] = sum_t x_c(t) exp(-2 pi i f t / n).
  const Eigen::MatrixXcd& spectra() const { return spectra_; }

  /// ((2L+1) x P) column p holds phi_{pairs[p].first, pairs[p].second}(d) at row d + L, from
  /// conj(X_p) X_q and one batched inverse FFT of all P products (eq 8). Throws InputError on a
  /// channel index out of range.
  Eigen::MatrixXd correlate(const std::vector<ChannelPair>& pairs) const;

 private:
  int samples_ = 0;
  int channels_ = 0;
  int max_lag_ = 0;
  int fft_length_ = 0;
  Eigen::RowVectorXd means_;
  Eigen::MatrixXcd spectra_;
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

/// Biased correlations (eq 8) of every ordered pair of columns of `signals` (S x C), through one
/// batched forward FFT, the C(C+1)/2 products p <= q and one batched inverse FFT; the pairs q > p
/// follow from phi_qp(d) = phi_pq(-d). O(C^2 n log n) with n ~ S + L, never O(S L).
Correlations correlate(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                       const CorrelationOptions& options);

}  // namespace stiffid::estimators
