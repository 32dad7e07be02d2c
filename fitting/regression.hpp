#pragma once
// The classical regressions of arm impedance (Piovesan et al. 2012, "Regressive Techniques"):
// dF = M dx'' + B dx' + K dx about the unperturbed trajectory, from one perturbation per trial in
// several directions at each estimation time.
//   force-pulse  full regression (M, B, K) over the first 200 ms of a 5 N, 200 ms force pulse
//   disp-full    full regression (M, B, K) over the first 200 ms of an 8 mm ramp-and-hold
//   disp-ss      K only, from the last 50 ms of the ramp-and-hold plateau (dF = K dx)
// Endpoint values are turned into joint values at the posture with models/arm.hpp:
// K_theta = J^T K_x J + Omega(f) (Perreault 1999 eq 16, Piovesan eq 21; f the force the hand
// applies to the robot, -baseline force), B_theta = J^T B_x J, M_theta = J^T M_x J.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "data/trial.hpp"
#include "models/arm.hpp"

namespace stiffid::fitting {

enum class RegressionMethod { force_pulse, displacement_full, displacement_steady_state };

/// "force-pulse" | "disp-full" | "disp-ss"; anything else throws InputError naming `what`.
RegressionMethod parse_regression_method(const std::string& text,
                                         const std::string& what = "method");
std::string regression_method_name(RegressionMethod method);

/// Weighted least squares of the regression: rows of `regressors` (R x P) against `targets`
/// (R x D): theta (P x D) = argmin |regressors theta - targets|. Columns are scaled to unit norm
/// first; a reciprocal condition number below `min_rcond` (singular regressors) throws InputError
/// naming `what`.
Eigen::MatrixXd solve_regression(const Eigen::MatrixXd& regressors, const Eigen::MatrixXd& targets,
                                 const std::string& what, double min_rcond = 1e-9);

struct RegressionOptions {
  RegressionMethod method = RegressionMethod::force_pulse;
  std::optional<double> onset_s;    ///< onset of every trial, s; empty: detected from the force
  double full_window_s = 0.2;       ///< full regressions: samples in [onset, onset + this), s
  double steady_window_s = 0.05;    ///< disp-ss: the last this much of the plateau, s
  double ramp_s = 0.1;              ///< disp-ss: ramp duration of the servo perturbation, s
  double plateau_s = 0.1;           ///< disp-ss: plateau duration, s
  double baseline_s = 0.2;          ///< postural baseline = mean over this long before onset, s
  double group_tolerance_s = 0.05;  ///< trials whose onsets differ less than this form one group
  double savgol_window_s = 0.021;   ///< Savitzky-Golay window for dx', dx'' (odd samples >= 5), s
  int savgol_order = 4;             ///< Savitzky-Golay polynomial degree
  double profile_hz = 400.0;        ///< rate of the PCHIP time profile, Hz
  models::ArmParameters arm;        ///< arm for the Jacobian (Piovesan Table 1 by default)
};

/// One estimation time: the regression over one onset group.
struct RegressionEstimate {
  double onset_s = 0.0;                 ///< mean onset of the group's trials, s
  double time_s = 0.0;                  ///< centre of the regression window, s
  std::vector<std::string> trials;      ///< sources of the group's trials
  Eigen::Vector2d theta_rad;            ///< posture (shoulder, elbow), rad
  Eigen::Matrix2d k_endpoint_n_per_m;   ///< endpoint stiffness, N/m
  Eigen::Matrix2d b_endpoint_ns_per_m;  ///< endpoint damping, N s/m (full regressions)
  Eigen::Matrix2d m_endpoint_kg;        ///< endpoint inertia, kg (full regressions)
  Eigen::Matrix2d k_joint_nm_per_rad;   ///< joint stiffness, N m/rad
  Eigen::Matrix2d b_joint_nms_per_rad;  ///< joint damping, N m s/rad (full regressions)
  Eigen::Matrix2d m_joint_kg_m2;        ///< joint inertia, kg m^2 (full regressions)
  Eigen::Vector2d residual_rms_n;       ///< RMS of the force residual per axis (x, y), N
  bool full = true;                     ///< false for disp-ss (B and M not estimated)
};

/// Time profiles by PCHIP between estimation times (each matrix entry separately), on
/// t_s = first estimation time + k / profile_hz up to the last.
struct RegressionProfile {
  Eigen::VectorXd t_s;                              ///< [T] s
  std::vector<Eigen::Matrix2d> k_joint_nm_per_rad;  ///< [T]
  std::vector<Eigen::Matrix2d> b_joint_nms_per_rad;
  std::vector<Eigen::Matrix2d> k_endpoint_n_per_m;
  std::vector<Eigen::Matrix2d> b_endpoint_ns_per_m;
};

struct RegressionResult {
  RegressionMethod method = RegressionMethod::force_pulse;
  std::vector<RegressionEstimate> estimates;  ///< by increasing onset
  RegressionProfile profile;
};

/// Onset of the perturbation in a trial, s: the force deviation from its mean over the first
/// 50 ms is compared with a floor (5 standard deviations of that reference stretch, at least 1e-6
/// of the largest deviation); the onset is the first sample above the floor that belongs to the
/// rise to 5 % of the largest deviation. Throws InputError when the force never deviates.
double detect_onset_s(const data::Trial& trial);

/// Runs a regression over trials with columns t, th1, th2, x, y, fx, fy (fx, fy the force the
/// robot applies to the hand, N; x, y in m; th in rad). With `baseline` (same columns) the
/// unperturbed trajectory is that trial interpolated at each sample time; otherwise the mean over
/// baseline_s before each trial's onset. Throws InputError on missing columns, too few trials per
/// group (fewer directions than unknowns per force component: 6 for full, 2 for disp-ss), windows
/// outside a trial, or singular regressors.
RegressionResult regress(const std::vector<data::Trial>& trials, const data::Trial* baseline,
                         const RegressionOptions& options);

/// The JSON of `stiffid regress` (issue 8).
nlohmann::json to_json(const RegressionResult& result);

}  // namespace stiffid::fitting
