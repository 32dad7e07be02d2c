#pragma once
// Time-frequency identification of time-varying joint stiffness and damping from one perturbed
// trial (Piovesan et al. 2012): deviations (stage 1), reassigned spectrogram (2), ridges (3),
// Savitzky-Golay smoothing (4), modal analysis (5) and normalised force (6); or, by default, the
// parametric `modal` method (issue 7, docs/tfa_modal.md): damped modes with shared time-varying
// frequency and decay fitted to the whole free response (damped_modes.hpp) in place of stages 2-4,
// and eq 48 (or the state-space inverse eigenproblem; modal_parameters.hpp) for stage 5.

#include <string>

#include "data/trial.hpp"
#include "estimators/damped_modes.hpp"
#include "estimators/modal_analysis.hpp"
#include "estimators/modal_parameters.hpp"
#include "estimators/normalized_force.hpp"
#include "estimators/reassigned_spectrogram.hpp"
#include "estimators/ridge.hpp"
#include "estimators/tfa_deviation.hpp"
#include "models/arm.hpp"

namespace stiffid::estimators {

enum class TfaMethod { modal, spectrogram };

/// "modal" or "spectrogram" -> TfaMethod; throws InputError naming --method otherwise.
TfaMethod parse_tfa_method(const std::string& text);
std::string to_string(TfaMethod method);

struct TfaOptions {
  TfaMethod method = TfaMethod::modal;
  DeviationOptions deviation;               ///< stage 1
  DampedModesOptions modes;                 ///< modal method: the fit (modes = angle channels)
  ModalParametersOptions modal_parameters;  ///< modal method: K, C from the tracks
  int decimation = 0;  ///< keep every D-th sample before the STFT (zero-phase FIR); 0 = auto: the
                       ///< largest divisor of the hop (in samples) leaving >= 8 x the ridge band's
                       ///< top frequency as sample rate
  ReassignedSpectrogramOptions spectrogram;  ///< stage 2 (band 0 = up to 2 x the ridge band top)
  RidgeOptions ridges;                       ///< stage 3 (modes = number of angle channels)
  ModalAnalysisOptions modal;                ///< stages 4-5
  models::ArmParameters arm;                 ///< inertia M(theta) of eq 9
};

struct TfaResult {
  DeviationResult deviation;          ///< stage 1 at the trial's rate
  int decimation = 1;                 ///< D used
  double analysis_rate_hz = 0.0;      ///< rate of the analysed signal, Hz
  double region_begin_s = 0.0;        ///< first analysed instant (free response, filter settled), s
  double region_end_s = 0.0;          ///< last analysed instant, s
  ReassignedSpectrogram spectrogram;  ///< stage 2 (spectrogram method; empty for modal)
  RidgeResult ridges;                 ///< stage 3 (modal method: the fitted tracks as ridges)
  DampedModesResult modes;            ///< modal method: the fit, with anr_db and valid per mode
  double noise_window_s = 0.0;        ///< modal method: the pre-onset span the noise covariance
                                      ///< came from, s (options.modes.noise_window_s, or less
                                      ///< when the trial holds less before the onset)
  std::string noise_warning;          ///< modal method: why noise_window_s is shorter than asked
  ModalParametersResult parameters;   ///< modal method: K, C and their validity per time
  ModalAnalysisResult modal;          ///< stages 4-5: K_theta(t), C_theta(t), P(t) (both methods)
  NormalizedForceResult force;        ///< stage 6
  Status status;
};

/// Runs the pipeline on the angle channels of a planar two-link arm trial (2 joints, rad). Throws
/// InputError on bad input (missing channels, onset outside the trial, too short after the onset
/// for one window, options out of range); numerical failures are in `status`.
TfaResult identify_tfa(const data::Trial& trial, const TfaOptions& options,
                       const data::Trial* baseline = nullptr);

}  // namespace stiffid::estimators
