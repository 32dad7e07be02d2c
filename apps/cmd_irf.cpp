// `stiffid irf`: two-sided MIMO impulse responses of a trial (estimators/irf.hpp).
//
//   stiffid irf TRIAL.csv --inputs fx,fy --outputs x,y --lags -0.1:1.0 [--pinv [RANK|mdl|tsvd]]
//               [--least-squares] [--fs HZ] [-o OUT.json]
//
// --lags A:B is in seconds; each end must be a whole number of samples at the trial's rate (within
// 1e-3 of a sample, the CSV reader's tolerance on time stamps), and A <= B. --pinv alone means
// --pinv mdl. Output JSON (stdout without -o):
//   {"fs", "inputs", "outputs", "lag_s", "irf": {OUT: {IN: [...]}}, "vaf_percent": {OUT: v},
//    "r2_percent": v, ...}
// vaf_percent and r2_percent come from the predicted outputs (as the shared reference); the
// correlation estimates of eqs 12-13 are in vaf_correlation_percent and r2_correlation_percent.

#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/channels.hpp"
#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "estimators/irf.hpp"

namespace stiffid::apps {
namespace {

// Largest distance of a lag end from a whole number of samples, in samples.
constexpr double kLagSampleTolerance = 1e-3;

struct IrfCommandOptions {
  std::string trial_path;
  std::string inputs;
  std::string outputs;
  std::string lags;
  std::string pinv;
  double sample_rate_hz = 0.0;
  std::string output_path;
  bool least_squares = false;
};

double parse_seconds(const std::string& text, const std::string& spec) {
  double value = 0.0;
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  const auto [ptr, error] = std::from_chars(begin, end, value);
  if (text.empty() || error != std::errc() || ptr != end || !std::isfinite(value)) {
    throw InputError("--lags: '" + spec + "': expected A:B in seconds (e.g. -0.1:1.0), '" + text +
                     "' is not a number");
  }
  return value;
}

int seconds_to_samples(double seconds, double sample_rate_hz, const std::string& spec) {
  const double samples = seconds * sample_rate_hz;
  const double rounded = std::round(samples);
  if (std::abs(samples - rounded) > kLagSampleTolerance || std::abs(rounded) > 1e9) {
    throw InputError("--lags: '" + spec + "': " + number_text(seconds) +
                     " s is not a whole number of samples at " + number_text(sample_rate_hz) +
                     " Hz (" + number_text(samples) + " samples)");
  }
  return static_cast<int>(rounded);
}

// The lag range A:B of --lags in s, checked for syntax and order.
std::pair<double, double> parse_lag_range_s(const std::string& spec) {
  const auto colon = spec.find(':');
  if (colon == std::string::npos || spec.find(':', colon + 1) != std::string::npos) {
    throw InputError("--lags: '" + spec + "': expected A:B in seconds (e.g. -0.1:1.0)");
  }
  const double first_s = parse_seconds(spec.substr(0, colon), spec);
  const double last_s = parse_seconds(spec.substr(colon + 1), spec);
  if (first_s > last_s) {
    throw InputError("--lags: '" + spec + "': the first lag must not exceed the last");
  }
  return {first_s, last_s};
}

// The lag range of --lags in samples at the trial's rate.
std::pair<int, int> lags_in_samples(const std::string& spec, double sample_rate_hz) {
  const auto [first_s, last_s] = parse_lag_range_s(spec);
  return {seconds_to_samples(first_s, sample_rate_hz, spec),
          seconds_to_samples(last_s, sample_rate_hz, spec)};
}

void parse_pinv(const std::string& text, CLI::Option* flag, estimators::IrfOptions& options) {
  if (flag->count() == 0) return;
  if (text.empty() || text == "mdl") {
    options.inverse = estimators::IrfInverse::mdl;
    return;
  }
  if (text == "tsvd") {
    options.inverse = estimators::IrfInverse::tsvd;
    return;
  }
  int rank = 0;
  const auto [ptr, error] = std::from_chars(text.data(), text.data() + text.size(), rank);
  if (error != std::errc() || ptr != text.data() + text.size() || rank < 1) {
    throw InputError("--pinv: '" + text + "': expected a positive rank, 'mdl' or 'tsvd'");
  }
  options.inverse = estimators::IrfInverse::rank;
  options.rank = rank;
}

const char* inverse_name(estimators::IrfInverse inverse) {
  switch (inverse) {
    case estimators::IrfInverse::rank:
      return "rank";
    case estimators::IrfInverse::mdl:
      return "mdl";
    case estimators::IrfInverse::tsvd:
      return "tsvd";
    case estimators::IrfInverse::full:
      break;
  }
  return "full";
}

nlohmann::json to_json(const estimators::IrfResult& result, const std::vector<std::string>& inputs,
                       const std::vector<std::string>& outputs,
                       const estimators::IrfOptions& options) {
  const estimators::IrfInverse inverse = options.inverse;
  const bool least_squares = options.least_squares;
  auto vector = [](const Eigen::VectorXd& v) {
    return std::vector<double>(v.data(), v.data() + v.size());
  };
  nlohmann::json out;
  out["fs"] = result.sample_rate_hz;
  out["inputs"] = inputs;
  out["outputs"] = outputs;
  out["lag_s"] = vector(result.lag_s);
  out["lag_samples"] = {result.first_lag, result.last_lag};
  for (int j = 0; j < result.outputs; ++j) {
    for (int i = 0; i < result.inputs; ++i)
      out["irf"][outputs[j]][inputs[i]] = vector(result.irf(j, i));
    out["vaf_percent"][outputs[j]] = result.vaf_percent(j);
    out["vaf_correlation_percent"][outputs[j]] = result.vaf_correlation_percent(j);
  }
  out["r2_percent"] = result.r2_percent;
  out["r2_correlation_percent"] = result.r2_correlation_percent;
  out["inverse"] = inverse_name(inverse);
  out["least_squares"] = least_squares;
  out["rank"] = result.rank;
  out["full_rank"] = result.full_rank;
  out["condition_number"] = result.condition_number;  // inf -> null
  out["samples"] = result.predicted.rows();
  return out;
}

void run(const IrfCommandOptions& cli, CLI::Option* pinv_flag) {
  estimators::IrfOptions options;
  parse_pinv(cli.pinv, pinv_flag, options);
  options.least_squares = cli.least_squares;
  const auto inputs = data::split_list(cli.inputs, "--inputs");
  const auto outputs = data::split_list(cli.outputs, "--outputs");
  check_distinct(inputs, outputs);
  const data::TrialCsvOptions csv = trial_csv_options(cli.sample_rate_hz);
  parse_lag_range_s(cli.lags);  // syntax errors before reading the file
  const data::Trial trial = data::read_trial_csv(cli.trial_path, csv);
  std::tie(options.first_lag, options.last_lag) = lags_in_samples(cli.lags, trial.sample_rate_hz);
  data::require_samples(trial, options.last_lag - options.first_lag + 2,
                        "the " + std::to_string(options.last_lag - options.first_lag + 1) +
                            " IRF lags of --lags " + cli.lags);

  const estimators::IrfResult result =
      estimators::estimate_irf(trial.column_view(inputs).matrix(),
                               trial.column_view(outputs).matrix(), trial.sample_rate_hz, options);
  if (!result.status.ok) throw NumericalFailure(result.status.message);
  data::write_json(cli.output_path, to_json(result, inputs, outputs, options));
}

}  // namespace

void add_irf_command(CLI::App& app) {
  auto cli = std::make_shared<IrfCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "irf", "Two-sided MIMO impulse responses from correlations (Perreault et al. 1999 eq 11)");
  sub->add_option("trial", cli->trial_path, "trial CSV (t column in s, or --fs)")->required();
  sub->add_option("--inputs", cli->inputs, "input channels, comma separated (e.g. fx,fy)")
      ->required();
  sub->add_option("--outputs", cli->outputs, "output channels, comma separated (e.g. x,y)")
      ->required();
  sub->add_option("--lags", cli->lags, "lag range A:B in s (A < 0: anticausal part)")
      ->required()
      ->allow_extra_args(false);
  CLI::Option* pinv = sub->add_option(
      "--pinv", cli->pinv,
      "robust pseudo-inverse (Westwick & Kearney 1997): keep RANK eigenvectors, or choose them "
      "by MDL (default when no value is given), or 'tsvd': MDL over eigenvectors in eigenvalue "
      "order");
  pinv->expected(0, 1);
  sub->add_flag(
      "--least-squares", cli->least_squares,
      "exact least squares: Psi = Z^T Z of the zero-padded lagged inputs instead of the "
      "biased-correlation Toeplitz matrix of eq 11 (no edge error; see estimators/irf.hpp)");
  sub->add_option("--fs", cli->sample_rate_hz, "sampling rate in Hz (required without a t column)");
  sub->add_option("-o,--output", cli->output_path, "output JSON file (default: stdout)");
  sub->callback([cli, pinv]() { run(*cli, pinv); });
}

}  // namespace stiffid::apps
