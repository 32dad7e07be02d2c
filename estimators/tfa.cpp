#include "estimators/tfa.hpp"

#include <cmath>
#include <string>

#include "data/error.hpp"
#include "estimators/decimate.hpp"

namespace stiffid::estimators {

TfaMethod parse_tfa_method(const std::string& text) {
  if (text == "spectrogram") return TfaMethod::spectrogram;
  throw InputError("--method: unknown method '" + text + "'; expected spectrogram");
}

std::string to_string(TfaMethod method) {
  switch (method) {
    case TfaMethod::spectrogram: return "spectrogram";
  }
  return "";
}

TfaResult identify_tfa(const data::Trial& trial, const TfaOptions& options,
                       const data::Trial* baseline) {
  if (options.deviation.angle_channels.size() != 2) {
    throw InputError("--angles: the arm model has 2 joints; give 2 angle channels, got " +
                     std::to_string(options.deviation.angle_channels.size()));
  }
  options.arm.validate();
  TfaResult r;
  r.deviation = joint_deviation(trial, options.deviation, baseline);
  const DeviationResult& dev = r.deviation;
  const double fs = dev.sample_rate_hz;

  const int hop = std::max(1, static_cast<int>(std::lround(options.spectrogram.hop_s * fs)));
  int d = options.decimation;
  if (d < 0) throw InputError("decimation factor must be >= 0 (0 = auto), got " + std::to_string(d));
  if (d == 0) {
    d = 1;
    for (int c = hop; c >= 1; --c) {
      if (hop % c == 0 && fs / c >= 8.0 * options.ridges.max_frequency_hz) {
        d = c;
        break;
      }
    }
  }
  DecimationOptions dec_options;
  dec_options.factor = d;
  const DecimationResult real = decimate(dev.deviation_rad, fs, dec_options);
  r.decimation = d;
  r.analysis_rate_hz = real.sample_rate_hz;

  TfSignal signal;
  signal.sample_rate_hz = real.sample_rate_hz;
  signal.start_time_s = dev.start_time_s;
  signal.real = real.samples;
  if (dev.hilbert_rad.size() > 0) signal.imag = decimate(dev.hilbert_rad, fs, dec_options).samples;
  const double dt = 1.0 / real.sample_rate_hz;
  const double filter_s = d > 1 ? dec_options.half_taps_per_factor * d / fs : 0.0;
  signal.begin = static_cast<int>(
      std::ceil((dev.free_start_s + filter_s - dev.start_time_s) / dt - 1e-9));
  signal.end = static_cast<int>(real.samples.rows()) - real.edge_samples;
  r.region_begin_s = dev.start_time_s + signal.begin * dt;
  r.region_end_s = dev.start_time_s + (signal.end - 1) * dt;
  if (signal.end - signal.begin < 1) {
    throw InputError("the trial ends " + std::to_string(dev.start_time_s + dev.deviation_rad.rows() / fs - dev.free_start_s) +
                     " s after the pulse: too short after the onset for one --window-s " +
                     std::to_string(options.spectrogram.window_s) + " s window");
  }

  ReassignedSpectrogramOptions sg_options = options.spectrogram;
  sg_options.hop_s = hop / fs;
  if (sg_options.max_frequency_hz <= 0.0) {
    sg_options.max_frequency_hz = std::min(0.5 * real.sample_rate_hz,
                                           2.0 * options.ridges.max_frequency_hz);
  }
  try {
    r.spectrogram = reassigned_spectrogram(signal, sg_options);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (the free response analysed runs from " +
                     std::to_string(r.region_begin_s) + " to " + std::to_string(r.region_end_s) +
                     " s: too short after the onset for one window)");
  }
  RidgeOptions ridge_options = options.ridges;
  ridge_options.modes = static_cast<int>(options.deviation.angle_channels.size());
  r.ridges = track_ridges(r.spectrogram, ridge_options);

  std::vector<Eigen::MatrixXd> inertia;
  inertia.reserve(r.spectrogram.frames());
  for (int m = 0; m < r.spectrogram.frames(); ++m) {
    const int row = std::min(static_cast<int>(dev.posture_rad.rows()) - 1,
                             r.spectrogram.centre(m) * d);
    const Eigen::Vector2d theta = dev.posture_rad.row(row).transpose();
    inertia.push_back(models::inertia_matrix(options.arm, theta));
  }
  r.modal = modal_analysis(r.ridges, inertia, options.modal);
  r.force = normalized_force(r.ridges, r.modal);
  r.status = r.modal.status;
  return r;
}

}  // namespace stiffid::estimators
