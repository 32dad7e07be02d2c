#pragma once
// Stage 2 of the time-frequency identification (Piovesan et al. 2012, "The Spectrogram", eq 7):
// the short-time Fourier transform of every channel with the window h, the time-weighted window
// t h and the derivative window h' (edge steps included), and from their ratios the reassigned
// time and frequency of every bin (Auger & Flandrin 1995) and its local decay rate.

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "estimators/tfa_window.hpp"

namespace stiffid::estimators {

/// Uniformly sampled channels to analyse, with the region where they are valid (the free response
/// after a perturbation): frames are centred inside the region and their windows are cut at its
/// ends (with the edge steps of the cut in the derivative window), so no frame mixes in samples the
/// free-response model does not describe.
struct TfSignal {
  double sample_rate_hz = 0.0;  ///< Hz
  double start_time_s = 0.0;    ///< time of sample 0, s
  Eigen::MatrixXd real;         ///< (S x C) the channels (e.g. joint deviations, rad)
  Eigen::MatrixXd imag;         ///< (S x C) their Hilbert transforms for an analytic signal; empty
                                ///< for a real signal
  int begin = 0;                ///< first valid sample
  int end = -1;                 ///< one past the last valid sample; -1 = S

  bool analytic() const { return imag.size() > 0; }
};

struct ReassignedSpectrogramOptions {
  TfWindow window = TfWindow::kaiser(3.0);  ///< window shape h (Piovesan 2012: Kaiser, beta 3)
  double window_s = 0.75;                   ///< window length T, s (rounded to 2L + 1 samples)
  double hop_s = 0.0025;          ///< time between frame centres, s (rounded to whole samples)
  int fft_size = 0;               ///< FFT length N >= 2L + 1 (zero padding); 0 = next power of two
  double min_frequency_hz = 0.0;  ///< lowest bin kept, Hz
  double max_frequency_hz = 0.0;  ///< highest bin kept, Hz; 0 = Nyquist
};

/// STFTs and reassignment operators. Bin k of frame m is
/// X_h[k, m] = sum_n x[c_m + n] h[n] exp(-i 2 pi f_k n dt) (phase referred to the frame centre
/// c_m), so a damped exponential c exp(lambda (t - t_m)) gives exactly c W(lambda - i 2 pi f_k)
/// (SampledWindow::transform). Reassignment (Auger & Flandrin 1995 eqs 41-42, with the local
/// decay rate from the same ratio):
///   f^ = f_k - Im(X_dh / X_h) / (2 pi),  t^ = t_m + Re(X_th / X_h),  alpha^ = -Re(X_dh / X_h).
struct ReassignedSpectrogram {
  double sample_rate_hz = 0.0;  ///< Hz
  double hop_s = 0.0;           ///< s (whole samples)
  int hop_samples = 0;
  int fft_size = 0;   ///< N
  int first_bin = 0;  ///< FFT bin of frequency_hz(0)
  TfWindow window = TfWindow::kaiser(3.0);
  int half_length = 0;                           ///< L: the window has 2L + 1 samples, T = 2 L dt
  std::shared_ptr<const SampledWindow> sampled;  ///< the sampled h and h' (shared, immutable)
  bool analytic = false;  ///< the channels were analytic signals (no negative frequencies)

  Eigen::VectorXd time_s;        ///< [T] frame centres, s
  Eigen::VectorXi centre;        ///< [T] frame centre sample indices
  Eigen::VectorXi offset_lo;     ///< [T] first window offset used (>= -L; > -L when cut)
  Eigen::VectorXi offset_hi;     ///< [T] last window offset used (<= L)
  Eigen::VectorXd frequency_hz;  ///< [F] bin frequencies, Hz

  std::vector<Eigen::MatrixXcd> stft;              ///< [C] (F x T) X_h, channel units x samples
  std::vector<Eigen::MatrixXcd> stft_time;         ///< [C] (F x T) X_th, units x s
  std::vector<Eigen::MatrixXcd> stft_derivative;   ///< [C] (F x T) X_dh, units / s
  std::vector<Eigen::MatrixXd> reassigned_time_s;  ///< [C] (F x T) t^, s
  std::vector<Eigen::MatrixXd> reassigned_frequency_hz;  ///< [C] (F x T) f^, Hz
  std::vector<Eigen::MatrixXd> decay_rate_per_s;         ///< [C] (F x T) alpha^, 1/s (< 0: decay)
  Eigen::MatrixXd power;                                 ///< (F x T) sum over channels of |X_h|^2
  Eigen::MatrixXd reassigned_power;  ///< (F x T) |X_h|^2 summed at the bin and frame nearest to
                                     ///< (f^, t^), over channels: the reassigned spectrogram

  int frames() const { return static_cast<int>(time_s.size()); }
  int bins() const { return static_cast<int>(frequency_hz.size()); }
  int channels() const { return static_cast<int>(stft.size()); }
  /// The window of frame m as used (cut to the valid region).
  SampledWindow::Cut frame_window(int m) const;
};

/// Computes the three STFTs of every channel with batched FFTs of 16 frames at a time through one
/// plan made once (the buffers of a single batch of every frame run to hundreds of MB) and the
/// reassignment. Throws InputError when the valid region is shorter than one window (2L + 1
/// samples) or the options are out of range (window or hop not positive, FFT shorter than the
/// window, empty frequency band).
ReassignedSpectrogram reassigned_spectrogram(const TfSignal& signal,
                                             const ReassignedSpectrogramOptions& options);

}  // namespace stiffid::estimators
