#pragma once
// CSV input and output: a generic table of text cells that remembers where each cell came from,
// and the trial reader/writer built on it.

#include <string>
#include <string_view>
#include <vector>

#include "data/trial.hpp"

namespace stiffid::data {

/// A CSV file as text cells. Row r of `cells` came from line `line_numbers[r]` of `source`.
struct CsvTable {
  std::string source;                           ///< file path (or a label) for messages
  std::vector<std::string> header;              ///< [C] column names as written
  std::vector<std::vector<std::string>> cells;  ///< [R][C] cells, trimmed, quotes removed
  std::vector<int> line_numbers;                ///< [R] 1-based line of each row

  int column_count() const { return static_cast<int>(header.size()); }
  int row_count() const { return static_cast<int>(cells.size()); }
  /// Index of a column; -1 when absent.
  int find(const std::string& name) const;
  /// Index of a column; throws InputError naming the file and the columns it has.
  int column(const std::string& name) const;
  /// "file:line:column" of a cell (1-based line and column), for messages.
  std::string where(int row, int col) const;
  /// The cell as a finite double; throws InputError naming file, line, column and the text.
  double number(int row, int col) const;
};

/// Parses CSV text: a header row, then rows with as many cells as the header (ragged rows, empty or
/// duplicate column names are InputErrors). Blank lines and lines starting with '#' are skipped,
/// and so is a UTF-8 byte-order mark before the header. Cells are separated by ','; a header of
/// one column holding ';' or a tab is an InputError that says so.
CsvTable parse_csv(const std::string& text, const std::string& source);
/// Reads and parses a CSV file; a missing or unreadable file is an InputError naming the path.
CsvTable read_csv(const std::string& path);

struct TrialCsvOptions {
  std::string time_column = "t";  ///< column holding time in s; absent -> sample_rate_hz is used
  double sample_rate_hz = 0.0;    ///< Hz; required when the file has no time column, and when
                                  ///< given with a time column it must agree with it
  double time_tolerance = 1e-3;   ///< largest deviation of a time stamp from the uniform grid, as
                                  ///< a fraction of the sampling step
};

/// Parses a trial from CSV text: a header row, then every column except time becomes a channel. A
/// header cell `name[unit]` (or `name (unit)`) sets the channel's unit. Every cell must be a finite
/// number; time must increase uniformly within the tolerance (an interval that is not the typical
/// step is named: missing or repeated rows). The header rules are parse_csv's. Errors name
/// source:line:column.
/// Cells are converted in place (no per-cell strings), straight into the trial's columns, on up to
/// max_threads() threads (data/parallel.hpp) for texts over 1 MiB; results do not depend on the
/// thread count.
Trial parse_trial_csv(std::string_view text, const std::string& source,
                      const TrialCsvOptions& options = {});
/// Reads a file (memory-mapped) and parses it with parse_trial_csv; a missing file is an
/// InputError naming it.
Trial read_trial_csv(const std::string& path, const TrialCsvOptions& options = {});

/// CSV text of a trial: a `t` column in s then one column per channel, full double precision.
/// With `with_units`, headers are written as `name[unit]` where a unit is known.
std::string trial_to_csv(const Trial& trial, bool with_units = false);
/// Writes trial_to_csv atomically (temporary file in the same folder, then rename).
void write_trial_csv(const std::string& path, const Trial& trial, bool with_units = false);

/// Splits "a,b,c" into names, trimming blanks; an empty item is an InputError naming `what`.
std::vector<std::string> split_list(const std::string& text, const std::string& what);

}  // namespace stiffid::data
