// `stiffid study SPEC.json|NAME [--store FILE.sqlite] [--resume] [--threads N] [--replicates N]
//                               [--csv OUT.csv] [--report DIR]`
// Runs a declarative study (validation/study.hpp) into an SQLite store, then exports it.

#include <cstdio>
#include <iostream>
#include <memory>

#include "apps/commands.hpp"
#include "validation/progress.hpp"
#include "validation/study.hpp"

namespace stiffid::apps {
namespace {

struct StudyFlags {
  std::string spec;
  std::string store;
  bool resume = false;
  int threads = 0;
  int replicates = 0;
  std::string csv;
  std::string report;
};

void run(const StudyFlags& flags) {
  validation::StudySpec spec = validation::load_study(flags.spec);
  if (flags.replicates > 0) spec.replicates = flags.replicates;
  validation::StudyOptions options;
  options.store_path = flags.store.empty() ? spec.name + ".sqlite" : flags.store;
  options.resume = flags.resume;
  options.threads = flags.threads;
  options.progress = validation::stderr_is_terminal();
  const validation::StudyResult result =
      validation::run_study(spec, options, validation::builtin_evaluators());
  if (!result.is_root) return;
  std::printf("study %s: %d cells (%d resumed, %d computed, %d failed) in %.2f s",
              spec.name.c_str(), result.cells_total, result.cells_resumed, result.cells_computed,
              result.cells_failed, result.wall_s);
  if (result.ranks > 1) std::printf(" on %d MPI ranks", result.ranks);
  std::printf("; store %s\n", options.store_path.c_str());
  if (!flags.csv.empty()) {
    validation::export_tidy_csv(spec, options.store_path, flags.csv);
    std::printf("wrote %s\n", flags.csv.c_str());
  }
  if (!flags.report.empty()) {
    validation::write_report(spec, options.store_path, flags.report);
    std::printf("wrote report in %s\n", flags.report.c_str());
  }
  std::fflush(stdout);
  if (!result.status.ok) throw NumericalFailure(result.status.message);
}

}  // namespace

void add_study_command(CLI::App& app) {
  auto flags = std::make_shared<StudyFlags>();
  CLI::App* cmd = app.add_subcommand(
      "study",
      "Run a simulation study: every cell of a factorial design, in parallel, into an SQLite "
      "store (resumable; under mpirun the cells are shared among ranks)");
  cmd->add_option("SPEC", flags->spec,
                  "study file (JSON, see docs/studies.md) or a built-in study name "
                  "(perreault1999)")
      ->required();
  cmd->add_option("--store", flags->store,
                  "SQLite result store (default: NAME.sqlite in the current folder); replaced "
                  "unless --resume");
  cmd->add_flag("--resume", flags->resume,
                "continue the study in --store: compute only the cells it does not hold yet");
  cmd->add_option("--threads", flags->threads, "worker threads per process (0: all cores)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--replicates", flags->replicates,
                  "seed replicates per cell, overriding the study file")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--csv", flags->csv, "write every stored value as tidy CSV to this file");
  cmd->add_option("--report", flags->report,
                  "write the study's report (Markdown and CSV tables) into this folder");
  cmd->callback([flags] { run(*flags); });
}

}  // namespace stiffid::apps
