#pragma once
// Welch auto- and cross-spectral matrices of several channels (Welch 1967; Perreault et al. 1999,
// section 2, the spectra G_xx, G_xy of eqs 1-2), with the conventions of scipy.signal.csd:
// one-sided density scaling, average = mean, G_ab = E[conj(S_a) S_b].

#include <Eigen/Core>
#include <string>
#include <vector>

#include "data/trial.hpp"
#include "estimators/window.hpp"

namespace stiffid::estimators {

/// Trend removed from each segment before windowing (scipy.signal.detrend): none, the mean
/// (constant), or the least-squares straight line (linear).
enum class Detrend { none, constant, linear };

/// Parses "none" | "constant" | "linear"; throws InputError naming `flag` otherwise.
Detrend parse_detrend(const std::string& text, const std::string& flag = "detrend");
std::string to_string(Detrend detrend);

struct WelchOptions {
  int segment_length = 256;  ///< samples per segment (scipy nperseg), >= 2
  int fft_length = 0;    ///< samples per FFT (scipy nfft), 0 = segment_length; longer = zero pad
  double overlap = 0.5;  ///< fraction of a segment shared with the next, in [0, 1)
  Window window = Window::hann();  ///< periodic (DFT-even) samples, as scipy get_window
  Detrend detrend = Detrend::constant;
};

/// Samples shared by consecutive segments: floor(overlap * segment_length) of the double
/// product, i.e. Python's int(overlap * nperseg) passed to scipy as noverlap (scipy itself takes
/// an integer and truncates with int()). So 0.29 * 100 = 28.999999999999996 gives 28.
int overlap_samples(const WelchOptions& options);
/// FFT length actually used (fft_length, or segment_length when 0), samples.
int fft_length(const WelchOptions& options);
/// Segments averaged for `samples` samples: (samples - noverlap) / (nperseg - noverlap), rounded
/// down as scipy (trailing samples that do not fill a segment are ignored); 0 when too short.
int welch_segment_count(int samples, const WelchOptions& options);
/// Throws InputError naming the option when segment_length < 2, fft_length in (0, segment_length),
/// overlap outside [0, 1) or not finite.
void validate(const WelchOptions& options);

/// Welch's equivalent number of independent segments for overlapped, tapered segments
/// (Welch 1967 eq. 11; Percival & Walden 1993 eq. 292b): K / (1 + 2 sum_{m=1}^{K-1} (1 - m/K)
/// rho(m)^2), rho(m) = sum_n w[n] w[n + m step] / sum_n w[n]^2, for K segments of white noise.
/// Equals K without overlap; about 0.95 K for Hann with 50 % overlap.
double equivalent_independent_segments(int segments, const WelchOptions& options);
/// The same for segments of `segment_length` samples sharing `overlap_samples` samples, tapered by
/// the periodic `window`.
double equivalent_independent_segments(int segments, int segment_length, int overlap_samples,
                                       const Window& window);

/// Cross-spectral matrices of C channels at F = fft_length / 2 + 1 one-sided frequencies.
struct CrossSpectra {
  double sample_rate_hz = 0.0;   ///< Hz
  Eigen::VectorXd frequency_hz;  ///< [F] k fs / fft_length, Hz
  /// [F] of (C x C) Hermitian: g[f](a, b) = mean over segments of conj(S_a) S_b times
  /// 2 / (fs sum w^2) (1 / (fs sum w^2) at 0 Hz and, for even FFT lengths, at fs / 2), in
  /// (unit_a unit_b) / Hz, exactly scipy.signal.csd(s_a, s_b, scaling='density').
  std::vector<Eigen::MatrixXcd> g;
  int segments = 0;         ///< segments averaged, n_d
  int segment_length = 0;   ///< samples per segment
  int fft_length = 0;       ///< samples per FFT
  int overlap_samples = 0;  ///< samples shared by consecutive segments

  int bins() const { return static_cast<int>(frequency_hz.size()); }
  int channels() const { return g.empty() ? 0 : static_cast<int>(g.front().rows()); }
};

/// Welch cross-spectral matrices of the columns of `signals` (S samples x C channels) sampled at
/// `sample_rate_hz` (Hz). Segments of all channels go through one batched real-FFT plan
/// (RealFft, made once), 32 segments of every channel per call, and the cross products accumulate
/// per bin as they come, so memory stays O(C^2 F + 32 C fft_length) for any record length. Throws
/// InputError when S < segment_length (naming `source`), on bad options or a non-positive rate.
CrossSpectra welch_cross_spectra(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                                 double sample_rate_hz, const WelchOptions& options,
                                 const std::string& source = "signals");

/// The same for named channels of a trial, in the order given; too few samples for one segment
/// is an InputError from data::require_samples naming the trial's file.
CrossSpectra welch_cross_spectra(const data::Trial& trial, const std::vector<std::string>& channels,
                                 const WelchOptions& options);

}  // namespace stiffid::estimators
