#pragma once
// Stage 3 of the time-frequency identification (Piovesan et al. 2012, eqs 5-6 and 33-36): ridges
// of the n modes through the reassigned spectrogram by dynamic programming, then at each frame the
// sub-bin angular frequency, decay rate, amplitude and phase of every mode in every channel.

#include <Eigen/Core>
#include <complex>
#include <vector>

#include "data/error.hpp"
#include "estimators/reassigned_spectrogram.hpp"

namespace stiffid::estimators {

struct RidgeOptions {
  int modes = 2;                       ///< n, number of ridges (degrees of freedom)
  double min_frequency_hz = 0.5;       ///< band searched, Hz
  double max_frequency_hz = 20.0;      ///< band searched, Hz
  double jump_penalty_per_hz = 2.0;    ///< DP cost of a frequency jump, per Hz per frame, in units
                                       ///< of the score (natural log of power)
  double max_jump_hz = 0.5;            ///< largest frequency change of a ridge between frames, Hz
  bool use_reassigned_power = true;    ///< track on the reassigned map (else on |X_h|^2)
  double power_floor_db = -120.0;      ///< power floor below the map's maximum, dB (log of zero)
  int fit_half_width_bins = 1;         ///< the frame model is fitted on bins ridge +- this many
  int refine_iterations = 12;          ///< rounds of interference cancellation for starting values
  double relaxation = 0.6;             ///< step of each round towards its new estimate, (0, 1]
  double min_mode_separation = 0.01;   ///< validity: modes whose frequencies differ by less than
                                       ///< this fraction of their mean are both invalid (merged)
  double outlier_window_s = 0.1;       ///< validity: a fit is compared with the median of its
  double outlier_hz = 0.25;            ///< mode's valid fits within this window, s, and is
                                       ///< invalid when further than outlier_hz from it, Hz
  Eigen::MatrixXd noise_covariance{};  ///< (C x C) noise covariance of the analysed channels,
                                       ///< channel units^2 (e.g. from before the onset); empty:
                                       ///< no amplitude-to-noise ratio, no such validity test
  double anr_threshold_db = 0.0;       ///< validity: amplitude-to-noise ratio at least this, dB
  double anr_floor_db = 100.0;         ///< the noise in the amplitude-to-noise ratio is at least
                                       ///< this far below the strongest mode's peak power per
                                       ///< channel, dB (noise-free data: a mode that has decayed
                                       ///< by more than this is noise)
  bool fit_chirp = true;               ///< frame model with chirps: each mode's lambda changes
                                       ///< linearly through the window (track_ridges)
  double chirp_min_gain = 30.0;        ///< pass 1 keeps a frame's chirped fit when it lowers the
                                       ///< sum of squares by more than this many expected noise
                                       ///< variances per real residual, per added unknown
  double chirp_min_window_fraction = 0.9;  ///< pass 1 fits chirp rates only in windows at least
                                           ///< this fraction of the full length
  double chirp_track_step_s = 0.01;        ///< frame fits about this far apart, s (at least every
                                           ///< frame; the frames between carry the nearest fit)
  double chirp_slope_window_s = 0.5;  ///< pass 2 holds the chirp rates at the slopes of pass 1's
                                      ///< lambda tracks, Savitzky-Golay (order 2) over this, s
  double max_misfit_fraction = 1e-3;  ///< validity, pass 2: a frame whose model misses more
  double max_misfit_noise = 50.0;     ///< than this fraction of the data's sum of squares at
                                      ///< the fit bins and more than max_misfit_noise expected
                                      ///< noise variances per real residual is invalid
  double max_mode_to_data_db = 6.0;   ///< validity: a mode's own part of the frame's STFT at the
                                      ///< fit bins at most this far above the STFT's energy
                                      ///< there, dB (more: modes cancelling each other; two
                                      ///< modes in one main lobe reach 4 dB legitimately)
};

/// Per-frame description of the modes. With lambda_j = alpha_j + i omega_j, the part of channel k
/// that belongs to mode j near frame m is Re(amplitude_c[j](m, k) exp(lambda_j (t - t_m))): a
/// damped cosine A_jk cos(omega_j (t - t_m) + phase_jk) (eqs 5, 35).
struct RidgeResult {
  Eigen::VectorXd time_s;            ///< [T] frame centres, s
  Eigen::MatrixXi bin;               ///< (T x n) DP path, index into the spectrogram's bins
  Eigen::MatrixXd frequency_hz;      ///< (T x n) f_j, Hz, ascending in j
  Eigen::MatrixXd omega_rad_per_s;   ///< (T x n) omega_j = 2 pi f_j, rad/s (eq 6)
  Eigen::MatrixXd decay_rate_per_s;  ///< (T x n) alpha_j from the reassignment, 1/s (< 0: decay)
  std::vector<Eigen::MatrixXd> amplitude;     ///< [n] of (T x C) A_jk, channel units (rad)
  std::vector<Eigen::MatrixXd> phase_rad;     ///< [n] of (T x C) phase of mode j in channel k
  std::vector<Eigen::MatrixXcd> amplitude_c;  ///< [n] of (T x C) complex amplitudes
  /// (T x n) amplitude-to-noise ratio of mode j at frame t, dB: 10 log10(a^H S^-1 a / 2), a the
  /// mode's complex amplitudes in the channels and S the noise covariance plus the floor of
  /// RidgeOptions::anr_floor_db on its diagonal (the mode's mean power per sample over the
  /// noise, in whitened units, as the modal method's anr_db); empty without
  /// RidgeOptions::noise_covariance.
  Eigen::MatrixXd anr_db;
  /// (T x n) mode j resolved at frame t: the frame fit converged, its frequency lies inside the
  /// ridge band (a fit that wanders off, e.g. onto a slow real pole at 0 Hz, is not a mode of the
  /// band), no other mode's fit is within min_mode_separation of it (two fits on one mode), its
  /// amplitude-to-noise ratio (when the noise is known) is at least anr_threshold_db (a mode
  /// that has decayed into the noise), the frame's fits keep the ridges' order (a fit that jumped
  /// onto or past another mode) and no mode's own part of the frame's STFT at the fit bins
  /// exceeds the STFT's energy there by more than max_mode_to_data_db (modes with large,
  /// cancelling amplitudes; these two make the frame invalid for every mode) and it
  /// is within outlier_hz of the median of the mode's valid fits around it. With fit_chirp also:
  /// the frame's chirped model does not miss the data (max_misfit_fraction, max_misfit_noise;
  /// invalid for every mode), and the mode's amplitude-to-noise ratio has not yet fallen below
  /// anr_threshold_db after its peak (a decayed mode does not come back). The values of an
  /// invalid frame, and of a frame whose fit failed, are bridged from the valid frames around it
  /// (omega, alpha and ln A linear, the phase along the integral of omega; continued from the
  /// nearest valid frame at the ends), so that stage 4's smoothing does not spread a bad fit.
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> valid;
  Status status;  ///< failure when a frame's fit failed and its mode has no valid frame to bridge
};

/// Joint DP over the n ridges b_1 < ... < b_n (modes never cross) maximising
/// sum_t sum_j ln(P(b_j, t) + floor) - penalty sum_t sum_j |f(b_j, t) - f(b_j, t - 1)|, with jumps
/// limited to max_jump_hz. At each frame, the modes are then refined from the STFT values: starting
/// from the reassigned frequency and decay at the ridge bins (channels weighted by |X_h|^2), the
/// complex amplitudes of all modes (and, for real signals, their negative-frequency images) are
/// fitted by least squares on the bins near the ridges with the exact window transform W, the
/// other components are subtracted from X_h and X_dh at each ridge bin, and the reassignment
/// equation Wd(s) / W(s) = X_dh / X_h is solved for lambda = s + i nu by Newton's method. For a sum
/// of n damped exponentials this recovers frequencies, decay rates and amplitudes exactly. With
/// fit_chirp the frame model gives each mode a chirp rate g_j (lambda_j + g_j u at offset u from
/// the frame centre): pass 1 on frames chirp_track_step_s apart keeps the fitted rates where they
/// lower the misfit by more than chirp_min_gain noise variances per unknown, the fit bins following
/// the fits; pass 2 refits those frames with the rates held at the smoothed slopes of pass 1's
/// tracks; the frames between carry the nearest fit's model (docs/tfa.md, "Chirped frame fits").
/// For a sum of n damped exponentials with lambdas linear in time this is exact.
/// Throws InputError on options out of range (modes < 1, band without n bins).
RidgeResult track_ridges(const ReassignedSpectrogram& spectrogram, const RidgeOptions& options);

/// Replaces the values of every invalid frame of a mode (valid(m, j) false) by those bridged from
/// its valid frames: between two valid frames, omega, alpha and ln A_jk are interpolated linearly
/// in time and the phase follows the integral of omega (its 2 pi branch matched at both ends);
/// before the first or after the last valid frame the nearest valid frame's mode is continued
/// (a exp(lambda dt)). The frames stay invalid. A mode without a valid frame keeps its values
/// where its fits resolved; only the frames whose fit failed are bridged, from those.
/// track_ridges calls it.
void bridge_invalid_frames(RidgeResult& ridges);

}  // namespace stiffid::estimators
