// `stiffid frf`: the MIMO H1 frequency-response matrix of a trial, with ordinary, multiple and
// partial coherences, the condition number of Gxx and random-error bands (estimators/frf.hpp).
//
//   stiffid frf TRIAL.csv --inputs fx,fy --outputs x,y [--nfft 256] [--overlap 0.5]
//               [--window hann|hamming|kaiser:BETA|rect] [--detrend constant|linear|none]
//               [--fs HZ] [--stiffness] [-o OUT.json]
//
// Welch segments of --nfft samples, noverlap = floor(overlap * nfft) (Python's int(), as passed to
// scipy), periodic window, one-sided density spectra as scipy.signal.csd. Output JSON (stdout
// without -o; arrays run over frequency_hz; non-finite values are null):
//   "fs" (Hz), "nfft" (samples per segment), "segments" (averaged), "inputs", "outputs",
//   "frequency_hz": [F],
//   "frf": {OUT: {IN: {"re": [F], "im": [F]}}}          output unit per input unit (m/N ...)
//   "coherence": {"ordinary": {OUT: {IN: [F]}}, "multiple": {OUT: [F]},
//                 "partial": {OUT: {IN: [F]}}}           B&P, conditioned on the other inputs
//   "condition_number": [F]                              lambda_max / lambda_min of Gxx
//   "random_error": {                                    Bendat & Piersol normalized random errors
//     "averages": n_d, "equivalent_independent_segments": Welch's overlap-corrected n_d,
//     "confidence_factor": c (bands = value (1 -/+ c eps), ~95 % for c = 2),
//     "frf_magnitude": {OUT: {IN: {"eps": [F], "lower": [F], "upper": [F]}}},   bands of |H|
//     "coherence": {"ordinary": {OUT: {IN: {"eps", "lower", "upper"}}},
//                   "partial":  {OUT: {IN: {"eps", "lower", "upper"}}},
//                   "multiple": {OUT: {"eps", "lower", "upper"}}}}
//   with --stiffness (needs as many outputs as inputs):
//   "stiffness": {IN: {OUT: {"re": [F], "im": [F]}}}     H(f)^-1, input unit per output unit (N/m)
// Only these keys are written (other tools parse this contract).
// Exit 2 on bad input (file, column, flag), 1 when the inputs are perfectly coupled (Gxx singular
// in the band with input power) or H is singular there with --stiffness; no file is written then.

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/channels.hpp"
#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "estimators/frf.hpp"

namespace stiffid::apps {
namespace {

struct FrfCommandOptions {
  std::string trial_path;
  std::string inputs;
  std::string outputs;
  int nfft = 256;
  double overlap = 0.5;
  std::string window = "hann";
  std::string detrend = "constant";
  double sample_rate_hz = 0.0;
  bool stiffness = false;
  std::string output_path;
};

void check_names(const data::Trial& trial, const std::vector<std::string>& names,
                 const std::string& flag) {
  for (const auto& name : names) {
    if (trial.find(name) >= 0) continue;
    std::string columns;
    for (const auto& c : trial.names) columns += " " + c;
    throw InputError(trial.source + ":1: " + flag + ": no column '" + name +
                     "' in the header (columns:" + columns + ")");
  }
}

// Series over frequency of entry (r, c) of per-frequency matrices.
template <typename Matrix, typename Fn>
std::vector<double> series(const std::vector<Matrix>& m, int r, int c, Fn fn) {
  std::vector<double> out(m.size());
  for (size_t f = 0; f < m.size(); ++f) out[f] = fn(m[f](r, c));
  return out;
}

std::vector<double> series(const std::vector<Eigen::MatrixXd>& m, int r, int c) {
  return series(m, r, c, [](double v) { return v; });
}

nlohmann::json complex_series(const std::vector<Eigen::MatrixXcd>& m, int r, int c) {
  return {{"re", series(m, r, c, [](std::complex<double> v) { return v.real(); })},
          {"im", series(m, r, c, [](std::complex<double> v) { return v.imag(); })}};
}

nlohmann::json band(const estimators::ErrorBand& b, int r, int c) {
  return {{"eps", series(b.eps, r, c)},
          {"lower", series(b.lower, r, c)},
          {"upper", series(b.upper, r, c)}};
}

std::vector<double> vector(const Eigen::VectorXd& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

nlohmann::json to_json(const estimators::FrfResult& r, const std::vector<std::string>& inputs,
                       const std::vector<std::string>& outputs) {
  nlohmann::json out;
  out["fs"] = r.sample_rate_hz;
  out["nfft"] = r.segment_length;
  out["segments"] = r.segments;
  out["inputs"] = inputs;
  out["outputs"] = outputs;
  out["frequency_hz"] = vector(r.frequency_hz);
  const auto& e = r.random_error;
  nlohmann::json& re = out["random_error"];
  re["averages"] = e.averages;
  re["equivalent_independent_segments"] = e.equivalent_independent_segments;
  re["confidence_factor"] = e.confidence_factor;
  for (size_t j = 0; j < outputs.size(); ++j) {
    const std::string& y = outputs[j];
    const int jj = static_cast<int>(j);
    out["coherence"]["multiple"][y] = vector(r.multiple_coherence.col(jj));
    re["coherence"]["multiple"][y] = band(e.multiple_coherence, jj, 0);
    for (size_t i = 0; i < inputs.size(); ++i) {
      const std::string& x = inputs[i];
      const int ii = static_cast<int>(i);
      out["frf"][y][x] = complex_series(r.h, jj, ii);
      out["coherence"]["ordinary"][y][x] = series(r.ordinary_coherence, jj, ii);
      out["coherence"]["partial"][y][x] = series(r.partial_coherence, jj, ii);
      re["frf_magnitude"][y][x] = band(e.frf_magnitude, jj, ii);
      re["coherence"]["ordinary"][y][x] = band(e.ordinary_coherence, jj, ii);
      re["coherence"]["partial"][y][x] = band(e.partial_coherence, jj, ii);
    }
  }
  out["condition_number"] = vector(r.condition_number);
  return out;
}

void run(const FrfCommandOptions& cli) {
  const auto inputs = data::split_list(cli.inputs, "--inputs");
  const auto outputs = data::split_list(cli.outputs, "--outputs");
  check_distinct(inputs, outputs);
  if (cli.nfft < 2) {
    throw InputError("--nfft: expected a segment length of at least 2 samples, got " +
                     std::to_string(cli.nfft));
  }
  if (!std::isfinite(cli.overlap) || cli.overlap < 0.0 || cli.overlap >= 1.0) {
    throw InputError("--overlap: expected a fraction in [0, 1), got " + number_text(cli.overlap));
  }
  const data::TrialCsvOptions csv = trial_csv_options(cli.sample_rate_hz);
  if (cli.stiffness && inputs.size() != outputs.size()) {
    throw InputError("--stiffness: inverting the FRF needs as many outputs as inputs, got " +
                     std::to_string(outputs.size()) + " outputs and " +
                     std::to_string(inputs.size()) + " inputs");
  }
  estimators::FrfOptions options;
  options.welch.segment_length = cli.nfft;
  options.welch.overlap = cli.overlap;
  options.welch.window = estimators::Window::parse(cli.window, "--window");
  options.welch.detrend = estimators::parse_detrend(cli.detrend, "--detrend");

  const data::Trial trial = data::read_trial_csv(cli.trial_path, csv);
  check_names(trial, inputs, "--inputs");
  check_names(trial, outputs, "--outputs");
  data::require_samples(trial, cli.nfft,
                        "one Welch segment of --nfft " + std::to_string(cli.nfft) + " samples");

  const estimators::FrfResult result = estimators::estimate_frf(trial, inputs, outputs, options);
  if (!result.status.ok) throw NumericalFailure(result.status.message);
  nlohmann::json out = to_json(result, inputs, outputs);
  if (cli.stiffness) {
    const estimators::InverseFrfResult k = estimators::invert_frf(result.h, result.in_band);
    if (!k.status.ok) throw NumericalFailure(trial.source + ": --stiffness: " + k.status.message);
    for (size_t i = 0; i < inputs.size(); ++i)
      for (size_t j = 0; j < outputs.size(); ++j)
        out["stiffness"][inputs[i]][outputs[j]] =
            complex_series(k.k, static_cast<int>(i), static_cast<int>(j));
  }
  data::write_json(cli.output_path, out);
}

}  // namespace

void add_frf_command(CLI::App& app) {
  auto cli = std::make_shared<FrfCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "frf",
      "MIMO frequency-response matrix (H1, Perreault et al. 1999 eqs 1-7) with ordinary, multiple "
      "and partial coherence, the condition number of Gxx and Bendat & Piersol random-error bands "
      "(JSON key random_error: averages, equivalent_independent_segments, confidence_factor c, "
      "frf_magnitude[OUT][IN] and coherence.{ordinary,partial}[OUT][IN], coherence.multiple[OUT], "
      "each {eps, lower, upper} with bands value (1 -/+ c eps))");
  sub->add_option("trial", cli->trial_path, "trial CSV (t column in s, or --fs)")->required();
  sub->add_option("--inputs", cli->inputs, "input channels, comma separated (e.g. fx,fy)")
      ->required();
  sub->add_option("--outputs", cli->outputs, "output channels, comma separated (e.g. x,y)")
      ->required();
  sub->add_option("--nfft", cli->nfft, "samples per Welch segment (and FFT)")
      ->capture_default_str();
  sub->add_option("--overlap", cli->overlap,
                  "fraction of a segment shared with the next, in [0, 1); noverlap = "
                  "floor(overlap * nfft)")
      ->capture_default_str();
  sub->add_option("--window", cli->window, "hann, hamming, kaiser:BETA or rect (periodic)")
      ->capture_default_str();
  sub->add_option("--detrend", cli->detrend, "per-segment detrend: constant, linear or none")
      ->capture_default_str();
  sub->add_option("--fs", cli->sample_rate_hz, "sampling rate in Hz (required without a t column)");
  sub->add_flag("--stiffness", cli->stiffness,
                "also write the inverse H(f)^-1 (e.g. stiffness in N/m from compliance in m/N) "
                "under the key \"stiffness\": {IN: {OUT: {re, im}}}");
  sub->add_option("-o,--output", cli->output_path, "output JSON file (default: stdout)");
  sub->callback([cli]() { run(*cli); });
}

}  // namespace stiffid::apps
