// `stiffid regress force-pulse|disp-full|disp-ss TRIAL.csv... [--onset auto|S] [--profile-hz 400]
//  [--baseline BASE.csv] [-o OUT.json]`: the classical regressions (fitting/regression.hpp).

#include <cmath>
#include <memory>

#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "fitting/regression.hpp"

namespace stiffid::apps {
namespace {

struct RegressArgs {
  std::string method;
  std::vector<std::string> trials;
  std::string onset = "auto";
  double profile_hz = 400.0;
  std::string baseline;
  std::string out;
};

void run_regress(const RegressArgs& a) {
  fitting::RegressionOptions o;
  o.method = fitting::parse_regression_method(a.method, "regress METHOD");
  o.profile_hz = a.profile_hz;
  if (a.onset != "auto") {
    std::size_t used = 0;
    double value = 0.0;
    try {
      value = std::stod(a.onset, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != a.onset.size() || !std::isfinite(value)) {
      throw InputError("--onset: expected auto or a time in s, got '" + a.onset + "'");
    }
    o.onset_s = value;
  }
  std::vector<data::Trial> trials;
  for (const std::string& path : a.trials) trials.push_back(data::read_trial_csv(path));
  std::unique_ptr<data::Trial> base;
  if (!a.baseline.empty()) base = std::make_unique<data::Trial>(data::read_trial_csv(a.baseline));
  data::write_json(a.out, fitting::to_json(fitting::regress(trials, base.get(), o)));
}

}  // namespace

void add_regress_command(CLI::App& app) {
  auto args = std::make_shared<RegressArgs>();
  CLI::App* cmd = app.add_subcommand(
      "regress", "Classical regressions dF = M dx'' + B dx' + K dx from perturbation trials");
  cmd->add_option("method", args->method, "force-pulse | disp-full | disp-ss")->required();
  cmd->add_option("trials", args->trials, "trial CSVs (t, th1, th2, x, y, fx, fy)")->required();
  cmd->add_option("--onset", args->onset,
                  "auto (from the force) or the onset time of every trial, s");
  cmd->add_option("--profile-hz", args->profile_hz, "rate of the PCHIP time profile, Hz");
  cmd->add_option("--baseline", args->baseline, "unperturbed trial (same columns) as baseline");
  cmd->add_option("-o,--output", args->out, "output JSON (stdout when absent)");
  cmd->callback([args]() { run_regress(*args); });
}

}  // namespace stiffid::apps
