#include "estimators/tfa_deviation.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "estimators/hilbert.hpp"

namespace stiffid::estimators {
namespace {

std::string where(const data::Trial& trial) {
  return trial.source.empty() ? std::string("trial") : trial.source;
}

// The named angle channels of `trial` in rad: a unit of "" or "rad" as recorded, "deg" and
// "mrad" converted; any other unit is refused (K and C would be off by its factor).
Eigen::MatrixXd angles_rad(const data::Trial& trial, const std::vector<std::string>& names,
                           const std::string& flag) {
  Eigen::MatrixXd angles = trial.columns(names);
  for (std::size_t k = 0; k < names.size(); ++k) {
    const std::string& unit = trial.units[static_cast<std::size_t>(trial.index(names[k]))];
    if (unit == "deg") {
      angles.col(static_cast<Eigen::Index>(k)) *= M_PI / 180.0;
    } else if (unit == "mrad") {
      angles.col(static_cast<Eigen::Index>(k)) *= 1e-3;
    } else if (!unit.empty() && unit != "rad") {
      throw InputError(where(trial) + ": " + flag + " channel '" + names[k] + "' is in [" + unit +
                       "]; expected joint angles in rad (deg and mrad are converted)");
    }
  }
  return angles;
}

double median(Eigen::VectorXd v) {
  std::sort(v.data(), v.data() + v.size());
  const Eigen::Index n = v.size();
  return n % 2 ? v(n / 2) : 0.5 * (v(n / 2 - 1) + v(n / 2));
}

}  // namespace

double detect_onset_s(const data::Trial& trial, const std::vector<std::string>& force_channels,
                      double threshold, double& end_s) {
  if (force_channels.empty()) {
    std::string names;
    for (const std::string& name : trial.names) names += " " + name;
    throw InputError(where(trial) +
                     ": --onset auto needs the force channels: give --forces (the "
                     "default fx,fy is not in the trial; channels:" +
                     names + ")");
  }
  if (!(threshold > 0.0 && threshold < 1.0)) {
    throw InputError("onset threshold must be in (0, 1), got " + number_text(threshold));
  }
  Eigen::MatrixXd f = trial.columns(force_channels);
  for (Eigen::Index c = 0; c < f.cols(); ++c) f.col(c).array() -= median(f.col(c));
  const Eigen::VectorXd norm = f.rowwise().norm();
  const double peak = norm.size() ? norm.maxCoeff() : 0.0;
  if (!(peak > 0.0)) {
    throw InputError(where(trial) + ": --onset auto: the force channels carry no pulse (constant)");
  }
  Eigen::Index first = 0;
  while (norm(first) < threshold * peak) ++first;
  Eigen::Index last = first;
  while (last + 1 < norm.size() && norm(last + 1) >= threshold * peak) ++last;
  end_s = trial.start_time_s + (last + 1) * trial.step_s();
  return trial.start_time_s + first * trial.step_s();
}

std::string posture_drift(const Eigen::MatrixXd& angles_rad, double dt_s, double response_s,
                          const Eigen::VectorXd& peak_rad,
                          const std::vector<std::string>& channels) {
  const Eigen::Index p = angles_rad.rows();
  if (p < 3) return "";
  const Eigen::VectorXd t =
      Eigen::VectorXd::LinSpaced(p, 0.0, static_cast<double>(p - 1) * dt_s).array() -
      0.5 * static_cast<double>(p - 1) * dt_s;
  const double tt = t.squaredNorm();
  std::string joints;
  for (Eigen::Index k = 0; k < angles_rad.cols(); ++k) {
    const Eigen::VectorXd y = angles_rad.col(k).array() - angles_rad.col(k).mean();
    const double slope = t.dot(y) / tt;  // rad/s
    const double residual_sd =
        std::sqrt((y - slope * t).squaredNorm() / static_cast<double>(p - 2));
    const double drift = std::abs(slope) * response_s;
    if (std::abs(slope) > 10.0 * residual_sd / std::sqrt(tt) && drift > 0.1 * peak_rad(k)) {
      joints += std::string(joints.empty() ? "" : "; ") + "'" + channels[k] + "' " +
                number_text(slope) + " rad/s: " + number_text(drift) + " rad over the " +
                number_text(response_s) + " s after it, largest deviation " +
                number_text(peak_rad(k)) + " rad";
    }
  }
  if (joints.empty()) return "";
  return "the joints move before the onset (" + joints + "): the posture, the mean over the " +
         number_text(static_cast<double>(p) * dt_s) +
         " s before the onset, is not a rest posture; for a movement trial give --baseline (the "
         "unperturbed trajectory)";
}

DeviationResult joint_deviation(const data::Trial& trial, const DeviationOptions& options,
                                const data::Trial* baseline) {
  if (options.angle_channels.empty()) throw InputError("--angles: no angle channel given");
  const Eigen::MatrixXd angles = angles_rad(trial, options.angle_channels, "--angles");
  const double dt = trial.step_s();
  const double t_end = trial.start_time_s + trial.sample_count() * dt;
  DeviationResult r;
  r.sample_rate_hz = trial.sample_rate_hz;
  r.channels = options.angle_channels;
  double pulse_end_s = 0.0;
  if (std::isnan(options.onset_s)) {
    r.onset_s = detect_onset_s(trial, options.force_channels, options.onset_threshold, pulse_end_s);
  } else {
    r.onset_s = options.onset_s;
    pulse_end_s = r.onset_s + std::max(0.0, options.pulse_s);
    if (!std::isfinite(r.onset_s) || r.onset_s < trial.start_time_s || r.onset_s >= t_end) {
      throw InputError("--onset " + number_text(options.onset_s) + " s is outside " + where(trial) +
                       " (" + number_text(trial.start_time_s) + " to " + number_text(t_end) +
                       " s)");
    }
  }
  if (pulse_end_s >= t_end) {
    throw InputError("--onset " + number_text(r.onset_s) + " s: the pulse ends at " +
                     number_text(pulse_end_s) + " s (--pulse-s), at or after the end of " +
                     where(trial) + " (" + number_text(t_end) + " s): no free response");
  }
  const int onset = static_cast<int>(std::ceil((r.onset_s - trial.start_time_s) / dt - 1e-9));
  int first_row =
      std::max(0, onset - static_cast<int>(std::lround(std::max(0.0, options.lead_s) / dt)));
  if (baseline != nullptr) {  // the lead reaches back only as far as the baseline
    const long covered = std::lround((baseline->start_time_s - trial.start_time_s) / dt);
    first_row = std::min(onset, std::max<int>(first_row, static_cast<int>(covered)));
  }
  const int rows = trial.sample_count() - first_row;
  r.start_time_s = trial.start_time_s + first_row * dt;
  r.free_start_s = std::max(pulse_end_s, trial.start_time_s + onset * dt);
  if (baseline == nullptr) {
    const int pre = static_cast<int>(std::lround(options.pre_onset_s / dt));
    if (pre < 1 || onset - pre < 0) {
      throw InputError(where(trial) + ": the posture is the mean over " +
                       number_text(options.pre_onset_s) + " s before the onset at " +
                       number_text(r.onset_s) + " s, but the trial starts at " +
                       number_text(trial.start_time_s) + " s (give --baseline or a later onset)");
    }
    const Eigen::RowVectorXd posture = angles.middleRows(onset - pre, pre).colwise().mean();
    r.posture_rad = posture.replicate(rows, 1);
    const int after = trial.sample_count() - onset;
    const Eigen::VectorXd peak =
        (angles.bottomRows(after).rowwise() - posture).cwiseAbs().colwise().maxCoeff().transpose();
    r.warning = posture_drift(angles.middleRows(onset - pre, pre), dt,
                              static_cast<double>(after) * dt, peak, options.angle_channels);
  } else {
    if (std::abs(baseline->sample_rate_hz - trial.sample_rate_hz) > 1e-9 * trial.sample_rate_hz) {
      throw InputError("--baseline " + where(*baseline) + ": sample rate " +
                       number_text(baseline->sample_rate_hz) + " Hz differs from the trial's " +
                       number_text(trial.sample_rate_hz) + " Hz");
    }
    const Eigen::MatrixXd base = angles_rad(*baseline, options.angle_channels, "--baseline");
    const long first = std::lround((r.start_time_s - baseline->start_time_s) / dt);
    if (first < 0 || first + rows > baseline->sample_count()) {
      throw InputError("--baseline " + where(*baseline) + " covers " +
                       number_text(baseline->start_time_s) + " to " +
                       number_text(baseline->start_time_s + baseline->duration_s()) +
                       " s but the trial needs " + number_text(r.start_time_s) + " to " +
                       number_text(t_end) + " s");
    }
    r.posture_rad = base.middleRows(first, rows);
  }
  r.deviation_rad = angles.bottomRows(rows) - r.posture_rad;
  if (options.analytic) r.hilbert_rad = hilbert_transform(r.deviation_rad);
  return r;
}

}  // namespace stiffid::estimators
