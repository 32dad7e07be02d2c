#include "estimators/tfa.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <string>

#include "data/error.hpp"
#include "estimators/decimate.hpp"

namespace stiffid::estimators {

TfaMethod parse_tfa_method(const std::string& text) {
  if (text == "modal") return TfaMethod::modal;
  if (text == "spectrogram") return TfaMethod::spectrogram;
  throw InputError("--method: unknown method '" + text + "'; expected modal or spectrogram");
}

std::string to_string(TfaMethod method) {
  switch (method) {
    case TfaMethod::modal:
      return "modal";
    case TfaMethod::spectrogram:
      return "spectrogram";
  }
  return "";
}

namespace {

// Inertia M(theta_0(t)) of the unperturbed posture at each time (the nearest input sample),
// kg m^2. Both methods: frame centres (spectrogram) and fitted samples (modal).
std::vector<Eigen::MatrixXd> inertia_at(const DeviationResult& dev,
                                        const models::ArmParameters& arm,
                                        const Eigen::VectorXd& time_s) {
  std::vector<Eigen::MatrixXd> inertia;
  inertia.reserve(time_s.size());
  const Eigen::Index last = dev.posture_rad.rows() - 1;
  for (Eigen::Index m = 0; m < time_s.size(); ++m) {
    const Eigen::Index row = std::clamp<Eigen::Index>(
        std::lround((time_s(m) - dev.start_time_s) * dev.sample_rate_hz), 0, last);
    const Eigen::Vector2d theta = dev.posture_rad.row(row).transpose();
    inertia.push_back(models::inertia_matrix(arm, theta));
  }
  return inertia;
}

// Noise covariance of the analysed channels for the spectrogram method's amplitude-to-noise
// ratios: the deviations over up to window_s before the onset (as far as the trial and the
// baseline reach, less 0.05 s), decimated like the analysed signal, the filter's reach at both
// ends left out. Empty when fewer than 8 samples per channel remain (no such test then).
Eigen::MatrixXd pre_onset_noise(const data::Trial& trial, const TfaOptions& options,
                                const data::Trial* baseline, const DecimationOptions& decimation,
                                double window_s) {
  DeviationOptions lead = options.deviation;
  lead.analytic = false;
  lead.lead_s = std::max(lead.lead_s, window_s + 0.05);
  const DeviationResult before = joint_deviation(trial, lead, baseline);
  const double fs = before.sample_rate_hz;
  const int c = static_cast<int>(before.deviation_rad.cols());
  const int onset = static_cast<int>(std::ceil((before.onset_s - before.start_time_s) * fs - 1e-9));
  const int used = std::min(onset - static_cast<int>(std::lround(0.05 * fs)),
                            static_cast<int>(std::lround(window_s * fs)));
  const int d = decimation.factor;
  const int h = filter_reach_samples(decimation);
  if (used <= 2 * h) return {};
  const DecimationResult x =
      decimate(before.deviation_rad.middleRows(onset - used, used), fs, decimation);
  const int first = x.edge_samples, last = (used - 1 - h) / d;
  if (last - first + 1 < 8 * c) return {};
  Eigen::MatrixXd noise = x.samples.middleRows(first, last - first + 1);
  noise.rowwise() -= noise.colwise().mean();
  return noise.transpose() * noise / double(noise.rows() - 1);
}

// Stages 2-5 of the modal method: the fit, K and C by the inverse eigenproblem, and the same
// per-time quantities as the spectrogram pipeline's modal analysis (omega, alpha and their
// derivatives come from the fitted splines, not from Savitzky-Golay smoothing).
void identify_modal(TfaResult& r, const TfaOptions& options) {
  const DeviationResult& dev = r.deviation;
  const int n = static_cast<int>(dev.channels.size());
  DampedModesOptions mo = options.modes;
  mo.modes = n;
  mo.skip_s = std::max(mo.skip_s, dev.free_start_s - dev.onset_s);
  if (!mo.mass_metric) {
    mo.mass_metric = [&dev, &options](const Eigen::VectorXd& t_s) {
      return inertia_at(dev, options.arm, t_s);
    };
  }
  // The noise window reaches back as far as the record allows (less a margin for the filter).
  const double available_s = dev.onset_s - dev.start_time_s - 0.05;
  const double asked_s = mo.noise_window_s;
  if (available_s >= 0.1) mo.noise_window_s = std::min(mo.noise_window_s, available_s);
  r.noise_window_s = mo.noise_window_s;
  r.modes =
      fit_damped_modes(dev.deviation_rad, dev.sample_rate_hz, dev.start_time_s, dev.onset_s, mo);
  const DampedModesResult& fit = r.modes;
  r.analysis_rate_hz = fit.rate_hz;
  if (r.noise_window_s < asked_s && fit.rate_hz > 0.0) {
    // A variance from N independent samples has a relative SD of sqrt(2 / N); the decimated
    // noise is about white up to the fit's Nyquist frequency, so N ~ window x fit rate.
    r.noise_warning =
        "the noise covariance comes from the " + number_text(r.noise_window_s) +
        " s before the onset that the trial holds (less 0.05 s kept for the "
        "filter), not the --noise-window-s " +
        number_text(asked_s) + " s asked (about +-" +
        number_text(std::round(100.0 * std::sqrt(2.0 / (r.noise_window_s * fit.rate_hz)))) +
        " % in its variances, and so in the squared posterior SDs)";
  }
  r.decimation = std::max(1, static_cast<int>(std::lround(dev.sample_rate_hz / fit.rate_hz)));
  if (!fit.status.ok || fit.t_s.size() == 0) {
    r.status = fit.status.ok ? Status::failure("modal fit: no sample fitted") : fit.status;
    return;
  }
  r.region_begin_s = fit.t_s(0);
  r.region_end_s = fit.t_s(fit.t_s.size() - 1);
  r.ridges = as_ridges(fit);
  const std::vector<Eigen::MatrixXd> inertia = inertia_at(dev, options.arm, fit.t_s);
  r.parameters = modal_parameters(fit, inertia, options.modal_parameters);

  const int frames = static_cast<int>(fit.t_s.size());
  ModalAnalysisResult& m = r.modal;
  m.time_s = fit.t_s;
  m.omega_rad_per_s.resize(frames, n);
  m.omega_dot_rad_per_s2.resize(frames, n);
  m.amplitude.resize(frames, n);
  m.alpha_per_s.resize(frames, n);
  m.alpha_dot_per_s2.resize(frames, n);
  m.phase_difference_rad.resize(frames, n);
  m.time_lag_s.resize(frames, n);
  m.gamma_per_s = r.parameters.gamma_per_s.transpose();
  m.eta_squared_per_s2 = r.parameters.eta_squared_rad2_per_s2.transpose();
  m.eigenvectors = r.parameters.eigenvectors;
  m.stiffness_nm_per_rad = r.parameters.stiffness;
  m.damping_nms_per_rad = r.parameters.damping;
  m.mode_shape.assign(frames, Eigen::MatrixXd::Zero(n, n));
  m.inertia_sqrt.reserve(frames);
  for (int t = 0; t < frames; ++t) {
    m.inertia_sqrt.push_back(models::spd_sqrt(inertia[t]));
  }
  for (int j = 0; j < n; ++j) {
    const ModeTrack& track = fit.modes[j];
    m.omega_rad_per_s.col(j) = track.omega_rad_per_s;
    m.omega_dot_rad_per_s2.col(j) = track.omega_dot_rad_per_s2;
    m.alpha_per_s.col(j) = track.alpha_per_s;
    m.alpha_dot_per_s2.col(j) = track.alpha_dot_per_s2;
    m.amplitude.col(j) = track.envelope.rowwise().norm();
    for (int t = 0; t < frames; ++t) {
      // Phases relative to the strongest channel (eqs 41-42); the mode shape is the in-phase
      // projection (eq 37), unit norm.
      Eigen::Index ref = 0;
      track.shape.row(t).cwiseAbs().maxCoeff(&ref);
      const std::complex<double> rotation = std::polar(1.0, -std::arg(track.shape(t, ref)));
      Eigen::VectorXd shape(n);
      double folded = 0.0;
      for (int k = 0; k < n; ++k) {
        const std::complex<double> a = track.shape(t, k) * rotation;
        shape(k) = a.real();
        if (k != ref) {
          double rho = std::arg(a);
          if (rho > M_PI / 2) rho -= M_PI;
          if (rho <= -M_PI / 2) rho += M_PI;
          folded = rho;
        }
      }
      const double norm = shape.norm();
      if (norm > 0.0) m.mode_shape[t].col(j) = shape / norm;
      m.phase_difference_rad(t, j) = folded;
      m.time_lag_s(t, j) = folded / track.omega_rad_per_s(t);
    }
  }
  m.status = fit.status;
  r.force = normalized_force(r.ridges, m);
  r.status = fit.status;
}

}  // namespace

TfaResult identify_tfa(const data::Trial& trial, const TfaOptions& options,
                       const data::Trial* baseline) {
  if (options.deviation.angle_channels.size() != 2) {
    throw InputError("--angles: the arm model has 2 joints; give 2 angle channels, got " +
                     std::to_string(options.deviation.angle_channels.size()));
  }
  options.arm.validate();
  TfaResult r;
  if (options.method == TfaMethod::modal) {
    DeviationOptions deviation = options.deviation;
    // The fit takes the noise covariance from before the onset (after its low-pass filter).
    deviation.lead_s = std::max(deviation.lead_s, options.modes.noise_window_s + 0.1);
    r.deviation = joint_deviation(trial, deviation, baseline);
    identify_modal(r, options);
    return r;
  }
  r.deviation = joint_deviation(trial, options.deviation, baseline);
  const DeviationResult& dev = r.deviation;
  const double fs = dev.sample_rate_hz;

  const int hop = std::max(1, static_cast<int>(std::lround(options.spectrogram.hop_s * fs)));
  int d = options.decimation;
  if (d < 0)
    throw InputError("decimation factor must be >= 0 (0 = auto), got " + std::to_string(d));
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
  const double filter_s = filter_reach_samples(dec_options) / fs;
  signal.begin =
      static_cast<int>(std::ceil((dev.free_start_s + filter_s - dev.start_time_s) / dt - 1e-9));
  signal.end = static_cast<int>(real.samples.rows()) - real.edge_samples;
  r.region_begin_s = dev.start_time_s + signal.begin * dt;
  r.region_end_s = dev.start_time_s + (signal.end - 1) * dt;
  if (signal.end - signal.begin < 1) {
    throw InputError(
        "the trial ends " +
        number_text(dev.start_time_s + dev.deviation_rad.rows() / fs - dev.free_start_s) +
        " s after the pulse: too short after the onset for one --window-s " +
        number_text(options.spectrogram.window_s) + " s window");
  }

  ReassignedSpectrogramOptions sg_options = options.spectrogram;
  sg_options.hop_s = hop / fs;
  if (sg_options.max_frequency_hz <= 0.0) {
    sg_options.max_frequency_hz =
        std::min(0.5 * real.sample_rate_hz, 2.0 * options.ridges.max_frequency_hz);
  }
  try {
    r.spectrogram = reassigned_spectrogram(signal, sg_options);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (the free response analysed runs from " +
                     number_text(r.region_begin_s) + " to " + number_text(r.region_end_s) +
                     " s: too short after the onset for one window)");
  }
  RidgeOptions ridge_options = options.ridges;
  ridge_options.modes = static_cast<int>(options.deviation.angle_channels.size());
  if (ridge_options.noise_covariance.size() == 0) {
    ridge_options.noise_covariance =
        pre_onset_noise(trial, options, baseline, dec_options, options.modes.noise_window_s);
  }
  r.ridges = track_ridges(r.spectrogram, ridge_options);

  // Frame centres are whole input samples (centre * D), so the posture row is exact.
  r.modal =
      modal_analysis(r.ridges, inertia_at(dev, options.arm, r.spectrogram.time_s), options.modal);
  r.force = normalized_force(r.ridges, r.modal);
  r.status = r.modal.status;
  return r;
}

}  // namespace stiffid::estimators
