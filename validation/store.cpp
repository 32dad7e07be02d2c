#include "validation/store.hpp"

#include <sqlite3.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <limits>

#include "data/error.hpp"

namespace stiffid::validation {
namespace {

// A prepared statement that finalizes itself.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql, const std::string& path) : path_(path) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK) {
      throw InputError(path + ": SQLite cannot prepare '" + sql + "': " + sqlite3_errmsg(db));
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  void bind(int i, const std::string& text) {
    sqlite3_bind_text(stmt_, i, text.c_str(), static_cast<int>(text.size()), SQLITE_TRANSIENT);
  }
  void bind(int i, std::int64_t value) { sqlite3_bind_int64(stmt_, i, value); }
  void bind_real(int i, double value) {
    if (std::isnan(value)) {
      sqlite3_bind_null(stmt_, i);
    } else {
      sqlite3_bind_double(stmt_, i, value);
    }
  }
  /// Steps once; true when a row is available.
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw InputError(path_ + ": SQLite error: " + sqlite3_errmsg(sqlite3_db_handle(stmt_)));
  }
  void reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  std::string text(int col) const {
    const auto* p = sqlite3_column_text(stmt_, col);
    return p ? reinterpret_cast<const char*>(p) : "";
  }
  std::int64_t integer(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const {
    if (sqlite3_column_type(stmt_, col) == SQLITE_NULL) {
      return std::numeric_limits<double>::quiet_NaN();
    }
    return sqlite3_column_double(stmt_, col);
  }

 private:
  sqlite3_stmt* stmt_ = nullptr;
  std::string path_;
};

// Seeds are unsigned 64-bit; SQLite integers are signed, so seeds are stored as 16 hex digits.
std::string seed_text(std::uint64_t seed) {
  char buffer[17];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(seed));
  return buffer;
}
std::uint64_t seed_value(const std::string& text) { return std::stoull(text, nullptr, 16); }

const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS study(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS cells(
  cell INTEGER PRIMARY KEY, design TEXT NOT NULL, levels TEXT NOT NULL,
  replicate INTEGER NOT NULL, seed TEXT NOT NULL, status TEXT NOT NULL, message TEXT NOT NULL,
  spec_hash TEXT NOT NULL, stiffid_version TEXT NOT NULL,
  started_utc TEXT NOT NULL, finished_utc TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS results(
  cell INTEGER NOT NULL, metric TEXT NOT NULL, value REAL,
  spec_hash TEXT NOT NULL, stiffid_version TEXT NOT NULL,
  started_utc TEXT NOT NULL, finished_utc TEXT NOT NULL,
  UNIQUE(cell, metric));
)sql";

}  // namespace

std::string ResultStore::utc_now() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t seconds = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buffer;
}

void ResultStore::remove_files(const std::string& path) {
  std::error_code ignored;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
    std::filesystem::remove(path + suffix, ignored);
  }
}

ResultStore::ResultStore(const std::string& path, Mode mode, const StoreHeader& header)
    : path_(path) {
  if (mode == Mode::create) {
    remove_files(path);
  } else if (!std::filesystem::exists(path)) {
    throw InputError(
        path + ": no such study store" +
        (mode == Mode::open_existing ? " to resume; run without --resume to start" : ""));
  }
  const int flags =
      mode == Mode::read_only ? SQLITE_OPEN_READONLY : (SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  if (sqlite3_open_v2(path.c_str(), &db_, flags | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(path + ": cannot open the study store: " + why);
  }
  // Several processes (MPI ranks, a test polling progress) may touch a store: wait for locks.
  sqlite3_busy_timeout(db_, 30000);
  if (mode == Mode::read_only) return;
  try {
    exec("PRAGMA journal_mode=WAL;");
    // In WAL mode NORMAL keeps every committed transaction across a process kill (only a power
    // loss can drop the last ones), which is what --resume relies on.
    exec("PRAGMA synchronous=NORMAL;");
    exec(kSchema);
    if (mode == Mode::create) {
      exec("BEGIN IMMEDIATE;");
      Statement insert(db_, "INSERT OR REPLACE INTO study(key, value) VALUES(?1, ?2);", path_);
      const std::pair<const char*, std::string> entries[] = {
          {"name", header.name},
          {"spec_hash", header.spec_hash},
          {"spec", header.spec_json},
          {"stiffid_version", header.stiffid_version},
          {"created_utc", utc_now()}};
      for (const auto& [key, value] : entries) {
        insert.bind(1, std::string(key));
        insert.bind(2, value);
        insert.step();
        insert.reset();
      }
      exec("COMMIT;");
    } else {
      const StoreHeader stored = this->header();
      if (stored.spec_hash != header.spec_hash) {
        throw InputError(path + ": this store holds study '" + stored.name + "' with spec hash " +
                         stored.spec_hash + ", but the study to resume has hash " +
                         header.spec_hash +
                         " (a different spec or --replicates); resume with the same spec, or run "
                         "without --resume to start again");
      }
    }
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

ResultStore::~ResultStore() { sqlite3_close(db_); }

void ResultStore::exec(const std::string& sql) const {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string why = error ? error : "unknown error";
    sqlite3_free(error);
    throw InputError(path_ + ": SQLite error: " + why);
  }
}

StoreHeader ResultStore::header() const {
  StoreHeader h;
  Statement select(db_, "SELECT key, value FROM study;", path_);
  bool any = false;
  while (select.step()) {
    any = true;
    const std::string key = select.text(0);
    if (key == "name") h.name = select.text(1);
    if (key == "spec_hash") h.spec_hash = select.text(1);
    if (key == "spec") h.spec_json = select.text(1);
    if (key == "stiffid_version") h.stiffid_version = select.text(1);
  }
  if (!any) throw InputError(path_ + ": not a stiffid study store (no study header)");
  return h;
}

std::set<int> ResultStore::stored_cells() const {
  std::set<int> cells;
  Statement select(db_, "SELECT cell FROM cells;", path_);
  while (select.step()) cells.insert(static_cast<int>(select.integer(0)));
  return cells;
}

std::vector<std::pair<int, std::string>> ResultStore::failed_cells() const {
  std::vector<std::pair<int, std::string>> failed;
  Statement select(db_, "SELECT cell, message FROM cells WHERE status <> 'ok' ORDER BY cell;",
                   path_);
  while (select.step()) failed.emplace_back(static_cast<int>(select.integer(0)), select.text(1));
  return failed;
}

void ResultStore::write_cell(const CellRecord& record) {
  const StoreHeader h = header();
  exec("BEGIN IMMEDIATE;");
  try {
    Statement cell(db_,
                   "INSERT INTO cells(cell, design, levels, replicate, seed, status, message, "
                   "spec_hash, stiffid_version, started_utc, finished_utc) "
                   "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11);",
                   path_);
    cell.bind(1, std::int64_t{record.cell});
    cell.bind(2, record.design);
    cell.bind(3, record.levels_json);
    cell.bind(4, std::int64_t{record.replicate});
    cell.bind(5, seed_text(record.seed));
    cell.bind(6, std::string(record.ok ? "ok" : "failed"));
    cell.bind(7, record.message);
    cell.bind(8, h.spec_hash);
    cell.bind(9, h.stiffid_version);
    cell.bind(10, record.started_utc);
    cell.bind(11, record.finished_utc);
    cell.step();
    Statement result(db_,
                     "INSERT INTO results(cell, metric, value, spec_hash, stiffid_version, "
                     "started_utc, finished_utc) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7);",
                     path_);
    for (const auto& [metric, value] : record.metrics) {
      result.bind(1, std::int64_t{record.cell});
      result.bind(2, metric);
      result.bind_real(3, value);
      result.bind(4, h.spec_hash);
      result.bind(5, h.stiffid_version);
      result.bind(6, record.started_utc);
      result.bind(7, record.finished_utc);
      result.step();
      result.reset();
    }
    exec("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

std::vector<ResultRow> ResultStore::rows() const {
  std::vector<ResultRow> rows;
  Statement select(db_,
                   "SELECT c.cell, c.design, c.levels, c.replicate, c.seed, r.metric, r.value "
                   "FROM results r JOIN cells c ON c.cell = r.cell ORDER BY c.cell, r.metric;",
                   path_);
  while (select.step()) {
    rows.push_back({static_cast<int>(select.integer(0)), select.text(1), select.text(2),
                    static_cast<int>(select.integer(3)), seed_value(select.text(4)), select.text(5),
                    select.real(6)});
  }
  return rows;
}

void ResultStore::merge_from(const std::string& other_path) {
  {
    const ResultStore other(other_path, Mode::read_only);
    if (other.header().spec_hash != header().spec_hash) {
      throw InputError(other_path + ": rank store of a different study spec; cannot merge");
    }
  }
  Statement attach(db_, "ATTACH DATABASE ?1 AS part;", path_);
  attach.bind(1, other_path);
  attach.step();
  try {
    exec("BEGIN IMMEDIATE;");
    // Results first, filtered on cells not yet in the main store, then the cells themselves.
    exec(
        "INSERT INTO results SELECT * FROM part.results "
        "WHERE cell NOT IN (SELECT cell FROM main.cells);"
        "INSERT INTO cells SELECT * FROM part.cells "
        "WHERE cell NOT IN (SELECT cell FROM main.cells);"
        "COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    exec("DETACH DATABASE part;");
    throw;
  }
  exec("DETACH DATABASE part;");
}

}  // namespace stiffid::validation
