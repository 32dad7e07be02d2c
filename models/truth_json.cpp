// truth_to_json: the truth of a simulated trial with unit-suffixed keys (docs/simulator.md).

#include <cmath>

#include "models/simulate.hpp"

namespace stiffid::models {

namespace {

using nlohmann::json;

json series_json(const Eigen::MatrixXd& series) {  // (S x k) -> [[...k values], ...]
  json out = json::array();
  for (Eigen::Index s = 0; s < series.rows(); ++s) {
    json row = json::array();
    for (Eigen::Index j = 0; j < series.cols(); ++j) row.push_back(series(s, j));
    out.push_back(std::move(row));
  }
  return out;
}

json matrix_series_json(const Eigen::MatrixXd& series, int n) {  // (S x n*n) -> [S][n][n]
  json out = json::array();
  for (Eigen::Index s = 0; s < series.rows(); ++s) {
    json m = json::array();
    for (int i = 0; i < n; ++i) {
      json row = json::array();
      for (int j = 0; j < n; ++j) row.push_back(series(s, i * n + j));
      m.push_back(std::move(row));
    }
    out.push_back(std::move(m));
  }
  return out;
}

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    json row = json::array();
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(std::move(row));
  }
  return rows;
}

json vector_json(const Eigen::VectorXd& v) {
  json out = json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

}  // namespace

json truth_to_json(const SimulationResult& result) {
  const Truth& t = result.truth;
  const bool arm = t.model == ModelKind::arm;
  const int n = t.dimension;
  json out;
  out["model"] = arm ? "arm" : "endpoint";
  out["coordinates"] = arm ? "joint" : "endpoint";
  out["dimension"] = n;
  out["integrator"] = integrator_kind_name(result.integrator);
  out["integrator_steps"] = result.steps;
  out["time_s"] = vector_json(t.time_s);
  out[arm ? "stiffness_nm_per_rad" : "stiffness_n_per_m"] = matrix_series_json(t.stiffness, n);
  out[arm ? "damping_nms_per_rad" : "damping_ns_per_m"] = matrix_series_json(t.damping, n);
  out[arm ? "inertia_kg_m2" : "inertia_kg"] = matrix_series_json(t.inertia, n);
  out["stiffness_profile"] = vector_json(t.stiffness_profile);
  out["damping_profile"] = vector_json(t.damping_profile);
  if (t.series_stiffness.size()) {
    out[arm ? "series_stiffness_nm_per_rad" : "series_stiffness_n_per_m"] =
        matrix_json(t.series_stiffness);
  }
  if (t.cubic_stiffness.size()) {
    out[arm ? "cubic_stiffness_nm_per_rad3" : "cubic_stiffness_n_per_m3"] =
        matrix_json(t.cubic_stiffness);
  }
  if (arm) {
    out["joint_angles_rad"] = series_json(t.position);
    out["joint_velocities_rad_per_s"] = series_json(t.velocity);
    out["reference_joint_angles_rad"] = series_json(t.reference_position);
    out["reference_joint_velocities_rad_per_s"] = series_json(t.reference_velocity);
    out["hand_position_m"] = series_json(t.hand_position_m);
    out["reference_hand_position_m"] = series_json(t.reference_hand_position_m);
    if (t.internal_state.size()) out["internal_state_rad"] = series_json(t.internal_state);
  } else {
    out["displacement_m"] = series_json(t.position);
    out["velocity_m_per_s"] = series_json(t.velocity);
    if (t.internal_state.size()) out["internal_state_m"] = series_json(t.internal_state);
  }
  out["applied_force_n"] = series_json(t.applied_force_n);
  json pulses = json::array();
  for (const ForcePulse& p : t.pulses) {
    pulses.push_back({{"onset_s", p.onset_s},
                      {"duration_s", p.duration_s},
                      {"amplitude_n", p.amplitude_n},
                      {"direction_rad", p.direction_rad}});
  }
  out["pulses"] = pulses;
  json ramps = json::array();
  for (const DisplacementRamp& r : t.ramps) {
    ramps.push_back({{"onset_s", r.onset_s},
                     {"amplitude_m", r.amplitude_m},
                     {"ramp_s", r.ramp_s},
                     {"plateau_s", r.plateau_s},
                     {"return_s", r.return_s},
                     {"direction_rad", r.direction_rad},
                     {"servo_stiffness_n_per_m", r.servo_stiffness_n_per_m},
                     {"servo_damping_ns_per_m", r.servo_damping_ns_per_m}});
  }
  out["ramps"] = ramps;
  out["noise_sigma_m"] = vector_json(t.noise_sigma);
  out["sdn_max_sigma_m"] = t.sdn_max_sigma;
  return out;
}

}  // namespace stiffid::models
