// `stiffid fit kv|pt|duffing TRIAL.csv --inputs f1,f2 --outputs x1,x2 [--hold foh|zoh]
//  [--starts 16] [--seed S] [--bounds FILE] [-o OUT.json]`: lumped-model fit to a time-series trial
// (fitting/lumped_fit.hpp). A fit that does not converge writes no file and exits 1.

#include <memory>

#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "fitting/lumped_fit.hpp"

namespace stiffid::apps {
namespace {

struct FitArgs {
  std::string model;
  std::string trial;
  std::string inputs;
  std::string outputs;
  std::string hold = "foh";
  int starts = 16;
  std::uint64_t seed = 0;
  std::string bounds;
  std::string frf;
  std::string tfa;
  double segment_s = 1.0;
  int max_iterations = 200;
  std::string out;
};

void run_fit(const FitArgs& a) {
  if (!a.frf.empty() || !a.tfa.empty()) {
    throw InputError(std::string(a.frf.empty() ? "--tfa" : "--frf") +
                     ": fits to frequency responses and time-frequency estimates are not "
                     "available in this build; give TRIAL.csv with --inputs and --outputs");
  }
  if (a.trial.empty()) throw InputError("fit: expected TRIAL.csv (or --frf / --tfa)");
  if (a.inputs.empty()) throw InputError("--inputs: expected the force channels, e.g. fx,fy");
  if (a.outputs.empty()) throw InputError("--outputs: expected the displacement channels, e.g. x,y");
  fitting::LumpedFitOptions o;
  o.model = fitting::parse_lumped_model(a.model, "fit MODEL");
  o.hold = fitting::parse_input_hold(a.hold);
  o.starts = a.starts;
  o.seed = a.seed;
  o.segment_s = a.segment_s;
  o.max_iterations = a.max_iterations;
  if (!a.bounds.empty()) o.ranges = fitting::read_ranges_json(a.bounds, o.model);
  const data::Trial trial = data::read_trial_csv(a.trial);
  const fitting::LumpedFitResult r =
      fitting::fit_lumped(trial, data::split_list(a.inputs, "--inputs"),
                          data::split_list(a.outputs, "--outputs"), o);
  if (!r.status.ok) throw NumericalFailure(r.status.message);
  data::write_json(a.out, fitting::to_json(r));
}

}  // namespace

void add_fit_command(CLI::App& app) {
  auto args = std::make_shared<FitArgs>();
  CLI::App* cmd = app.add_subcommand(
      "fit", "Fit a lumped model (kv, pt, duffing) to a trial: forces in, displacements out");
  cmd->add_option("model", args->model, "kv | pt | duffing")->required();
  cmd->add_option("trial", args->trial, "trial CSV (t column and channels)");
  cmd->add_option("--inputs", args->inputs, "force channels (N), comma separated");
  cmd->add_option("--outputs", args->outputs, "displacement channels (m), comma separated");
  cmd->add_option("--hold", args->hold, "inputs between samples: foh (linear) or zoh (held)");
  cmd->add_option("--starts", args->starts, "multi-start local solves (box centre + Latin hypercube)");
  cmd->add_option("--seed", args->seed, "seed of the Latin hypercube");
  cmd->add_option("--bounds", args->bounds, "JSON {NAME: [lower, upper]} start box per matrix");
  cmd->add_option("--segment", args->segment_s, "multiple-shooting segment length, s (0: single)");
  cmd->add_option("--max-iterations", args->max_iterations, "iterations per local solve stage");
  cmd->add_option("--frf", args->frf, "fit to a `stiffid frf` JSON (not available yet)");
  cmd->add_option("--tfa", args->tfa, "fit to a `stiffid tfa` JSON (not available yet)");
  cmd->add_option("-o,--output", args->out, "output JSON (stdout when absent)");
  cmd->callback([args]() { run_fit(*args); });
}

}  // namespace stiffid::apps
