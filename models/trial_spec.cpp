// TrialSpec::validate: impossible values of a trial spec, named by their JSON key path.

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

#include "models/simulate.hpp"

namespace stiffid::models {

namespace {

std::string where(const std::string& source, const std::string& key) {
  return source.empty() ? key : source + ": " + key;
}

void require_positive(const std::string& source, const std::string& key, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    std::ostringstream msg;
    msg << where(source, key) << ": expected a positive finite value, got " << value;
    throw InputError(msg.str());
  }
}

void require_non_negative(const std::string& source, const std::string& key, double value) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    std::ostringstream msg;
    msg << where(source, key) << ": expected a non-negative finite value, got " << value;
    throw InputError(msg.str());
  }
}

void require_finite(const std::string& source, const std::string& key, double value) {
  if (!std::isfinite(value)) throw InputError(where(source, key) + ": expected a finite value");
}

// Prefixes InputErrors of helpers (which name keys only) with the spec's source.
template <class F>
void with_source(const std::string& source, F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    if (source.empty()) throw;
    throw InputError(source + ": " + e.what());
  }
}

}  // namespace

void TrialSpec::validate() const {
  require_positive(source, "duration_s", duration_s);
  require_positive(source, "sample_rate_hz", sample_rate_hz);
  const long samples = std::lround(duration_s * sample_rate_hz);
  if (samples < 2) {
    throw InputError(where(source, "duration_s") +
                     ": the trial must hold at least 2 samples (duration_s * sample_rate_hz)");
  }
  if (samples > 100'000'000L) {
    throw InputError(where(source, "duration_s") + ": more than 1e8 samples requested");
  }
  const int n = dimension();
  if (model == ModelKind::arm) {
    with_source(source, [&] { arm.validate(); });
    if (task.kind == TaskKind::posture) {
      if (task.posture_by_angles) {
        require_finite(source, "task.joint_angles_deg", task.posture_joint_rad(0));
        if (!(task.posture_joint_rad(1) > 0.0 && task.posture_joint_rad(1) < M_PI)) {
          throw InputError(where(source, "task.joint_angles_deg") +
                           ": the elbow angle must lie in (0, 180) deg (flexed elbow)");
        }
      } else {
        with_source(source, [&] { inverse_kinematics(arm, task.posture_hand_m, "task.hand_m"); });
      }
    } else {
      require_positive(source, "task.rate_per_s", task.reach_rate_per_s);
      require_positive(source, "task.q", task.reach_q);
      if (!std::isnan(task.reach_midpoint_s)) {
        require_finite(source, "task.midpoint_s", task.reach_midpoint_s);
      }
      with_source(source, [&] {
        inverse_kinematics(arm, task.reach_start_m, "task.start_m");
        inverse_kinematics(arm, task.reach_target_m, "task.target_m");
        // The straight path must stay reachable: check it finely (the sigmoid covers it once).
        for (int k = 0; k <= 200; ++k) {
          const Eigen::Vector2d p =
              task.reach_start_m + (k / 200.0) * (task.reach_target_m - task.reach_start_m);
          inverse_kinematics(arm, p, "task (the straight path from start_m to target_m)");
        }
      });
    }
    with_source(source, [&] { joint.validate("viscoelasticity", Space::joint); });
    if (joint.dimension() != 2) {
      throw InputError(where(source, "viscoelasticity") + ": the arm needs 2 x 2 joint matrices");
    }
  } else {
    const Eigen::MatrixXd& i = endpoint.inertia_kg;
    if (i.rows() < 1 || i.rows() != i.cols() || !i.allFinite()) {
      throw InputError(where(source, "endpoint.inertia_kg") + ": expected a finite square matrix");
    }
    if ((i - i.transpose()).cwiseAbs().maxCoeff() >
        1e-12 * std::max(1.0, i.cwiseAbs().maxCoeff())) {
      throw InputError(where(source, "endpoint.inertia_kg") + ": expected a symmetric matrix");
    }
    if (!(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(i).eigenvalues().minCoeff() > 0.0)) {
      throw InputError(where(source, "endpoint.inertia_kg") +
                       ": expected a positive definite inertia (positive masses)");
    }
    with_source(source, [&] { endpoint.element.validate("endpoint", Space::endpoint); });
    if (endpoint.element.dimension() != n) {
      throw InputError(where(source, "endpoint") +
                       ": stiffness and inertia matrices must have the same size");
    }
  }
  const char* unit = model == ModelKind::arm ? "rad" : "m";
  if (initial_deviation.size() != 0 && initial_deviation.size() != n) {
    throw InputError(where(source, std::string("initial.deviation_") + unit) + ": expected " +
                     std::to_string(n) + " values");
  }
  if (initial_deviation_rate.size() != 0 && initial_deviation_rate.size() != n) {
    throw InputError(where(source, std::string("initial.rate_") + unit + "_per_s") + ": expected " +
                     std::to_string(n) + " values");
  }
  if (!initial_deviation.allFinite() || !initial_deviation_rate.allFinite()) {
    throw InputError(where(source, "initial") + ": expected finite values");
  }

  const double end = (samples - 1) / sample_rate_hz;
  for (std::size_t k = 0; k < perturbations.pulses.size(); ++k) {
    const ForcePulse& p = perturbations.pulses[k];
    const std::string key = "perturbations[" + std::to_string(k) + "].";
    require_non_negative(source, key + "onset_s", p.onset_s);
    if (p.onset_s > end) {
      throw InputError(where(source, key + "onset_s") + ": the onset lies after the trial's end");
    }
    require_positive(source, key + "duration_s", p.duration_s);
    require_finite(source, key + "amplitude_n", p.amplitude_n);
    require_finite(source, key + "direction_deg", p.direction_rad);
  }
  for (std::size_t k = 0; k < perturbations.ramps.size(); ++k) {
    const DisplacementRamp& r = perturbations.ramps[k];
    const std::string key =
        "perturbations[" + std::to_string(perturbations.pulses.size() + k) + "].";
    require_non_negative(source, key + "onset_s", r.onset_s);
    if (r.onset_s > end) {
      throw InputError(where(source, key + "onset_s") + ": the onset lies after the trial's end");
    }
    require_finite(source, key + "amplitude_m", r.amplitude_m);
    require_positive(source, key + "ramp_s", r.ramp_s);
    require_non_negative(source, key + "plateau_s", r.plateau_s);
    require_positive(source, key + "return_s", r.return_s);
    require_finite(source, key + "direction_deg", r.direction_rad);
    require_positive(source, key + "servo_stiffness_n_per_m", r.servo_stiffness_n_per_m);
    require_non_negative(source, key + "servo_damping_ns_per_m", r.servo_damping_ns_per_m);
    if (model == ModelKind::endpoint && n > 2) {
      throw InputError(where(source, key + "kind") + ": ramp_and_hold acts in a plane (n <= 2)");
    }
  }
  if (perturbations.random) {
    const RandomForce& f = perturbations.random_force;
    const std::string key = "perturbations[random_force].";
    require_positive(source, key + "bandwidth_hz", f.bandwidth_hz);
    if (!(f.bandwidth_hz < 0.5 * sample_rate_hz)) {
      throw InputError(where(source, key + "bandwidth_hz") +
                       ": must lie below the Nyquist frequency sample_rate_hz / 2");
    }
    if (f.filter_order < 1 || f.filter_order > 20) {
      throw InputError(where(source, key + "filter_order") + ": expected an order in [1, 20]");
    }
    if (f.oversample < 1 || f.oversample > 64) {
      throw InputError(where(source, key + "oversample") + ": expected a factor in [1, 64]");
    }
    if (!(f.coupling_percent >= 0.0 && f.coupling_percent <= 100.0)) {
      throw InputError(where(source, key + "coupling_percent") + ": expected a value in [0, 100]");
    }
    require_non_negative(source, key + "peak_to_peak_n", f.peak_to_peak_n);
    require_non_negative(source, key + "rms_n", f.rms_n);
    require_non_negative(source, key + "warmup_s", f.warmup_s);
  }
  if (std::isnan(noise.snr_db))
    throw InputError(where(source, "noise.snr_db") + ": expected a number");
  if (noise.signal_dependent) require_finite(source, "noise.sdn_max_snr_db", noise.sdn_max_snr_db);
  const Viscoelasticity& element = model == ModelKind::arm ? joint : endpoint.element;
  if (noise.signal_dependent && !element.stiffness_table.empty()) {
    throw InputError(where(source, "noise.signal_dependent") +
                     ": signal-dependent noise follows the stiffness profile u_K(t), which a "
                     "stiffness_table replaces; use a profile or constant noise");
  }
  require_positive(source, "integrator.absolute_tolerance", integrator.absolute_tolerance);
  require_positive(source, "integrator.relative_tolerance", integrator.relative_tolerance);
  require_positive(source, "integrator.initial_step_s", integrator.initial_step_s);
  if (integrator.max_steps < 1) {
    throw InputError(where(source, "integrator.max_steps") + ": expected a positive count");
  }
}

}  // namespace stiffid::models
