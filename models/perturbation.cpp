#include "models/perturbation.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "data/error.hpp"
#include "models/butterworth.hpp"

namespace stiffid::models {

ForcePulse force_impulse(double onset_s, double direction_rad) {
  return ForcePulse{onset_s, 0.02, 5.0, direction_rad, false};
}

ForcePulse force_pulse(double onset_s, double direction_rad) {
  return ForcePulse{onset_s, 0.2, 5.0, direction_rad, false};
}

double octant_direction_rad(int k) { return k * M_PI / 4.0; }

namespace {

// Ramp-and-hold shape s(t) in [0, 1] and its rate, 1/s.
std::pair<double, double> ramp_shape(const DisplacementRamp& r, double t_s) {
  const double tau = t_s - r.onset_s;
  if (tau < 0.0) return {0.0, 0.0};
  if (tau < r.ramp_s) return {tau / r.ramp_s, 1.0 / r.ramp_s};
  if (tau < r.ramp_s + r.plateau_s) return {1.0, 0.0};
  const double back = tau - r.ramp_s - r.plateau_s;
  if (back < r.return_s) return {1.0 - back / r.return_s, -1.0 / r.return_s};
  return {0.0, 0.0};
}

}  // namespace

Eigen::Vector2d DisplacementRamp::offset_m(double t_s) const {
  return ramp_shape(*this, t_s).first * amplitude_m *
         Eigen::Vector2d(std::cos(direction_rad), std::sin(direction_rad));
}

Eigen::Vector2d DisplacementRamp::offset_rate_m_per_s(double t_s) const {
  return ramp_shape(*this, t_s).second * amplitude_m *
         Eigen::Vector2d(std::cos(direction_rad), std::sin(direction_rad));
}

Eigen::MatrixXd random_forces(const RandomForce& options, int samples, int inputs,
                              double sample_rate_hz, std::mt19937_64& rng) {
  const int r = options.oversample;
  if (r < 1) throw InputError("random force: expected oversample >= 1, got " + std::to_string(r));
  const Eigen::MatrixXd sos =
      butterworth_lowpass_sos(options.filter_order, options.bandwidth_hz, r * sample_rate_hz);
  const Eigen::Index fine = static_cast<Eigen::Index>(samples) * r;
  const Eigen::Index warmup = std::lround(options.warmup_s * sample_rate_hz) * r;
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd e(samples, inputs);
  for (int i = 0; i < inputs; ++i) {
    Eigen::VectorXd white(fine + warmup);
    for (Eigen::Index k = 0; k < white.size(); ++k) white(k) = normal(rng);
    const Eigen::VectorXd filtered = sos_filter(sos, white);
    for (int k = 0; k < samples; ++k) e(k, i) = filtered(warmup + static_cast<Eigen::Index>(k) * r);
  }
  // Standardize each input over the trial.
  auto standardize = [](Eigen::VectorXd v) {
    v.array() -= v.mean();
    const double norm = v.norm();
    return norm > 0.0 ? Eigen::VectorXd(v / norm) : v;
  };
  for (int i = 0; i < inputs; ++i) e.col(i) = standardize(e.col(i));
  Eigen::MatrixXd f = e;
  if (inputs >= 2 && options.coupling_percent > 0.0) {
    const double c = options.coupling_percent / 100.0;
    // Remove from e2 its projection on e1 (both zero-mean, unit norm), so that the coupled input
    // has a squared sample correlation with input 1 of exactly c.
    const Eigen::VectorXd e2 = standardize(e.col(1) - e.col(1).dot(e.col(0)) * e.col(0));
    f.col(1) = std::sqrt(c) * e.col(0) + std::sqrt(1.0 - c) * e2;
  }
  for (int i = 0; i < inputs; ++i) {
    Eigen::VectorXd v = f.col(i);
    v.array() -= v.mean();
    double scale = 0.0;
    if (options.rms_n > 0.0) {
      const double rms = std::sqrt(v.squaredNorm() / std::max(1, samples));
      scale = rms > 0.0 ? options.rms_n / rms : 0.0;
    } else {
      const double ptp = samples > 0 ? v.maxCoeff() - v.minCoeff() : 0.0;
      scale = ptp > 0.0 ? options.peak_to_peak_n / ptp : 0.0;
    }
    f.col(i) = v * scale;
  }
  return f;
}

}  // namespace stiffid::models
