// `stiffid simulate SPEC [-o TRIAL.csv] [--truth TRUTH.json] [--seed N]`: one simulated trial with
// its truth (models/simulate.hpp; spec format in docs/simulator.md).

#include <iostream>
#include <memory>
#include <optional>
#include <random>

#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/output.hpp"
#include "models/simulate.hpp"
#include "models/spec.hpp"

namespace stiffid::apps {

namespace {
struct SimulateFlags {
  std::string spec;
  std::string output;
  std::string truth;
  std::optional<unsigned long long> seed;
};
}  // namespace

void add_simulate_command(CLI::App& app) {
  auto flags = std::make_shared<SimulateFlags>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate one trial (arm or endpoint model) from a JSON spec, with its truth");
  cmd->add_option("SPEC", flags->spec, "JSON trial spec (see docs/simulator.md)")->required();
  cmd->add_option("-o,--output", flags->output,
                  "trial CSV (t plus the channels; stdout when absent or -)");
  cmd->add_option("--truth", flags->truth, "truth JSON: K(t), C(t), M(theta(t)), paths, forces");
  cmd->add_option("--seed", flags->seed, "random seed (overrides the spec's \"seed\")");
  cmd->callback([flags] {
    models::TrialSpec spec = models::read_trial_spec(flags->spec);
    if (flags->seed) spec.seed = *flags->seed;
    std::mt19937_64 rng(spec.seed);
    const models::SimulationResult result = models::simulate(spec, rng);
    if (!result.status.ok) throw NumericalFailure(flags->spec + ": " + result.status.message);
    const std::string csv = data::trial_to_csv(result.trial, false);
    if (flags->output.empty() || flags->output == "-") {
      std::cout << csv;
    } else {
      data::write_file_atomically(flags->output, csv);
    }
    if (!flags->truth.empty()) {
      nlohmann::json truth = models::truth_to_json(result);
      truth["spec"] = models::trial_spec_to_json(spec);
      data::write_json(flags->truth, truth);
    }
  });
}

}  // namespace stiffid::apps
