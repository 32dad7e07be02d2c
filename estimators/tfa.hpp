#pragma once
// Time-frequency identification of time-varying joint stiffness and damping from one perturbed
// trial (Piovesan et al. 2012): deviations (stage 1), reassigned spectrogram (2), ridges (3),
// Savitzky-Golay smoothing (4), modal analysis (5) and normalised force (6). Issue 7's parametric
// method will replace stages 2-3 behind TfaOptions::method.

#include <string>

#include "data/trial.hpp"
#include "estimators/modal_analysis.hpp"
#include "estimators/normalized_force.hpp"
#include "estimators/reassigned_spectrogram.hpp"
#include "estimators/ridge.hpp"
#include "estimators/tfa_deviation.hpp"
#include "models/arm.hpp"

namespace stiffid::estimators {

enum class TfaMethod { spectrogram };

/// "spectrogram" -> TfaMethod; throws InputError naming --method otherwise.
TfaMethod parse_tfa_method(const std::string& text);
std::string to_string(TfaMethod method);

struct TfaOptions {
  TfaMethod method = TfaMethod::spectrogram;
  DeviationOptions deviation;                 ///< stage 1
  int decimation = 0;  ///< keep every D-th sample before the STFT (zero-phase FIR); 0 = auto: the
                       ///< largest divisor of the hop (in samples) leaving >= 8 x the ridge band's
                       ///< top frequency as sample rate
  ReassignedSpectrogramOptions spectrogram;   ///< stage 2 (band 0 = up to 2 x the ridge band top)
  RidgeOptions ridges;                        ///< stage 3 (modes = number of angle channels)
  ModalAnalysisOptions modal;                 ///< stages 4-5
  models::ArmParameters arm;                  ///< inertia M(theta) of eq 9
};

struct TfaResult {
  DeviationResult deviation;          ///< stage 1 at the trial's rate
  int decimation = 1;                 ///< D used
  double analysis_rate_hz = 0.0;      ///< rate of the analysed signal, Hz
  double region_begin_s = 0.0;        ///< first analysed instant (free response, filter settled), s
  double region_end_s = 0.0;          ///< last analysed instant, s
  ReassignedSpectrogram spectrogram;  ///< stage 2
  RidgeResult ridges;                 ///< stage 3
  ModalAnalysisResult modal;          ///< stages 4-5: K_theta(t), C_theta(t), P(t)
  NormalizedForceResult force;        ///< stage 6
  Status status;
};

/// Runs the pipeline on the angle channels of a planar two-link arm trial (2 joints, rad). Throws
/// InputError on bad input (missing channels, onset outside the trial, too short after the onset
/// for one window, options out of range); numerical failures are in `status`.
TfaResult identify_tfa(const data::Trial& trial, const TfaOptions& options,
                       const data::Trial* baseline = nullptr);

}  // namespace stiffid::estimators
