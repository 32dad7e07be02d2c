#pragma once
// Stage 1 of the time-frequency identification (Piovesan et al. 2012 eqs 11-14): joint angle
// deviations delta theta(t) from the unperturbed trajectory, from the perturbation onset on.

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "data/trial.hpp"

namespace stiffid::estimators {

struct DeviationOptions {
  std::vector<std::string> angle_channels;  ///< joint angles (shoulder, elbow, ...): rad, or a
                                            ///< header unit [deg] or [mrad], converted
  std::vector<std::string> force_channels;  ///< perturbation forces, N (needed for auto onset)
  double onset_s = std::numeric_limits<double>::quiet_NaN();  ///< pulse onset, s; NaN = auto
  double onset_threshold = 0.1;  ///< auto onset: first sample where |f - median f| reaches this
                                 ///< fraction of its peak
  double pre_onset_s = 0.2;      ///< without a baseline: posture = mean angles over this span
                                 ///< before the onset, s
  double pulse_s = 0.02;         ///< pulse duration when the onset is given, s (auto: measured)
  bool analytic = false;         ///< also return the Hilbert transforms of the deviations
  double lead_s = 0.0;           ///< also keep up to this span before the onset (as far as the
                                 ///< trial and the baseline reach), e.g. for noise estimates, s
};

struct DeviationResult {
  double sample_rate_hz = 0.0;  ///< Hz
  double start_time_s = 0.0;    ///< time of row 0: the onset sample, or up to lead_s before, s
  double onset_s = 0.0;         ///< onset used, s
  double free_start_s = 0.0;    ///< end of the pulse: the free response starts here, s
  std::vector<std::string> channels;  ///< [n] angle channel names
  Eigen::MatrixXd
      deviation_rad;            ///< (S' x n) delta theta from start_time_s to the end of the trial
  Eigen::MatrixXd hilbert_rad;  ///< (S' x n) H[delta theta] when analytic, else empty
  Eigen::MatrixXd posture_rad;  ///< (S' x n) unperturbed angles theta_0(t)
  /// Without a baseline: why the pre-onset mean is not a rest posture (the joints move before the
  /// onset, as in a movement trial; posture_drift), else empty.
  std::string warning;
};

/// Whether `angles_rad` (P x n, the joint angles over the span before the onset whose mean is the
/// posture, rad, sampled every dt_s) move: per joint, the least-squares slope (rad/s) is more than
/// 10 standard errors from zero and, carried over `response_s` (the rest of the trial after the
/// onset, s), it moves the joint by more than a tenth of `peak_rad` (the largest |deviation| of
/// that joint after the onset, rad). Returns the message naming each such joint, or "".
std::string posture_drift(const Eigen::MatrixXd& angles_rad, double dt_s, double response_s,
                          const Eigen::VectorXd& peak_rad,
                          const std::vector<std::string>& channels);

/// Deviations from `baseline` (a trial with the same angle channels and rate covering the trial's
/// times, e.g. the mean of unperturbed repetitions) or, without one, from the mean of the angles
/// over the `pre_onset_s` before the onset (posture). Throws InputError naming the flag when a
/// channel is missing, the onset is outside the trial (or not found in the forces), the pre-onset
/// span or the baseline does not cover what is needed.
DeviationResult joint_deviation(const data::Trial& trial, const DeviationOptions& options,
                                const data::Trial* baseline = nullptr);

/// Onset of a force pulse: first sample where the norm of the force channels (medians removed)
/// reaches `threshold` x its peak; `end_s` receives the end of that supra-threshold run, s.
/// Throws InputError when the channels carry no pulse.
double detect_onset_s(const data::Trial& trial, const std::vector<std::string>& force_channels,
                      double threshold, double& end_s);

}  // namespace stiffid::estimators
