#pragma once
// Parametric time-varying modal fit of a free response (issue 7, the `modal` tfa method; see
// docs/tfa_modal.md): n damped oscillations whose angular frequency omega_j(t) and growth rate
// alpha_j(t) are shared by all channels, with slowly varying complex mode shapes, fitted to the
// whole post-onset record at once by variable projection on Ceres.
//
// Model, channel k, time tau from the first fitted sample (Piovesan 2012 eqs 5, 33, 39):
//   x_k(tau) = sum_j Re( a_jk(tau) exp(Phi_j(tau)) ) + sum_r b_rk exp(beta_r tau) + o_k
//              + s_k exp(2 Re Phi_J(tau)) + Re( h_k exp(2 Phi_J(tau)) ),
//   Phi_j(tau) = int_0^tau (alpha_j(s) + i omega_j(s)) ds,
// omega_j, alpha_j cubic B-splines (knots ~0.1 s), a_jk(tau) complex cubic B-splines with coarse
// knots whose changes are penalized (they stay constant unless the data ask otherwise), and
// optional real terms (non-oscillatory exponentials with constant rates beta_r and amplitudes b_rk:
// the slow creep of a Poynting-Thomson element's fibres, its real poles) and a constant offset o_k
// per channel (the error of the posture the deviations are taken from), and the second-order
// response of the strongest mode J (its square: a slow part at twice its decay and a second
// harmonic, from the arm's Coriolis and centripetal terms). The
// amplitudes a are linear and eliminated (variable projection, Golub & Pereyra 2003, with
// Kaufman's Jacobian); residuals are whitened by the pre-onset noise covariance.

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "estimators/matrix_pencil.hpp"
#include "estimators/ridge.hpp"

namespace stiffid::estimators {

/// The two designs of issue 7: (b) `whole`, the whole free response at once with spline tracks
/// (the default), and (a) `sliding`, one fit per window of sliding_window_s around each fitted
/// sample with locally linear omega_j, alpha_j and constant mode shapes (docs/tfa_modal.md).
enum class ModalDesign { whole, sliding };

/// "whole" or "sliding"; throws InputError otherwise. (Inline: the command line parses it in
/// programs that do not link the fit.)
inline ModalDesign parse_modal_design(const std::string& text) {
  if (text == "whole") return ModalDesign::whole;
  if (text == "sliding") return ModalDesign::sliding;
  throw InputError("--design: unknown design '" + text + "'; expected whole or sliding");
}
inline std::string to_string(ModalDesign design) {
  return design == ModalDesign::sliding ? "sliding" : "whole";
}

/// What the decay splines of the whole-record design are (docs/tfa_modal.md, "Damping tracks"):
/// alpha, the envelope decay alpha_j(t) itself (Re Phi_j = int alpha_j); gamma, the modal damping
/// -Gamma_j(t) (Re Phi_j = int(-Gamma_j) - ln(omega_j) / 2, the WKB amplitude of q'' + 2 Gamma
/// q' + eta^2 q = 0 with slowly changing eta; alpha_j = -Gamma_j - omega_j' / (2 omega_j)
/// follows, and the roughness prior and decay tie act on Gamma_j); best (the default), both fits
/// (run concurrently) and the one with the lower BIC kept (whitened residual and effective
/// number of parameters; alpha on a tie; docs/tfa_modal.md, "Choosing the damping tracks").
enum class DecayTracks { alpha, gamma, best };

/// "alpha", "gamma" or "best"; throws InputError otherwise.
inline DecayTracks parse_decay_tracks(const std::string& text) {
  if (text == "alpha") return DecayTracks::alpha;
  if (text == "gamma") return DecayTracks::gamma;
  if (text == "best") return DecayTracks::best;
  throw InputError("--decay-tracks: unknown value '" + text + "'; expected alpha, gamma or best");
}
inline std::string to_string(DecayTracks tracks) {
  return tracks == DecayTracks::alpha ? "alpha" : tracks == DecayTracks::gamma ? "gamma" : "best";
}

struct DampedModesOptions {
  int modes = 2;                            ///< n damped oscillations (degrees of freedom)
  ModalDesign design = ModalDesign::whole;  ///< whole record (b) or sliding windows (a)
  double sliding_window_s = 0.5;            ///< sliding design: window length, s (centred on each
                                  ///< fitted sample; the first and last half window of the
                                  ///< record have no estimate)
  double decimate_hz = 200.0;   ///< rate after zero-phase low-pass + decimation, Hz; <= 0:
                                ///< keep the input rate (no filter)
  double skip_s = 0.025;        ///< after the onset, not free (the pulse), s; the fit also
                                ///< starts the filter half-length later
  double noise_window_s = 1.0;  ///< before the onset, for the noise covariance, s (the
                                ///< tfa pipeline shortens it to what the trial holds)
  double knot_spacing_s = 0.1;  ///< knot spacing of omega_j(t), alpha_j(t), s
  DecayTracks decay_tracks = DecayTracks::best;  ///< design whole: alpha_j or -Gamma_j
                                                 ///< splines, or the fit of both with the
                                                 ///< lower BIC (DecayTracks); sliding: alpha_j
  double shape_knot_spacing_s = 0.5;  ///< knot spacing of the mode shapes a_jk(t), s; <= 0:
                                      ///< constant mode shapes
  double shape_weight = -1.0;         ///< lambda of the penalty on shape changes (whitened
                                      ///< units, dimensionless); < 0: chosen by GCV, and the
                                      ///< varying shapes kept only when their BIC beats the
                                      ///< constant shapes'
  double shape_phase_factor = 1.0;    ///< the shape penalty on changes of the phases between
                                      ///< joints, relative to that on the amplitude ratios
                                      ///< (> 0, dimensionless; 1: alike; docs/tfa_modal.md,
                                      ///< "Phase factor of the shape penalty")
  /// Mass metric of the channels at each of the fitted times t_s (one C x C matrix per time,
  /// symmetric positive definite; the tfa pipeline gives the arm's inertia M(theta_0(t)), kg
  /// m^2). Given, each mode's decay alpha_j
  /// and frequency omega_j are those of its modal coordinate, the mode's amplitude measured in
  /// this metric (q_j = |a_j(t)|_M, its phase the M-weighted mean of its channels'), not those
  /// of the fitted exponent alone: a mode shape that turns changes its amplitude along the
  /// constant part the fit holds fixed (docs/tfa_modal.md, "Modal amplitude"). Empty, or the
  /// sliding design (constant shapes in each window): the exponent's alpha_j, omega_j.
  std::function<std::vector<Eigen::MatrixXd>(const Eigen::VectorXd& t_s)> mass_metric;
  double track_roughness = -1.0;      ///< prior SD of second differences of the omega (rad/s)
                                      ///< and alpha (1/s) spline coefficients; < 0: from the
                                      ///< data over 0.003 .. 3 (continuation smooth -> rough),
                                      ///< rougher only while the BIC rule accepts the extra
                                      ///< effective parameters (docs/tfa_modal.md)
  double local_roughness_dof = 1.0;   ///< with track_roughness from the data: nu of the
                                      ///< Student-t prior (scale from the same grid, by the
                                      ///< same BIC rule) on the second differences of all
                                      ///< tracks at each knot, which lets the roughness vary
                                      ///< along the record: rough where the tracks bend
                                      ///< (a sharp stiffness change), smooth elsewhere. Tried
                                      ///< when the continuation chose tracks rougher than the
                                      ///< smoothest, kept when its BIC is lower (> 0,
                                      ///< dimensionless; 0: one roughness for the whole
                                      ///< record; docs/tfa_modal.md, "Local roughness")
  double lost_track_time_s = 0.3;     ///< design whole: a mode that sank into the noise
                                      ///< (its ANR below anr_threshold_db from some sample to
                                      ///< the end) has tracks the data no longer determine
                                      ///< there; omega_j and alpha_j are continued from its
                                      ///< last sample at or above the threshold with their
                                      ///< slopes decaying with this time constant, s (a damped
                                      ///< trend; 0: held constant; < 0: the splines' own
                                      ///< straight-line extrapolation). Those samples stay
                                      ///< invalid (docs/tfa_modal.md, "Lost modes")
  double decay_tie = 0.0;             ///< soft tie of the decay tracks, alpha_j(t) = rho_j
                                      ///< alpha_1(t) with rho_j fitted: prior SD of the
                                      ///< difference, relative to mode j's mean decay
                                      ///< (dimensionless); 0 (default): no tie; < 0: from the
                                      ///< data over 0.3 .. 0.003 (loose -> tight), tighter only
                                      ///< while the BIC rule accepts the lost fit. Opt-in: it
                                      ///< helps posture trials whose K and C change by a
                                      ///< common factor and hurts movement trials
                                      ///< (docs/tfa_modal.md)
  double frequency_tie = 0.0;         ///< soft tie of the frequency tracks, omega_j(t) =
                                      ///< rho_j omega_1(t) with rho_j fitted: prior SD of the
                                      ///< difference, relative to mode j's mean frequency
                                      ///< (dimensionless); 0 (default): no tie; < 0: from the
                                      ///< data as decay_tie (searched after it). Opt-in, as
                                      ///< decay_tie: it holds when stiffness changes by a
                                      ///< common factor; it costs k12 on some constant-K
                                      ///< posture trials and hurts movement trials
                                      ///< (docs/tfa_modal.md). With a tie taken, the untied
                                      ///< shape refit is still offered (shape_refit)
  double init_window_s = 0.5;         ///< sliding matrix-pencil windows for the start, s
  double init_max_rate_hz = 250.0;    ///< the start's matrix pencils work at this rate at most,
                                      ///< Hz: a fit at a higher rate (--decimate-hz above it)
                                      ///< hands them its samples low-passed and decimated
                                      ///< further (MatrixPencilOptions::max_rate_hz); 0: none
  double anr_threshold_db = 0.0;      ///< validity: amplitude-to-noise ratio at least this, dB
  double max_frequency_sd_hz = 0.1;   ///< validity: posterior SD of f_j(t) at most this, Hz
  double max_mode_to_data_db = 20.0;  ///< validity: a mode's power at most this far above the
                                      ///< whitened data power within +-0.25 s, dB (more: modes
                                      ///< cancelling each other)
  double min_mode_separation = 0.01;  ///< validity: two modes whose frequencies differ by less
                                      ///< than this fraction of their mean (or 2 SDs) are both
                                      ///< invalid there (merged tracks)
  int max_iterations = 100;           ///< Levenberg-Marquardt iterations per stage
  int real_terms = -1;                ///< R real terms b_k exp(beta_r tau) beside the modes
                                      ///< (constant rate beta_r, 1/s, and amplitudes); < 0
                                      ///< (default): the fewest (0 .. 2n) with which the start's
                                      ///< matrix pencil finds the n oscillatory poles (0 on a
                                      ///< Kelvin-Voigt arm; Poynting-Thomson trials need them)
  bool offsets = true;                ///< design whole: also fit a constant offset per
                                      ///< channel (linear), the error of the posture the
                                      ///< deviations are taken from (the 0.2 s pre-onset
                                      ///< mean), rad
  bool shape_refit = true;            ///< design whole, shapes and roughness from the data:
                                      ///< when the constant-shape continuation chose tracks
                                      ///< rougher than the smoothest, also fit smoother tracks
                                      ///< with the varying shapes from the start; kept when
                                      ///< its BIC is lower and its frequencies stay at least
                                      ///< 1 / (4 shape_knot_spacing_s) Hz apart
                                      ///< (docs/tfa_modal.md, "Shape refit")
  bool second_order = true;           ///< design whole: also fit the quadratic distortion of
                                      ///< the strongest mode j (the arm's Coriolis and
                                      ///< centripetal terms): s_k exp(2 Re Phi_j) + Re(h_k
                                      ///< exp(2 Phi_j)) per channel, linear amplitudes, kept
                                      ///< when they pay by the roughness rule
};

/// True when `o` asks for both decay models' fits, the lower BIC kept (DecayTracks::best with
/// the whole-record design; the sliding design has alpha_j splines only).
inline bool fits_both_decay_models(const DampedModesOptions& o) {
  return o.decay_tracks == DecayTracks::best && o.design == ModalDesign::whole;
}

/// One real term of the fit: b_k exp(beta tau), tau from the first fitted sample.
struct RealTerm {
  double rate_per_s = 0.0;     ///< beta, 1/s (< 0 decays)
  double rate_sd_per_s = 0.0;  ///< its posterior SD, 1/s
  Eigen::VectorXd amplitude;   ///< [C] b_k at the first fitted sample, channel units (rad)
};

/// One mode's tracks over the fitted times (T samples, C channels).
struct ModeTrack {
  Eigen::VectorXd frequency_hz;          ///< [T] f_j = omega_j / 2 pi, Hz
  Eigen::VectorXd omega_rad_per_s;       ///< [T] omega_j(t) = d/dt phase (eq 6), rad/s
  Eigen::VectorXd omega_dot_rad_per_s2;  ///< [T] d omega_j / dt, rad/s^2 (eqs 45-46)
  Eigen::VectorXd alpha_per_s;           ///< [T] alpha_j(t), 1/s; eq 47 sign (< 0 decays);
                                         ///< decay rate = -alpha_j
  Eigen::VectorXd alpha_dot_per_s2;      ///< [T] d alpha_j / dt, 1/s^2 (eq 46, corrected)
  Eigen::MatrixXcd shape;                ///< (T x C) a_jk(t): complex mode shape times modal
                                         ///< amplitude at tau = 0 (eq 38-39), channel units
  Eigen::MatrixXd envelope;              ///< (T x C) A_jk(t) = |a_jk| exp(Re Phi_j), channel units
  Eigen::MatrixXd phase_rad;             ///< (T x C) arg a_jk + Im Phi_j, continuous, rad
  Eigen::MatrixXd log_envelope_rate_per_s;  ///< (T x C) d/dt ln A_jk = alpha_j + d/dt ln|a_jk|
                                            ///< (eq 47 per channel), 1/s
  Eigen::VectorXd anr_db;           ///< [T] amplitude-to-noise ratio, dB (docs/tfa_modal.md)
  Eigen::VectorXd frequency_sd_hz;  ///< [T] posterior SD of f_j, Hz
  Eigen::VectorXd alpha_sd_per_s;   ///< [T] posterior SD of alpha_j, 1/s
  double decay_ratio = 1.0;         ///< rho_j of the decay tie: alpha_j(t) ~ rho_j times
                                    ///< the reference mode's (the start's lowest
                                    ///< frequency, ratio 1); 1 without a tie
  double frequency_ratio = 1.0;     ///< rho_j of the frequency tie: omega_j(t) ~ rho_j
                                    ///< times the reference mode's; 1 without a tie
  Eigen::Array<bool, Eigen::Dynamic, 1> valid;  ///< [T] fit converged; ANR, frequency SD, mode-to-
                                                ///< data power and separation within limits
};

struct DampedModesResult {
  Status status;                     ///< failure: start not found or the fit failed
  bool converged = false;            ///< Levenberg-Marquardt converged in max_iterations; when not,
                                     ///< the fit is returned with every valid flag false
  std::string warning;               ///< why converged is false, else empty
  Eigen::VectorXd t_s;               ///< [T] fitted sample times, s (same clock as the input)
  std::vector<ModeTrack> modes;      ///< [n] in ascending mean frequency
  double rate_hz = 0.0;              ///< sample rate of the fitted data, Hz
  Eigen::MatrixXd noise_covariance;  ///< (C x C) of the filtered pre-onset noise, channel units^2
  std::vector<RealTerm> real_terms;  ///< [R] slowest first; empty without real terms
  Eigen::VectorXd offset_rad;        ///< [C] fitted constant offset per channel (the posture's
                                     ///< error; zeros when not fitted), channel units (rad)
  int second_order_mode = -1;        ///< index in `modes` of the mode whose quadratic
                                     ///< distortion was fitted; -1: none
  Eigen::MatrixXd fitted;            ///< (T x C) the model at t_s (modes, real terms, offsets
                                     ///< and second-order terms), channel units
  Eigen::MatrixXd data;              ///< (T x C) filtered, decimated data at t_s, channel units
  MatrixPencilResult start;          ///< global matrix pencil over the fitted samples
  double shape_weight = 0.0;         ///< shape-change penalty used; 0: constant shapes (no
                                     ///< shape stage, or, with the weight from the data, the BIC
                                     ///< kept the constant-shape fit)
  bool shape_refit = false;          ///< the shape refit replaced the constant-shape continuation's
                                     ///< result (track_roughness and shape_weight are the refit's)
  double track_roughness = 0.0;      ///< track roughness prior SD used, rad/s and 1/s (with a
                                     ///< local roughness: the Student-t prior's scale)
  Eigen::VectorXd roughness_t_s;     ///< [K] with a local roughness: the knots at which it is
                                     ///< given (the middle knot of each second difference), s
                                     ///< (same clock as t_s); empty: one roughness throughout
  Eigen::VectorXd roughness_sd;      ///< [K] with a local roughness: the prior SD of the tracks'
                                     ///< second differences at roughness_t_s (the last EM
                                     ///< sweep's), rad/s and 1/s
  double decay_tie = 0.0;            ///< decay-tie prior SD used (relative); 0: none
  double frequency_tie = 0.0;        ///< frequency-tie prior SD used (relative); 0: none
  double residual_rms_whitened = 0.0;  ///< RMS whitened data residual (1 = noise level)
  /// Whole design: effective number of parameters of the fit (track coefficients by the trace
  /// of their linearized influence under the priors, linear amplitudes by the trace of their
  /// penalized smoother, plus a local roughness's bent knots); NaN for the sliding design.
  double effective_parameters = std::numeric_limits<double>::quiet_NaN();
  /// Whole design: BIC with the residual variance unknown, N ln(RSS) + ln(N) effective_parameters
  /// (N whitened data values, RSS their residual sum of squares); NaN for the sliding design.
  double bic = std::numeric_limits<double>::quiet_NaN();
  int iterations = 0;  ///< Levenberg-Marquardt iterations, all stages (with
                       ///< DecayTracks::best, of both fits)
  DecayTracks decay_tracks = DecayTracks::alpha;  ///< the decay splines of this fit (alpha or
                                                  ///< gamma)
  /// With DecayTracks::best: residual_rms_whitened and bic of the alpha and the gamma fit (NaN
  /// for a fit that failed); else all NaN. The fit with the lower BIC is kept.
  double alpha_residual_rms_whitened = std::numeric_limits<double>::quiet_NaN();
  double gamma_residual_rms_whitened = std::numeric_limits<double>::quiet_NaN();
  double alpha_bic = std::numeric_limits<double>::quiet_NaN();
  double gamma_bic = std::numeric_limits<double>::quiet_NaN();
};

/// Fits n damped modes to the free response in `deviation` ((S x C), channel units, typically
/// rad) sampled at `sample_rate_hz`, the first sample at `start_time_s`, after the pulse at
/// `onset_s` (same clock). Throws InputError when the record has fewer than noise_window_s before
/// the onset or fewer than 0.5 s of free response, or options are out of range.
DampedModesResult fit_damped_modes(const Eigen::Ref<const Eigen::MatrixXd>& deviation,
                                   double sample_rate_hz, double start_time_s, double onset_s,
                                   const DampedModesOptions& options);

/// The tracks in the form of the spectrogram method's ridges (ridge.hpp), so that stages 4-6 of the
/// tfa pipeline (modal_analysis.hpp, normalized_force.hpp) take either method: per mode j,
/// frequency_hz, omega_rad_per_s and decay_rate_per_s (= alpha_j, < 0 decays) as columns j,
/// amplitude[j] = A_jk(t), phase_rad[j], amplitude_c[j] = A_jk e^{i phase_jk}; bin = -1 (no
/// spectrogram); the status is the fit's.
RidgeResult as_ridges(const DampedModesResult& result);

}  // namespace stiffid::estimators
