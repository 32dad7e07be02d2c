#include "validation/study.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include "data/output.hpp"
#include "validation/progress.hpp"
#include "validation/study_keys.hpp"
#include "validation/study_mpi.hpp"

namespace stiffid::validation {
namespace fs = std::filesystem;

void EvaluatorRegistry::add(const std::string& name, CellEvaluator evaluator,
                            const std::string& description) {
  entries_[name] = {std::move(evaluator), description};
}

const CellEvaluator* EvaluatorRegistry::find(const std::string& name) const {
  const auto it = entries_.find(name);
  return it == entries_.end() ? nullptr : &it->second.first;
}

std::vector<std::string> EvaluatorRegistry::describe() const {
  std::vector<std::string> lines;
  for (const auto& [name, entry] : entries_) lines.push_back(name + ": " + entry.second);
  return lines;
}

CellOutcome synthetic_evaluator(const nlohmann::json& spec, std::uint64_t seed) {
  SpecKeys keys(spec, "evaluator 'synthetic'");
  const double mean = keys.number("mean", 0.0, -1e300, 1e300);
  const double sd = keys.number("sd", 1.0, 0.0, 1e300);
  const long samples = keys.integer("samples", 100, 1, 100000000);
  const long delay_ms = keys.integer("delay_ms", 0, 0, 3600000);
  const bool fail = keys.boolean("fail", false);
  keys.reject_unknown();
  if (delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  if (fail) return {Status::failure("synthetic failure requested by the spec"), {}};
  std::mt19937_64 generator(seed);
  std::normal_distribution<double> normal(mean, sd);
  // Welford's running mean and variance: one pass, no catastrophic cancellation.
  double running_mean = 0.0;
  double m2 = 0.0;
  double first = 0.0;
  for (long i = 0; i < samples; ++i) {
    const double x = normal(generator);
    if (i == 0) first = x;
    const double delta = x - running_mean;
    running_mean += delta / static_cast<double>(i + 1);
    m2 += delta * (x - running_mean);
  }
  const double sample_sd = samples > 1 ? std::sqrt(m2 / static_cast<double>(samples - 1)) : 0.0;
  return {Status::success(),
          {{"sample_mean", running_mean}, {"sample_sd", sample_sd}, {"first_draw", first}}};
}

namespace {

std::string rank_store_path(const std::string& store, int rank) {
  return store + ".rank" + std::to_string(rank);
}

// Leftover per-rank stores of an earlier MPI run (any number of ranks) next to `store`.
std::vector<std::string> rank_stores(const std::string& store) {
  std::vector<std::string> found;
  const fs::path path(store);
  const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const std::string prefix = path.filename().string() + ".rank";
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(folder, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    if (!rest.empty() && rest.find_first_not_of("0123456789") == std::string::npos) {
      found.push_back(entry.path().string());
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

void remove_rank_stores(const std::string& store) {
  for (const auto& path : rank_stores(store)) ResultStore::remove_files(path);
}

// Keeps the metrics the design asks for; a metric the evaluator does not make is a spec error.
std::map<std::string, double> kept_metrics(const StudySpec& spec, int design_index,
                                           std::map<std::string, double> metrics) {
  const Design& design = spec.designs[design_index];
  if (design.metrics.empty()) return metrics;
  std::map<std::string, double> kept;
  for (const auto& name : design.metrics) {
    const auto it = metrics.find(name);
    if (it == metrics.end()) {
      std::string made;
      for (const auto& [m, v] : metrics) made += (made.empty() ? "" : ", ") + m;
      throw InputError(spec.source + ": key 'designs/" + std::to_string(design_index) +
                       "/metrics': evaluator '" + design.evaluator + "' makes no metric '" + name +
                       "'; it makes: " + made);
    }
    kept.insert(*it);
  }
  return kept;
}

CellRecord evaluate_cell(const StudySpec& spec, const Cell& cell, const CellEvaluator& evaluator) {
  const Design& design = spec.designs[cell.design];
  CellRecord record;
  record.cell = cell.index;
  record.design = design.name;
  record.levels_json = cell.levels.dump();
  record.replicate = cell.replicate;
  record.seed = cell.seed;
  record.started_utc = ResultStore::utc_now();
  CellOutcome outcome = evaluator(fill_template(design, cell), cell.seed);
  record.finished_utc = ResultStore::utc_now();
  record.ok = outcome.status.ok;
  record.message = outcome.status.message;
  if (record.ok) record.metrics = kept_metrics(spec, cell.design, std::move(outcome.metrics));
  return record;
}

// Evaluates `pending` cells with TBB, writing each to `store` as it finishes.
void compute_cells(const StudySpec& spec, const std::vector<const Cell*>& pending,
                   const std::vector<const CellEvaluator*>& evaluators, ResultStore& store,
                   int threads, ProgressBar& progress) {
  std::mutex store_mutex;
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, pending.size(), 1),
        [&](const tbb::blocked_range<std::size_t>& range) {
          for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Cell& cell = *pending[i];
            const CellRecord record = evaluate_cell(spec, cell, *evaluators[cell.design]);
            std::lock_guard<std::mutex> lock(store_mutex);
            store.write_cell(record);
            progress.tick();
          }
        },
        tbb::simple_partitioner());
  });
}

std::vector<const CellEvaluator*> resolve_evaluators(const StudySpec& spec,
                                                     const EvaluatorRegistry& registry) {
  std::vector<const CellEvaluator*> evaluators;
  for (std::size_t d = 0; d < spec.designs.size(); ++d) {
    const CellEvaluator* evaluator = registry.find(spec.designs[d].evaluator);
    if (!evaluator) {
      std::string known;
      for (const auto& line : registry.describe()) known += "\n  " + line;
      throw InputError(spec.source + ": key 'designs/" + std::to_string(d) +
                       "/evaluator': unknown evaluator '" + spec.designs[d].evaluator +
                       "'; expected one of:" + known);
    }
    evaluators.push_back(evaluator);
  }
  return evaluators;
}

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string level_text(const nlohmann::json& level) {
  return level.is_string() ? level.get<std::string>() : level.dump();
}

std::string number_text(double value) {
  if (std::isnan(value)) return "NA";
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

std::string factor_cells(const std::vector<std::string>& factors, const nlohmann::json& levels) {
  std::string out;
  for (const auto& f : factors) {
    out += ",";
    if (levels.contains(f)) out += csv_field(level_text(levels.at(f)));
  }
  return out;
}

}  // namespace

StudyResult run_study(const StudySpec& spec, const StudyOptions& options,
                      const EvaluatorRegistry& registry) {
  const auto start = std::chrono::steady_clock::now();
  if (options.store_path.empty()) throw InputError("--store: expected a store file path");
  if (options.threads < 0) throw InputError("--threads: expected 0 (all cores) or more");
  const std::vector<const CellEvaluator*> evaluators = resolve_evaluators(spec, registry);
  const std::vector<Cell> cells = enumerate_cells(spec);
  const StoreHeader header{spec.name, spec.hash(), spec.to_json().dump(), version()};
  const std::string& path = options.store_path;

  MpiWorld world;
  StudyResult result;
  result.cells_total = static_cast<int>(cells.size());
  result.ranks = world.size();
  result.is_root = world.rank() == 0;

  // Rank 0 prepares the main store: a fresh one, or the resumed one with the cells of any rank
  // stores a killed MPI run left behind merged in.
  std::unique_ptr<ResultStore> main_store;
  bool setup_failed = false;
  std::string setup_error;
  if (world.rank() == 0) {
    try {
      if (options.resume) {
        main_store = std::make_unique<ResultStore>(path, ResultStore::Mode::open_existing, header);
        for (const auto& part : rank_stores(path)) {
          main_store->merge_from(part);
          ResultStore::remove_files(part);
        }
      } else {
        remove_rank_stores(path);
        main_store = std::make_unique<ResultStore>(path, ResultStore::Mode::create, header);
      }
    } catch (const InputError& e) {
      setup_failed = true;
      setup_error = e.what();
    }
  }
  if (world.any(setup_failed)) {
    throw InputError(setup_failed ? setup_error : "rank 0 could not prepare the study store");
  }

  std::set<int> done;
  std::unique_ptr<ResultStore> rank_store;
  if (world.size() == 1) {
    done = main_store->stored_cells();
  } else {
    done = ResultStore(path, ResultStore::Mode::read_only).stored_cells();
    rank_store = std::make_unique<ResultStore>(rank_store_path(path, world.rank()),
                                               ResultStore::Mode::create, header);
  }
  std::vector<const Cell*> pending;
  for (const Cell& cell : cells) {
    if (cell.index % world.size() == world.rank() && !done.count(cell.index)) {
      pending.push_back(&cell);
    }
  }
  result.cells_resumed = static_cast<int>(done.size());

  ResultStore& target = world.size() == 1 ? *main_store : *rank_store;
  bool compute_failed = false;
  std::string compute_error;
  {
    const int mine = static_cast<int>(pending.size());
    const std::string label =
        "study " + spec.name +
        (world.size() > 1 ? " (rank 0 of " + std::to_string(world.size()) + ")" : "");
    ProgressBar progress(label, static_cast<int>(done.size()) + mine, static_cast<int>(done.size()),
                         options.progress && world.rank() == 0);
    try {
      compute_cells(spec, pending, evaluators, target, options.threads, progress);
    } catch (const InputError& e) {
      if (world.size() == 1) throw;
      compute_failed = true;
      compute_error = e.what();
    }
  }
  if (world.any(compute_failed)) {
    throw InputError(compute_failed ? compute_error
                                    : "another MPI rank stopped on an error (see its message)");
  }
  result.cells_computed = static_cast<int>(world.sum(static_cast<long>(pending.size())));

  if (world.size() > 1) {
    rank_store.reset();
    world.barrier();  // every rank store is complete and closed
    if (world.rank() == 0) {
      for (int r = 0; r < world.size(); ++r) {
        main_store->merge_from(rank_store_path(path, r));
        ResultStore::remove_files(rank_store_path(path, r));
      }
    }
    world.barrier();  // the main store holds every cell before any rank returns
  }
  const auto failed = main_store ? main_store->failed_cells()
                                 : ResultStore(path, ResultStore::Mode::read_only).failed_cells();
  result.cells_failed = static_cast<int>(failed.size());
  if (!failed.empty()) {
    result.status =
        Status::failure(std::to_string(failed.size()) + " of " + std::to_string(cells.size()) +
                        " cells failed; first: cell " + std::to_string(failed.front().first) +
                        ": " + failed.front().second);
  }
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string tidy_csv(const StudySpec& spec, const std::vector<ResultRow>& rows) {
  const std::vector<std::string> factors = spec.factor_names();
  std::ostringstream out;
  out << "study,design,cell,replicate,seed";
  for (const auto& f : factors) out << ',' << csv_field(f);
  out << ",metric,value\n";
  for (const ResultRow& row : rows) {
    out << csv_field(spec.name) << ',' << csv_field(row.design) << ',' << row.cell << ','
        << row.replicate << ',' << row.seed
        << factor_cells(factors, nlohmann::json::parse(row.levels_json)) << ','
        << csv_field(row.metric) << ',' << number_text(row.value) << '\n';
  }
  return out.str();
}

void export_tidy_csv(const StudySpec& spec, const std::string& store_path,
                     const std::string& csv_path) {
  const ResultStore store(store_path, ResultStore::Mode::read_only);
  data::write_file_atomically(csv_path, tidy_csv(spec, store.rows()));
}

std::vector<SummaryRow> summarize(const std::vector<ResultRow>& rows) {
  std::vector<SummaryRow> summary;
  std::map<std::tuple<std::string, std::string, std::string>, std::vector<double>> groups;
  for (const ResultRow& row : rows) {
    const auto key = std::make_tuple(row.design, row.levels_json, row.metric);
    auto [it, fresh] = groups.try_emplace(key);
    if (fresh) {
      summary.push_back(
          {row.design, nlohmann::json::parse(row.levels_json), row.metric, 0, 0.0, 0.0});
    }
    if (std::isfinite(row.value)) it->second.push_back(row.value);
  }
  for (SummaryRow& s : summary) {
    const auto& values = groups.at(std::make_tuple(s.design, s.levels.dump(), s.metric));
    s.n = static_cast<int>(values.size());
    if (s.n == 0) {
      s.mean = s.sd = std::nan("");
      continue;
    }
    double sum = 0.0;
    for (double v : values) sum += v;
    s.mean = sum / s.n;
    double squares = 0.0;
    for (double v : values) squares += (v - s.mean) * (v - s.mean);
    s.sd = s.n > 1 ? std::sqrt(squares / (s.n - 1)) : 0.0;
  }
  return summary;
}

std::string summary_csv(const StudySpec& spec, const std::vector<SummaryRow>& summary) {
  const std::vector<std::string> factors = spec.factor_names();
  std::ostringstream out;
  out << "design";
  for (const auto& f : factors) out << ',' << csv_field(f);
  out << ",metric,n,mean,sd\n";
  for (const SummaryRow& s : summary) {
    out << csv_field(s.design) << factor_cells(factors, s.levels) << ',' << csv_field(s.metric)
        << ',' << s.n << ',' << number_text(s.mean) << ',' << number_text(s.sd) << '\n';
  }
  return out.str();
}

void write_summary_report(const StudySpec& spec, const std::vector<ResultRow>& rows,
                          const std::string& folder) {
  const std::vector<SummaryRow> summary = summarize(rows);
  data::write_file_atomically((fs::path(folder) / "summary.csv").string(),
                              summary_csv(spec, summary));
  std::ostringstream md;
  md << "# Study " << spec.name << "\n\n"
     << "stiffid " << version() << ", spec hash `" << spec.hash() << "`, seed " << spec.seed << ", "
     << spec.replicates << " replicate(s) per cell; values are mean +- SD over "
     << "replicates.\n";
  for (const Design& design : spec.designs) {
    std::vector<std::string> metrics;
    std::vector<std::string> combos;
    std::map<std::pair<std::string, std::string>, const SummaryRow*> table;
    for (const SummaryRow& s : summary) {
      if (s.design != design.name) continue;
      if (std::find(metrics.begin(), metrics.end(), s.metric) == metrics.end()) {
        metrics.push_back(s.metric);
      }
      if (std::find(combos.begin(), combos.end(), s.levels.dump()) == combos.end()) {
        combos.push_back(s.levels.dump());
      }
      table[{s.levels.dump(), s.metric}] = &s;
    }
    md << "\n## " << design.name << " (evaluator " << design.evaluator << ")\n\n|";
    for (const auto& f : design.factors) md << ' ' << f.name << " |";
    for (const auto& m : metrics) md << ' ' << m << " |";
    md << "\n|";
    for (std::size_t i = 0; i < design.factors.size() + metrics.size(); ++i) md << " --- |";
    md << '\n';
    for (const auto& combo : combos) {
      const nlohmann::json levels = nlohmann::json::parse(combo);
      md << '|';
      for (const auto& f : design.factors) md << ' ' << level_text(levels.at(f.name)) << " |";
      for (const auto& m : metrics) {
        const auto it = table.find({combo, m});
        char cell[96] = "";
        if (it != table.end()) {
          std::snprintf(cell, sizeof cell, "%.4g +- %.2g (n=%d)", it->second->mean, it->second->sd,
                        it->second->n);
        }
        md << ' ' << cell << " |";
      }
      md << '\n';
    }
  }
  data::write_file_atomically((fs::path(folder) / "report.md").string(), md.str());
}

void write_report(const StudySpec& spec, const std::string& store_path, const std::string& folder) {
  const auto reporters = builtin_reporters();
  const auto it = reporters.find(spec.report);
  if (it == reporters.end()) {
    std::string known;
    for (const auto& [name, fn] : reporters) known += (known.empty() ? "" : ", ") + name;
    throw InputError(spec.source + ": key 'report': unknown reporter '" + spec.report +
                     "'; expected one of " + known);
  }
  std::error_code error;
  fs::create_directories(folder, error);
  if (error || !fs::is_directory(folder)) {
    throw InputError("--report " + folder + ": cannot create the folder: " + error.message());
  }
  const ResultStore store(store_path, ResultStore::Mode::read_only);
  it->second(spec, store.rows(), folder);
}

StudySpec load_study(const std::string& path_or_name) {
  if (fs::exists(path_or_name) || path_or_name.find('/') != std::string::npos ||
      path_or_name.ends_with(".json")) {
    return read_study_spec(path_or_name);
  }
  const char* dir = std::getenv("STIFFID_STUDIES_DIR");
  const fs::path folder =
      dir ? fs::path(dir) : fs::path(STIFFID_SOURCE_DIR) / "validation" / "studies";
  const fs::path file = folder / (path_or_name + ".json");
  if (!fs::exists(file)) {
    std::string known;
    std::error_code error;
    for (const auto& entry : fs::directory_iterator(folder, error)) {
      if (entry.path().extension() == ".json") {
        known += (known.empty() ? "" : ", ") + entry.path().stem().string();
      }
    }
    throw InputError("SPEC '" + path_or_name +
                     "': no such study file and no built-in study of "
                     "that name (built-in studies in " +
                     folder.string() + ": " + (known.empty() ? "none" : known) + ")");
  }
  StudySpec spec = read_study_spec(file.string());
  return spec;
}

}  // namespace stiffid::validation
