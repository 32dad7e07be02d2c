#pragma once
// The result store of a study: one SQLite database file (WAL journal).
//
// Tables:
//   study(key TEXT PRIMARY KEY, value TEXT)        name, spec_hash, spec (canonical JSON),
//                                                  stiffid_version, created_utc
//   cells(cell INTEGER PRIMARY KEY, design, levels, replicate, seed, status, message,
//         spec_hash, stiffid_version, started_utc, finished_utc)
//   results(cell, metric, value, spec_hash, stiffid_version, started_utc, finished_utc,
//           UNIQUE(cell, metric))                  one row per cell and metric
// A cell's `cells` row and all its `results` rows are written in one transaction, so a killed
// process leaves whole cells only and a resumed study recomputes exactly the missing ones.
// Timestamps are UTC, ISO 8601 with milliseconds. A NaN metric is stored as NULL.

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

struct sqlite3;

namespace stiffid::validation {

/// What identifies the study a store belongs to.
struct StoreHeader {
  std::string name;             ///< study name
  std::string spec_hash;        ///< StudySpec::hash()
  std::string spec_json;        ///< StudySpec::to_json().dump()
  std::string stiffid_version;  ///< stiffid::version() of the run that created the store
};

/// One computed cell.
struct CellRecord {
  int cell = 0;
  std::string design;
  std::string levels_json;  ///< canonical JSON of {factor: level}
  int replicate = 0;
  std::uint64_t seed = 0;
  bool ok = true;       ///< false when the evaluator reported a numerical failure
  std::string message;  ///< why it failed (empty when ok)
  std::string started_utc;
  std::string finished_utc;
  std::map<std::string, double> metrics;  ///< metric -> value (empty for a failed cell)
};

/// One stored metric value, with its cell's identity.
struct ResultRow {
  int cell = 0;
  std::string design;
  std::string levels_json;
  int replicate = 0;
  std::uint64_t seed = 0;
  std::string metric;
  double value = 0.0;  ///< NaN when stored as NULL
};

class ResultStore {
 public:
  enum class Mode { create, open_existing, read_only };

  /// create: a new store (an existing file at `path` and its -wal/-shm files are removed first);
  /// open_existing: the file must exist and belong to `header` (same spec hash), else InputError;
  /// read_only: opens an existing store for reading (header not checked).
  ResultStore(const std::string& path, Mode mode, const StoreHeader& header = {});
  ~ResultStore();
  ResultStore(const ResultStore&) = delete;
  ResultStore& operator=(const ResultStore&) = delete;

  const std::string& path() const { return path_; }
  /// The header stored in the file.
  StoreHeader header() const;
  /// Indices of the cells already stored (ok or failed).
  std::set<int> stored_cells() const;
  /// Number of stored cells whose evaluator failed, and the first one's message.
  std::vector<std::pair<int, std::string>> failed_cells() const;
  /// Writes one cell and its metrics in one transaction. Writing a cell already present is a
  /// broken invariant of the runner (the UNIQUE constraints reject it).
  void write_cell(const CellRecord& record);
  /// Every metric value, ordered by cell then metric name.
  std::vector<ResultRow> rows() const;
  /// Copies every cell and result of the store at `other_path` (same spec hash) into this one in
  /// one transaction; cells already present are kept as they are.
  void merge_from(const std::string& other_path);

  /// Removes a store file and its -wal/-shm companions (no error when absent).
  static void remove_files(const std::string& path);
  /// UTC now as "YYYY-MM-DDTHH:MM:SS.mmmZ".
  static std::string utc_now();

 private:
  void exec(const std::string& sql) const;
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace stiffid::validation
