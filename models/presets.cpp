#include "models/presets.hpp"

#include <cmath>
#include <string>

namespace stiffid::models {

namespace {
constexpr double kDeg = M_PI / 180.0;
// Perreault simulated in continuous time (Simulink) and sampled at 50 Hz: the 9 Hz forces are an
// analog filter's output, approximated by filtering at 10 x 50 Hz (see RandomForce::oversample).
constexpr int kPerreaultOversample = 10;
}  // namespace

Eigen::Vector2d perreault_posture_rad(int position) {
  static const double angles_deg[4][2] = {{63.0, 77.0}, {42.0, 63.0}, {102.0, 59.0}, {37.0, 127.0}};
  if (position < 1 || position > 4) {
    throw InputError("Perreault posture: expected a position 1..4 (Fig 6), got " +
                     std::to_string(position));
  }
  return {angles_deg[position - 1][0] * kDeg, angles_deg[position - 1][1] * kDeg};
}

Viscoelasticity perreault_joint_viscoelasticity() {
  Viscoelasticity e;
  e.kind = ElementKind::kelvin_voigt;
  e.stiffness = (Eigen::MatrixXd(2, 2) << 15.0, 5.0, 5.0, 12.0).finished();
  e.damping = (Eigen::MatrixXd(2, 2) << 0.6, 0.2, 0.2, 0.5).finished();
  return e;
}

TrialSpec perreault_arm_trial(int position) {
  TrialSpec spec;
  spec.model = ModelKind::arm;
  spec.duration_s = 60.0;
  spec.sample_rate_hz = 50.0;
  spec.task.kind = TaskKind::posture;
  spec.task.posture_by_angles = true;
  spec.task.posture_joint_rad = perreault_posture_rad(position);
  spec.joint = perreault_joint_viscoelasticity();
  spec.perturbations.random = true;
  spec.perturbations.random_force.oversample = kPerreaultOversample;
  return spec;
}

TrialSpec perreault_endpoint_trial(double coupling_percent, double snr_db) {
  TrialSpec spec;
  spec.model = ModelKind::endpoint;
  spec.duration_s = 60.0;
  spec.sample_rate_hz = 50.0;
  spec.endpoint = reference_endpoint_model();
  spec.perturbations.random = true;
  spec.perturbations.random_force.oversample = kPerreaultOversample;
  spec.perturbations.random_force.coupling_percent = coupling_percent;
  spec.noise.snr_db = snr_db;
  return spec;
}

namespace {
TrialSpec piovesan_base(TaskKind task, ProfileKind stiffness_profile, ProfileKind damping_profile) {
  TrialSpec spec;
  spec.model = ModelKind::arm;
  spec.duration_s = 5.0;
  spec.sample_rate_hz = 4000.0;
  spec.task.kind = task;
  spec.joint = piovesan_kelvin_voigt();
  spec.joint.stiffness_profile.kind = stiffness_profile;
  spec.joint.damping_profile.kind = damping_profile;
  return spec;
}
}  // namespace

TrialSpec piovesan_impulse_trial(TaskKind task, ProfileKind stiffness_profile,
                                 ProfileKind damping_profile, double direction_rad) {
  TrialSpec spec = piovesan_base(task, stiffness_profile, damping_profile);
  spec.perturbations.pulses.push_back(force_impulse(2.5, direction_rad));
  return spec;
}

TrialSpec piovesan_pulse_trial(TaskKind task, ProfileKind stiffness_profile,
                               ProfileKind damping_profile, double direction_rad, double onset_s) {
  TrialSpec spec = piovesan_base(task, stiffness_profile, damping_profile);
  spec.perturbations.pulses.push_back(force_pulse(onset_s, direction_rad));
  return spec;
}

TrialSpec piovesan_ramp_trial(TaskKind task, ProfileKind stiffness_profile,
                              ProfileKind damping_profile, double direction_rad, double onset_s) {
  TrialSpec spec = piovesan_base(task, stiffness_profile, damping_profile);
  DisplacementRamp ramp;
  ramp.onset_s = onset_s;
  ramp.direction_rad = direction_rad;
  spec.perturbations.ramps.push_back(ramp);
  return spec;
}

}  // namespace stiffid::models
