#pragma once
// The study runner: evaluates every cell of a declarative study (study_spec.hpp) in parallel,
// stores one row per cell and metric in an SQLite store (store.hpp), resumes killed runs, runs
// across MPI ranks, and exports tidy CSV, summaries and reports. Studies plug in through cell
// evaluators (name -> function) and reporters (name -> function), kept in explicit registries.

#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "validation/store.hpp"
#include "validation/study_spec.hpp"

namespace stiffid::validation {

/// What a cell evaluator returns: its metrics, or a numerical failure (tier 2) that is stored with
/// the cell and reported by the runner.
struct CellOutcome {
  Status status;
  std::map<std::string, double> metrics;  ///< metric name -> value (units in the name)
};

/// A cell evaluator computes a cell's metrics from its trial spec (the design's template with the
/// cell's levels filled in) and the cell's seed. It must be a pure function of (spec, seed) -- all
/// randomness from a generator seeded with `seed` -- and safe to call from several threads at once
/// for different cells. A wrong key in the spec is an InputError naming the key.
using CellEvaluator = std::function<CellOutcome(const nlohmann::json& spec, std::uint64_t seed)>;

class EvaluatorRegistry {
 public:
  /// Registers (or replaces) an evaluator.
  void add(const std::string& name, CellEvaluator evaluator, const std::string& description);
  /// The evaluator, or nullptr when none has that name.
  const CellEvaluator* find(const std::string& name) const;
  /// "name: description" lines, for messages and --help.
  std::vector<std::string> describe() const;

 private:
  std::map<std::string, std::pair<CellEvaluator, std::string>> entries_;
};

/// The evaluators shipped with stiffid:
/// - "synthetic": seeded draws with no physics, to exercise and test runners (see
///   synthetic_evaluator);
/// - "perreault1999.linear", "perreault1999.arm": Perreault et al. 1999 simulations
/// (perreault1999.hpp).
EvaluatorRegistry builtin_evaluators();

/// "synthetic" evaluator. Spec keys: "mean" (default 0), "sd" (>= 0, default 1), "samples"
/// (integer >= 1, default 100), "delay_ms" (integer >= 0, default 0: sleep per cell, to test
/// progress, kill and resume), "fail" (bool, default false: report a numerical failure).
/// Metrics: "sample_mean" and "sample_sd" (unbiased) of `samples` normal draws N(mean, sd^2) from
/// std::mt19937_64(seed), and "first_draw".
CellOutcome synthetic_evaluator(const nlohmann::json& spec, std::uint64_t seed);

struct StudyOptions {
  std::string store_path;  ///< SQLite store; required
  bool resume = false;     ///< continue the store at store_path (same spec hash) instead of
                           ///< replacing it
  int threads = 0;         ///< worker threads per process; 0 = all cores
  bool progress = false;   ///< draw a progress bar on stderr (the CLI sets it when stderr is a TTY)
};

struct StudyResult {
  Status status;           ///< failure when some cells reported a numerical failure
  int cells_total = 0;     ///< cells of the study
  int cells_resumed = 0;   ///< cells found already stored (with --resume)
  int cells_computed = 0;  ///< cells computed by this run (all ranks)
  int cells_failed = 0;    ///< stored cells whose evaluator failed (all runs)
  double wall_s = 0.0;     ///< wall time of this run, s
  int ranks = 1;           ///< MPI processes (1 without mpirun)
  bool is_root = true;     ///< false on MPI ranks other than 0, which must not export
};

/// Runs the study: enumerates its cells, skips those already stored (when resuming), evaluates the
/// rest in parallel with TBB and writes each finished cell to the store in its own transaction.
/// Under mpirun (MPI build), rank r of K evaluates the cells with index % K == r into its own store
/// STORE.rankR, and rank 0 merges them into STORE after a barrier; the stored values are identical
/// to a single-process run. Throws InputError for an unknown evaluator, a metric the evaluator does
/// not make, a bad trial spec, an unusable store, or mpirun without MPI support.
StudyResult run_study(const StudySpec& spec, const StudyOptions& options,
                      const EvaluatorRegistry& evaluators);

/// Tidy CSV of a store: header `study,design,cell,replicate,seed,<factor columns>,metric,value`,
/// one row per cell and metric ordered by cell then metric; factor columns are the union over
/// designs (empty where a design lacks the factor); values with 17 significant digits ("NA" for
/// NaN). Depends only on stored values, so identical runs give identical text.
std::string tidy_csv(const StudySpec& spec, const std::vector<ResultRow>& rows);
/// Reads the store at `store_path` and writes tidy_csv atomically to `csv_path`.
void export_tidy_csv(const StudySpec& spec, const std::string& store_path,
                     const std::string& csv_path);

/// Mean and SD over the replicates of one design, one combination of levels, one metric.
struct SummaryRow {
  std::string design;
  nlohmann::json levels;  ///< {factor: level}
  std::string metric;
  int n = 0;          ///< finite values averaged
  double mean = 0.0;  ///< NaN when n == 0
  double sd = 0.0;    ///< sample SD (n - 1); 0 when n == 1, NaN when n == 0
};
/// Summary rows in order of first appearance (cell order, then metric name).
std::vector<SummaryRow> summarize(const std::vector<ResultRow>& rows);
/// CSV of summarize(): `design,<factor columns>,metric,n,mean,sd`.
std::string summary_csv(const StudySpec& spec, const std::vector<SummaryRow>& summary);

/// A reporter writes a study's report files into a folder that exists.
using StudyReporter = std::function<void(const StudySpec& spec, const std::vector<ResultRow>& rows,
                                         const std::string& folder)>;
/// Reporters shipped with stiffid: "summary" (report.md and summary.csv, any study) and
/// "perreault1999" (perreault1999.hpp).
std::map<std::string, StudyReporter> builtin_reporters();
/// Creates `folder` and runs the reporter named by spec.report on the store's rows (InputError for
/// an unknown reporter or an unwritable folder).
void write_report(const StudySpec& spec, const std::string& store_path, const std::string& folder);
/// The generic reporter: summary.csv and report.md (a table of mean +- SD per design).
void write_summary_report(const StudySpec& spec, const std::vector<ResultRow>& rows,
                          const std::string& folder);

/// A study given on the command line: a path to a study file, or the name of a built-in study
/// (a file validation/studies/NAME.json of the source tree, or of $STIFFID_STUDIES_DIR when set).
StudySpec load_study(const std::string& path_or_name);

}  // namespace stiffid::validation
