// `stiffid tfa`: time-varying joint stiffness K(t) and damping C(t) of a two-link arm from one
// trial with one force impulse: by default the parametric damped-mode fit (`--method modal`,
// docs/tfa_modal.md), or the reassigned spectrogram and modal analysis of Piovesan et al. 2012
// (`--method spectrogram`, docs/tfa.md); estimators/tfa.hpp.
//
//   stiffid tfa TRIAL.csv --angles th1,th2 --onset 2.5|auto [--forces fx,fy] [--fs HZ]
//               [--method modal|spectrogram] [--decimate-hz 200] [--knots-s 0.1]
//               [--shape-knots-s 0.5] [--decay-tracks alpha|gamma|best]
//               [--baseline BASE.csv] [--subject SPEC.json]
//               [--window kaiser:3|hann|gaussian:S] [--window-s 0.75] [--hop-s 0.0025]
//               [--fft-size N] [--fmin 0.5] [--fmax 20] [--jump-penalty 2] [--max-jump-hz 0.5]
//               [--chirp true|false] [--anr-floor-db 100] [--sg-window-s 0.25] [--sg-order 3]
//               [--pulse-s 0.02] [--analytic]
//               [--decimation D] [-o OUT.json] [--spectrogram OUT.csv]
//
// Output JSON (stdout without -o; every series runs over "t_s", frame centres in s; non-finite
// values are null): "method", "options" (all settings used), "onset_s", "free_start_s",
// "analysed_s" [first, last], "analysis_rate_hz", "decimation", "t_s" [T],
//   "f_hz"[j] (smoothed), "f_ridge_hz"[j] (per frame), "omega_rad_per_s"[j],
//   "amplitude"[j][k] (rad, mode j in joint k), "phase_rad"[j][k],
//   "alpha_per_s"[j] (eq 47), "alpha_ridge_per_s"[j] (reassignment), "gamma_per_s"[j] (eq 45),
//   "eta_squared_per_s2"[j] (eq 46), "phase_difference_rad"[j], "time_lag_s"[j] (eq 42),
//   "eigenvectors"[r][c] (P(t), columns = modes), "mode_shapes"[r][c] (joint space),
//   "K_nm_per_rad"[r][c], "C_nms_per_rad"[r][c] (eq 48), "M_kg_m2"[r][c] (M(theta(t)) used),
//   "normalized_force": {"q"[j], "q_dot"[j], "sigma"[j], "envelope"[j], "envelope_force"[j]},
//   "valid"[j] (per time: mode j's amplitude-to-noise ratio and frequency SD within limits; for
//   the spectrogram method: the frame resolved, its frequency inside the ridge band and near its
//   ridge, its amplitude-to-noise ratio at least 0 dB, the frame's fits in the ridges' order and
//   without cancelling modes, and with the chirped fits its model not missing the data),
//   "anr_db"[j] (both methods; null for the spectrogram when the trial holds no record before the
//   onset), "K_valid" (per time: every mode valid, eta^2 > Gamma^2, K positive definite and C
//   positive semidefinite; modal).
// For --method modal the spectrogram options are not used; "options" lists the modal ones and the
// data-chosen weights, and f_ridge_hz / alpha_ridge_per_s repeat the fitted tracks;
// --decay-tracks alpha|gamma|best (default best) chooses the decay splines, options.decay_tracks
// says which the kept fit has, "decay_tracks_residual_rms_whitened" and "decay_tracks_bic"
// {alpha, gamma} both fits' residuals and BICs with best (else null); "effective_parameters"
// and "bic" are the kept fit's (design whole; null for sliding).
// --chirp true (spectrogram method, the default): frame fits whose modes' lambdas change linearly
// through the window (estimators/ridge.hpp, docs/tfa.md "Chirped frame fits"); --chirp false: the
// stationary frame model.
// --spectrogram writes CSV rows t_s,f_hz,channel,power,t_reassigned_s,f_reassigned_hz for the bins
// within 60 dB of the map's peak (scripts/plot_spectrogram.py draws it with the ridges).
// Exit 2 on bad input, 1 when frames cannot be resolved; no file is written then.

#include <cmath>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "apps/channels.hpp"
#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "data/text_input.hpp"
#include "estimators/tfa.hpp"
#include "models/spec.hpp"

namespace stiffid::apps {
namespace {

struct TfaCommandOptions {
  std::string design = "whole", mapping = "eq48",
              decay_tracks = estimators::to_string(estimators::DampedModesOptions{}.decay_tracks);
  std::string trial_path, angles, forces, onset, method = "modal", baseline_path, subject_path,
                                                 window = "kaiser:3", output_path, spectrogram_path;
  double sample_rate_hz = 0.0;  // --fs, Hz: for files without a t column (0: from t)
  bool no_shape_refit = false;
  bool no_second_order = false;
  estimators::TfaOptions tfa;
};

double parse_number(const std::string& text, const std::string& flag) {
  size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || !std::isfinite(v)) {
    throw InputError(flag + ": expected a number, got '" + text + "'");
  }
  return v;
}

models::ArmParameters read_subject(const std::string& path) {
  nlohmann::json spec;
  try {
    spec = data::read_json_file(path);
  } catch (const InputError& e) {
    throw InputError(std::string("--subject ") + e.what());
  }
  if (!spec.is_object()) throw InputError("--subject " + path + ": expected a JSON object");
  if (spec.contains("model")) {  // a simulation spec (docs/simulator.md): the arm it simulates
    models::TrialSpec trial_spec;
    try {
      trial_spec = models::parse_trial_spec(spec, path);
    } catch (const InputError& e) {
      throw InputError(std::string("--subject ") + e.what());
    }
    if (trial_spec.model != models::ModelKind::arm) {
      throw InputError("--subject " + path +
                       ": a spec of the endpoint model has no arm; give an arm model's spec or "
                       "the arm parameters (l1_m, r1_m, m1_kg, iz1_kg_m2, l2_m, r2_m, m2_kg, "
                       "iz2_kg_m2)");
    }
    return trial_spec.arm;
  }
  models::ArmParameters arm;
  const std::pair<const char*, double*> fields[] = {
      {"l1_m", &arm.l1_m},           {"r1_m", &arm.r1_m},          {"m1_kg", &arm.m1_kg},
      {"iz1_kg_m2", &arm.iz1_kg_m2}, {"l2_m", &arm.l2_m},          {"r2_m", &arm.r2_m},
      {"m2_kg", &arm.m2_kg},         {"iz2_kg_m2", &arm.iz2_kg_m2}};
  for (const auto& [key, value] : spec.items()) {
    double* target = nullptr;
    for (const auto& [name, field] : fields) {
      if (key == name) target = field;
    }
    if (target == nullptr) {
      throw InputError("--subject " + path + ": unknown key \"" + key +
                       "\"; expected l1_m, r1_m, m1_kg, iz1_kg_m2, l2_m, r2_m, m2_kg, iz2_kg_m2");
    }
    if (!value.is_number()) {
      throw InputError("--subject " + path + ": key \"" + key + "\" must be a number");
    }
    *target = value.get<double>();
  }
  try {
    arm.validate();
  } catch (const InputError& e) {
    throw InputError("--subject " + path + ": " + e.what());
  }
  return arm;
}

nlohmann::json series(const Eigen::Ref<const Eigen::VectorXd>& v) {
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    out.push_back(std::isfinite(v(i)) ? nlohmann::json(v(i)) : nlohmann::json(nullptr));
  }
  return out;
}

nlohmann::json columns(const Eigen::MatrixXd& m) {  // (T x n) -> [n][T]
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index j = 0; j < m.cols(); ++j) out.push_back(series(m.col(j)));
  return out;
}

nlohmann::json matrices(const std::vector<Eigen::MatrixXd>& list) {  // [T](r x c) -> [r][c][T]
  const Eigen::Index rows = list.empty() ? 0 : list[0].rows();
  const Eigen::Index cols = list.empty() ? 0 : list[0].cols();
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index r = 0; r < rows; ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index c = 0; c < cols; ++c) {
      Eigen::VectorXd v(list.size());
      for (size_t m = 0; m < list.size(); ++m) v(m) = list[m](r, c);
      row.push_back(series(v));
    }
    out.push_back(row);
  }
  return out;
}

std::string spectrogram_csv(const estimators::ReassignedSpectrogram& sg,
                            const std::vector<std::string>& names) {
  double peak = 0.0;
  for (int c = 0; c < sg.channels(); ++c) peak = std::max(peak, sg.stft[c].cwiseAbs2().maxCoeff());
  std::ostringstream out;
  out.precision(10);
  out << "t_s,f_hz,channel,power,t_reassigned_s,f_reassigned_hz\n";
  for (int c = 0; c < sg.channels(); ++c) {
    for (int m = 0; m < sg.frames(); ++m) {
      for (int k = 0; k < sg.bins(); ++k) {
        const double p = std::norm(sg.stft[c](k, m));
        if (p < 1e-6 * peak) continue;
        out << sg.time_s(m) << ',' << sg.frequency_hz(k) << ',' << names[c] << ',' << p << ','
            << sg.reassigned_time_s[c](k, m) << ',' << sg.reassigned_frequency_hz[c](k, m) << '\n';
      }
    }
  }
  return out.str();
}

void run(TfaCommandOptions cli) {
  estimators::TfaOptions& o = cli.tfa;
  o.method = estimators::parse_tfa_method(cli.method);
  o.modes.design = estimators::parse_modal_design(cli.design);
  o.modes.shape_refit = !cli.no_shape_refit;
  o.modes.second_order = !cli.no_second_order;
  o.modes.decay_tracks = estimators::parse_decay_tracks(cli.decay_tracks);
  o.modal_parameters.mapping = estimators::parse_modal_mapping(cli.mapping);
  if (o.modal_parameters.mapping != estimators::ModalMapping::paper_eq48 &&
      o.method != estimators::TfaMethod::modal) {
    throw InputError("--mapping " + cli.mapping +
                     ": only the modal method has a state-space mapping (the spectrogram method "
                     "uses eq 48)");
  }
  if (!cli.spectrogram_path.empty() && o.method != estimators::TfaMethod::spectrogram) {
    throw InputError("--spectrogram: the time-frequency map exists only with --method spectrogram");
  }
  o.deviation.angle_channels = data::split_list(cli.angles, "--angles");
  if (!cli.forces.empty()) o.deviation.force_channels = data::split_list(cli.forces, "--forces");
  if (cli.onset == "auto") {
    o.deviation.onset_s = std::numeric_limits<double>::quiet_NaN();
  } else {
    o.deviation.onset_s = parse_number(cli.onset, "--onset");
  }
  o.spectrogram.window = estimators::TfWindow::parse(cli.window, "--window");
  if (!cli.subject_path.empty()) o.arm = read_subject(cli.subject_path);

  const data::TrialCsvOptions csv = trial_csv_options(cli.sample_rate_hz);
  const data::Trial trial = data::read_trial_csv(cli.trial_path, csv);
  // --onset auto without --forces: the force channels fx, fy when the trial has both (the
  // simulator's and the manipulandum exports' names); detect_onset_s names what is missing.
  if (cli.onset == "auto" && o.deviation.force_channels.empty() && trial.find("fx") >= 0 &&
      trial.find("fy") >= 0) {
    o.deviation.force_channels = {"fx", "fy"};
  }
  std::unique_ptr<data::Trial> baseline;
  if (!cli.baseline_path.empty()) {
    baseline = std::make_unique<data::Trial>(data::read_trial_csv(cli.baseline_path, csv));
  }
  const estimators::TfaResult r = estimators::identify_tfa(trial, o, baseline.get());
  // Every warning of the run (the deviation's about the trial file; the modal method's about its
  // noise window and its fit), shown before a failure too: a movement trial without --baseline, a
  // short noise window or the modal fit's own warning may explain it.
  nlohmann::json warnings = nlohmann::json::array();
  for (const std::string* warning : {&r.deviation.warning, &r.noise_warning, &r.modes.warning}) {
    if (warning->empty()) continue;
    const bool about_file = warning == &r.deviation.warning;
    std::cerr << "stiffid tfa: warning: " << (about_file ? trial.source + ": " : "") << *warning
              << '\n';
    warnings.push_back(*warning);
  }
  if (!r.status.ok) throw NumericalFailure(trial.source + ": " + r.status.message);

  nlohmann::json out;
  out["method"] = estimators::to_string(o.method);
  // As printed on stderr ([] when none): for scripts that read the JSON.
  out["warnings"] = std::move(warnings);
  out["options"] = {{"angles", o.deviation.angle_channels},
                    {"forces", o.deviation.force_channels},
                    {"onset", cli.onset},
                    {"baseline", cli.baseline_path},
                    {"subject", cli.subject_path},
                    {"arm",
                     {{"l1_m", o.arm.l1_m},
                      {"r1_m", o.arm.r1_m},
                      {"m1_kg", o.arm.m1_kg},
                      {"iz1_kg_m2", o.arm.iz1_kg_m2},
                      {"l2_m", o.arm.l2_m},
                      {"r2_m", o.arm.r2_m},
                      {"m2_kg", o.arm.m2_kg},
                      {"iz2_kg_m2", o.arm.iz2_kg_m2}}},
                    {"pulse_s", o.deviation.pulse_s},
                    {"decimation", r.decimation}};
  if (o.method == estimators::TfaMethod::modal) {
    const estimators::DampedModesOptions& mo = o.modes;
    const bool both = estimators::fits_both_decay_models(mo);  // best: both fits' figures too
    out["options"].update({{"decimate_hz", mo.decimate_hz},
                           {"knots_s", mo.knot_spacing_s},
                           {"shape_knots_s", mo.shape_knot_spacing_s},
                           {"skip_s", mo.skip_s},
                           {"noise_window_s", r.noise_window_s},
                           {"init_window_s", mo.init_window_s},
                           {"anr_threshold_db", mo.anr_threshold_db},
                           {"max_frequency_sd_hz", mo.max_frequency_sd_hz},
                           {"max_mode_to_data_db", mo.max_mode_to_data_db},
                           {"min_mode_separation", mo.min_mode_separation},
                           {"shape_weight", r.modes.shape_weight},
                           {"shape_phase_factor", mo.shape_phase_factor},
                           {"track_roughness", r.modes.track_roughness},
                           {"shape_weight_from_data", mo.shape_weight < 0.0},
                           {"track_roughness_from_data", mo.track_roughness < 0.0},
                           {"local_roughness_dof", mo.local_roughness_dof},
                           {"lost_track_time_s", mo.lost_track_time_s},
                           {"decay_tie", r.modes.decay_tie},
                           {"decay_tie_from_data", mo.decay_tie < 0.0},
                           {"frequency_tie", r.modes.frequency_tie},
                           {"frequency_tie_from_data", mo.frequency_tie < 0.0},
                           {"design", estimators::to_string(mo.design)},
                           {"decay_tracks", estimators::to_string(r.modes.decay_tracks)},
                           {"decay_tracks_from_data", both},
                           {"sliding_window_s", mo.sliding_window_s},
                           {"real_terms", r.modes.real_terms.size()},
                           {"real_terms_from_data", mo.real_terms < 0},
                           {"offsets", mo.offsets && mo.design == estimators::ModalDesign::whole},
                           {"second_order", r.modes.second_order_mode >= 0},
                           {"shape_refit", r.modes.shape_refit},
                           {"mapping", estimators::to_string(o.modal_parameters.mapping)}});
    // The roughness at each knot when it varies along the record (null: one roughness).
    out["track_roughness_local"] = r.modes.roughness_sd.size() == 0
                                       ? nlohmann::json(nullptr)
                                       : nlohmann::json{{"t_s", series(r.modes.roughness_t_s)},
                                                        {"sd", series(r.modes.roughness_sd)}};
    out["residual_rms_whitened"] = r.modes.residual_rms_whitened;
    // Design whole: the fit's effective number of parameters and BIC (null: sliding design).
    out["effective_parameters"] = r.modes.effective_parameters;
    out["bic"] = r.modes.bic;
    // With --decay-tracks best: both fits' residuals and BICs (null: that fit failed); else null.
    auto both_fits = [&](double alpha, double gamma) {
      return both ? nlohmann::json{{"alpha", alpha}, {"gamma", gamma}} : nlohmann::json(nullptr);
    };
    out["decay_tracks_residual_rms_whitened"] =
        both_fits(r.modes.alpha_residual_rms_whitened, r.modes.gamma_residual_rms_whitened);
    out["decay_tracks_bic"] = both_fits(r.modes.alpha_bic, r.modes.gamma_bic);
    out["converged"] = r.modes.converged;
    out["iterations"] = r.modes.iterations;
    std::vector<double> ratios, frequency_ratios;
    for (const estimators::ModeTrack& mode : r.modes.modes) {
      ratios.push_back(mode.decay_ratio);
      frequency_ratios.push_back(mode.frequency_ratio);
    }
    out["decay_ratio"] = ratios;
    out["frequency_ratio"] = frequency_ratios;
    // Real terms b_k exp(rate (t - t_s[0])): the non-oscillatory part of the response (fibre
    // creep of a Poynting-Thomson element); not modes, so not in K, C or the normalized force.
    nlohmann::json real_terms = nlohmann::json::array();
    for (const estimators::RealTerm& term : r.modes.real_terms) {
      real_terms.push_back({{"rate_per_s", term.rate_per_s},
                            {"rate_sd_per_s", term.rate_sd_per_s},
                            {"amplitude_rad", series(term.amplitude)}});
    }
    out["real_terms"] = real_terms;
    out["offset_rad"] = series(r.modes.offset_rad);
    // Index j of the mode whose quadratic distortion was fitted (-1: none), as in f_hz[j].
    out["second_order_mode"] = r.modes.second_order_mode;
    const Eigen::MatrixXd& cov = r.modes.noise_covariance;
    nlohmann::json noise = nlohmann::json::array();
    for (Eigen::Index i = 0; i < cov.rows(); ++i) {
      noise.push_back(std::vector<double>(cov.cols()));
      for (Eigen::Index k = 0; k < cov.cols(); ++k) noise[i][k] = cov(i, k);
    }
    out["noise_covariance_rad2"] = noise;
  } else {
    out["options"].update({{"window", o.spectrogram.window.name()},
                           {"window_s", 2.0 * r.spectrogram.half_length / r.analysis_rate_hz},
                           {"hop_s", r.spectrogram.hop_s},
                           {"fft_size", r.spectrogram.fft_size},
                           {"fmin_hz", o.ridges.min_frequency_hz},
                           {"fmax_hz", o.ridges.max_frequency_hz},
                           {"jump_penalty_per_hz", o.ridges.jump_penalty_per_hz},
                           {"max_jump_hz", o.ridges.max_jump_hz},
                           {"chirp", o.ridges.fit_chirp},
                           {"anr_floor_db", o.ridges.anr_floor_db},
                           {"sg_window_s", o.modal.smoothing.window_s},
                           {"sg_order", o.modal.smoothing.polynomial_order},
                           {"analytic", o.deviation.analytic}});
  }
  out["onset_s"] = r.deviation.onset_s;
  out["free_start_s"] = r.deviation.free_start_s;
  out["analysed_s"] = {r.region_begin_s, r.region_end_s};
  out["analysis_rate_hz"] = r.analysis_rate_hz;
  out["decimation"] = r.decimation;
  out["t_s"] = series(r.modal.time_s);
  out["f_hz"] = columns(r.modal.omega_rad_per_s / (2.0 * M_PI));
  out["f_ridge_hz"] = columns(r.ridges.frequency_hz);
  out["omega_rad_per_s"] = columns(r.modal.omega_rad_per_s);
  nlohmann::json amplitude = nlohmann::json::array(), phase = nlohmann::json::array();
  for (size_t j = 0; j < r.ridges.amplitude.size(); ++j) {
    amplitude.push_back(columns(r.ridges.amplitude[j]));
    phase.push_back(columns(r.ridges.phase_rad[j]));
  }
  out["amplitude"] = amplitude;
  out["phase_rad"] = phase;
  out["alpha_per_s"] = columns(r.modal.alpha_per_s);
  out["alpha_ridge_per_s"] = columns(r.ridges.decay_rate_per_s);
  out["gamma_per_s"] = columns(r.modal.gamma_per_s);
  out["eta_squared_per_s2"] = columns(r.modal.eta_squared_per_s2);
  out["phase_difference_rad"] = columns(r.modal.phase_difference_rad);
  out["time_lag_s"] = columns(r.modal.time_lag_s);
  out["eigenvectors"] = matrices(r.modal.eigenvectors);
  out["mode_shapes"] = matrices(r.modal.mode_shape);
  out["K_nm_per_rad"] = matrices(r.modal.stiffness_nm_per_rad);
  out["C_nms_per_rad"] = matrices(r.modal.damping_nms_per_rad);
  std::vector<Eigen::MatrixXd> inertia;  // M = (M^1/2)^2 per frame
  for (const Eigen::MatrixXd& root : r.modal.inertia_sqrt) inertia.push_back(root * root);
  out["M_kg_m2"] = matrices(inertia);
  out["normalized_force"] = {{"q", columns(r.force.coordinate)},
                             {"q_dot", columns(r.force.velocity)},
                             {"sigma", columns(r.force.force)},
                             {"envelope", columns(r.force.envelope)},
                             {"envelope_force", columns(r.force.envelope_force)}};
  nlohmann::json valid = nlohmann::json::array(), anr = nlohmann::json::array();
  const Eigen::Index frames = r.modal.time_s.size();
  for (Eigen::Index j = 0; j < r.modal.omega_rad_per_s.cols(); ++j) {
    if (o.method == estimators::TfaMethod::modal) {
      const auto& track = r.modes.modes[j];
      valid.push_back(
          std::vector<bool>(track.valid.data(), track.valid.data() + track.valid.size()));
      anr.push_back(series(track.anr_db));
    } else {
      std::vector<bool> ok(frames, false);  // the ridge frames are the modal-analysis frames
      for (Eigen::Index m = 0; m < frames && m < r.ridges.valid.rows(); ++m) {
        ok[m] = r.status.ok && r.ridges.valid(m, j) && r.modal.separated(m);
      }
      valid.push_back(ok);
      if (r.ridges.anr_db.rows() == frames) {
        anr.push_back(series(r.ridges.anr_db.col(j)));
      } else {
        anr.push_back(std::vector<std::nullptr_t>(frames, nullptr));
      }
    }
  }
  out["valid"] = valid;
  out["anr_db"] = anr;
  if (o.method == estimators::TfaMethod::modal) {
    const auto& ok = r.parameters.valid;
    out["K_valid"] = std::vector<bool>(ok.data(), ok.data() + ok.size());
  }
  if (!cli.spectrogram_path.empty()) {
    data::write_file_atomically(cli.spectrogram_path,
                                spectrogram_csv(r.spectrogram, o.deviation.angle_channels));
  }
  data::write_json(cli.output_path, out);
}

}  // namespace

void add_tfa_command(CLI::App& app) {
  auto cli = std::make_shared<TfaCommandOptions>();
  estimators::TfaOptions& o = cli->tfa;
  CLI::App* sub = app.add_subcommand(
      "tfa",
      "time-varying joint stiffness K(t) and damping C(t) from one impulse-perturbed trial: "
      "damped-mode fit (default) or reassigned spectrogram, then modal analysis (Piovesan et al. "
      "2012 eqs 23-49)");
  sub->add_option("trial", cli->trial_path, "trial CSV with a t column (s), or --fs")->required();
  sub->add_option("--angles", cli->angles, "shoulder,elbow angle channels (rad)")->required();
  sub->add_option("--onset", cli->onset, "pulse onset in s, or auto (from --forces)")->required();
  sub->add_option("--fs", cli->sample_rate_hz,
                  "sampling rate in Hz (required without a t column; time then starts at 0 s)");
  sub->add_option("--forces", cli->forces,
                  "force channels (N), for --onset auto (default fx,fy when the trial has both)");
  sub->add_option("--method", cli->method,
                  "modal (damped modes fitted to the whole free response, docs/tfa_modal.md) or "
                  "spectrogram (Piovesan 2012, docs/tfa.md)")
      ->capture_default_str();
  sub->add_option("--decimate-hz", o.modes.decimate_hz,
                  "modal: rate the deviations are low-passed and decimated to, Hz (<= 0: none)")
      ->capture_default_str();
  sub->add_option("--knots-s", o.modes.knot_spacing_s,
                  "modal: knot spacing of the frequency and decay splines, s")
      ->capture_default_str();
  sub->add_option("--shape-knots-s", o.modes.shape_knot_spacing_s,
                  "modal: knot spacing of the mode-shape splines, s (<= 0: constant shapes)")
      ->capture_default_str();
  sub->add_option("--noise-window-s", o.modes.noise_window_s,
                  "span before the onset whose deviations give the noise covariance (modal: its "
                  "whitening; spectrogram: the modes' amplitude-to-noise ratios), s")
      ->capture_default_str();
  sub->add_option("--track-roughness", o.modes.track_roughness,
                  "modal: prior SD of the second differences of the frequency (rad/s) and decay "
                  "(1/s) spline coefficients (< 0: chosen from the data by the BIC rule, "
                  "docs/tfa_modal.md)")
      ->capture_default_str();
  sub->add_option("--local-roughness-dof", o.modes.local_roughness_dof,
                  "modal, --track-roughness from the data: nu of the Student-t prior that lets "
                  "the roughness vary along the record, rough only where the tracks bend (a sharp "
                  "stiffness change); kept when its BIC is lower (0: one roughness for the whole "
                  "record; docs/tfa_modal.md, \"Local roughness\")")
      ->capture_default_str();
  sub->add_option("--lost-track-time-s", o.modes.lost_track_time_s,
                  "modal: after the last time a mode's ANR is at or above the threshold (it "
                  "sank into the noise), its frequency and decay tracks go on from there with "
                  "their slopes decaying with "
                  "this time constant, s (0: held constant; < 0: the splines' straight-line "
                  "extrapolation); those times stay invalid (docs/tfa_modal.md, \"Lost modes\")")
      ->capture_default_str();
  sub->add_option("--decay-tie", o.modes.decay_tie,
                  "modal: prior SD of the soft tie alpha_j(t) = rho_j alpha_1(t) of the decay "
                  "tracks, relative (0: no tie; < 0: chosen from the data by the BIC rule; for "
                  "posture trials whose stiffness and damping change by a common factor, not "
                  "for movement trials: docs/tfa_modal.md)")
      ->capture_default_str();
  sub->add_option("--frequency-tie", o.modes.frequency_tie,
                  "modal: prior SD of the soft tie omega_j(t) = rho_j omega_1(t) of the "
                  "frequency tracks, relative (0: no tie; < 0: chosen from the data by the BIC "
                  "rule, after --decay-tie; for posture trials whose stiffness changes by a "
                  "common factor, not for movement trials: docs/tfa_modal.md)")
      ->capture_default_str();
  sub->add_option("--design", cli->design,
                  "modal: whole (the whole free response at once, spline tracks) or sliding "
                  "(one fit per --sliding-window-s window around each sample, locally linear "
                  "tracks; docs/tfa_modal.md)")
      ->capture_default_str();
  sub->add_option("--mapping", cli->mapping,
                  "modal: tracks and shapes to K(t), C(t): eq48 (Piovesan 2012 eq 48, real "
                  "mode shapes) or state_space (complex shapes: exact for non-classical damping, "
                  "but C then carries the noise of the shapes' phases; docs/tfa_modal.md)")
      ->capture_default_str();
  sub->add_option("--sliding-window-s", o.modes.sliding_window_s,
                  "modal, --design sliding: window length, s")
      ->capture_default_str();
  sub->add_option("--real-terms", o.modes.real_terms,
                  "modal: non-oscillatory exponentials fitted beside the modes (constant rates; "
                  "< 0: the fewest, 0 to 2 per joint, with which the start finds the oscillatory "
                  "modes: 0 on a Kelvin-Voigt arm, needed for Poynting-Thomson trials)")
      ->capture_default_str();
  sub->add_option("--shape-weight", o.modes.shape_weight,
                  "modal: weight of the penalty on mode-shape changes (< 0: chosen from the data)")
      ->capture_default_str();
  sub->add_option("--shape-phase-factor", o.modes.shape_phase_factor,
                  "modal: penalty on changes of the phases between joints within a mode shape, "
                  "relative to that on the amplitude ratios (> 0; e.g. 10 for a stiffness ellipse "
                  "that turns: docs/tfa_modal.md, \"Phase factor of the shape penalty\")")
      ->capture_default_str();
  sub->add_flag("--no-shape-refit", cli->no_shape_refit,
                "modal: do not refit smoother tracks with varying mode shapes when the "
                "constant-shape fit chose rough tracks (docs/tfa_modal.md, \"Shape refit\")");
  sub->add_option("--decay-tracks", cli->decay_tracks,
                  "modal, --design whole: what the decay splines are: alpha (the envelope decay "
                  "alpha_j(t), 1/s), gamma (the modal damping rates Gamma_j(t), 1/s; alpha_j = "
                  "-Gamma_j - omega_j' / (2 omega_j) follows from the frequency track) or best "
                  "(both fits, concurrently; the lower BIC kept; docs/tfa_modal.md, "
                  "\"Damping tracks\")")
      ->capture_default_str();
  sub->add_flag("--no-second-order", cli->no_second_order,
                "modal: do not offer the strongest mode's quadratic distortion terms (docs/"
                "tfa_modal.md, \"Quadratic distortion of the strongest mode\")");
  sub->add_option("--baseline", cli->baseline_path,
                  "unperturbed trial (same angle channels and rate); default: the posture is "
                  "the mean over 0.2 s before the onset");
  sub->add_option("--subject", cli->subject_path,
                  "JSON object of arm parameters (l1_m, r1_m, m1_kg, iz1_kg_m2, l2_m, r2_m, "
                  "m2_kg, iz2_kg_m2; m, kg, kg m^2; a key left out keeps Piovesan 2012 Table "
                  "1's value), or an arm model's simulation spec (its arm); default Piovesan "
                  "2012 Table 1");
  sub->add_option("--window", cli->window, "kaiser:BETA, hann or gaussian:SIGMA_FRACTION")
      ->capture_default_str();
  sub->add_option("--window-s", o.spectrogram.window_s, "STFT window length, s")
      ->capture_default_str();
  sub->add_option("--hop-s", o.spectrogram.hop_s, "STFT hop, s")->capture_default_str();
  sub->add_option("--fft-size", o.spectrogram.fft_size,
                  "FFT length (0: next power of two >= the window)")
      ->capture_default_str();
  sub->add_option("--fmin", o.ridges.min_frequency_hz, "lowest ridge frequency, Hz")
      ->capture_default_str();
  sub->add_option("--fmax", o.ridges.max_frequency_hz, "highest ridge frequency, Hz")
      ->capture_default_str();
  sub->add_option("--jump-penalty", o.ridges.jump_penalty_per_hz,
                  "ridge cost per Hz of frequency change per frame")
      ->capture_default_str();
  sub->add_option("--max-jump-hz", o.ridges.max_jump_hz, "largest ridge jump per frame, Hz")
      ->capture_default_str();
  sub->add_option("--chirp", o.ridges.fit_chirp,
                  "spectrogram method: frame fits with each mode's chirp rate (d lambda/dt, "
                  "1/s^2) fitted where the data ask for it, then held at the slopes of the "
                  "tracks (docs/tfa.md); true (the default) or false: the stationary frame "
                  "model, each mode's lambda constant through the window")
      ->capture_default_str();
  sub->add_option("--anr-floor-db", o.ridges.anr_floor_db,
                  "spectrogram method: the noise in the amplitude-to-noise ratio is at least this "
                  "far below the strongest mode's peak power, dB (noise-free data)")
      ->capture_default_str();
  sub->add_option("--sg-window-s", o.modal.smoothing.window_s, "Savitzky-Golay window, s")
      ->capture_default_str();
  sub->add_option("--sg-order", o.modal.smoothing.polynomial_order,
                  "Savitzky-Golay polynomial order")
      ->capture_default_str();
  sub->add_option("--pulse-s", o.deviation.pulse_s,
                  "pulse duration after a given onset, s (auto onset: measured)")
      ->capture_default_str();
  sub->add_flag("--analytic", o.deviation.analytic,
                "analyse the analytic signals (FFT Hilbert transform) of the deviations");
  sub->add_option("--decimation", o.decimation, "keep every D-th sample before the STFT (0: auto)")
      ->capture_default_str();
  sub->add_option("-o,--output", cli->output_path, "output JSON file (default: stdout)");
  sub->add_option("--spectrogram", cli->spectrogram_path,
                  "write the (reassigned) time-frequency map as CSV");
  sub->callback([cli]() { run(*cli); });
}

}  // namespace stiffid::apps
