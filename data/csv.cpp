#include "data/csv.hpp"

#include <fast_float/fast_float.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <string_view>

#include "data/error.hpp"
#include "data/output.hpp"
#include "data/parallel.hpp"
#include "data/text_input.hpp"

namespace stiffid::data {
namespace {

// `s` without leading and trailing blanks (space, tab, carriage return).
std::string_view trim_view(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

std::string trim(const std::string& s) { return std::string(trim_view(s)); }

// Splits one CSV line into trimmed cells; double-quoted cells may hold commas and "" for a quote.
std::vector<std::string> split_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cell += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cell += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.push_back(trim(cell));
      cell.clear();
    } else {
      cell += c;
    }
  }
  out.push_back(trim(cell));
  return out;
}

// A blank line or a comment (first non-blank character '#').
bool skipped(std::string_view line) {
  const std::string_view t = trim_view(line);
  return t.empty() || t[0] == '#';
}

// Splits a header cell "name[unit]" or "name (unit)" into name and unit.
std::pair<std::string, std::string> name_and_unit(const std::string& header) {
  for (const auto& [open, close] : {std::pair{'[', ']'}, std::pair{'(', ')'}}) {
    const auto a = header.find(open);
    if (a != std::string::npos && !header.empty() && header.back() == close) {
      return {trim(header.substr(0, a)), trim(header.substr(a + 1, header.size() - a - 2))};
    }
  }
  return {header, ""};
}

// Length of a UTF-8 byte-order mark at the start of `text` (spreadsheets write one): 3 or 0.
std::size_t bom_length(std::string_view text) {
  return text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
}

void check_header(const std::vector<std::string>& cells, const std::string& source, int line) {
  if (cells.size() == 1) {
    for (const char separator : {';', '\t'}) {
      if (cells[0].find(separator) == std::string::npos) continue;
      throw InputError(source + ":" + std::to_string(line) + ": the header is one column, '" +
                       cells[0] + "': cells must be separated by ',' (this file uses " +
                       (separator == ';' ? "';'" : "tabs") + ")");
    }
  }
  std::set<std::string> seen;
  for (size_t c = 0; c < cells.size(); ++c) {
    const std::string name = name_and_unit(cells[c]).first;
    const std::string at = source + ":" + std::to_string(line) + ":" + std::to_string(c + 1);
    if (name.empty()) throw InputError(at + ": empty column name in the header");
    if (!seen.insert(name).second) throw InputError(at + ": duplicate column '" + name + "'");
  }
}

InputError ragged(const std::string& source, int line, size_t cells, size_t columns) {
  return InputError(source + ":" + std::to_string(line) + ": ragged row: " + std::to_string(cells) +
                    " cells, expected " + std::to_string(columns) + " as in the header");
}

// The number at p (text up to `end`) into out: the character after it, or nullptr when none
// starts there. A leading '+' is accepted, as by strtod. The fast path and the checked path of the
// trial reader both read their numbers here.
const char* read_number(const char* p, const char* end, double& out) {
  if (end - p > 1 && *p == '+' && p[1] != '-') ++p;
  const auto [ptr, ec] = fast_float::from_chars(p, end, out);
  return ec == std::errc() ? ptr : nullptr;
}

// A cell as a finite double, or an InputError naming file:line:column, the column and the text.
double parse_number(std::string_view text, const std::string& source, int line, int col,
                    const std::string& column) {
  double value = 0.0;
  const char* end = text.data() + text.size();
  const char* ptr = read_number(text.data(), end, value);
  if (ptr == end && !text.empty() && std::isfinite(value)) return value;
  // The location is spelled out only on failure: this runs for every cell of a long trial.
  const std::string where = source + ":" + std::to_string(line) + ":" + std::to_string(col + 1);
  if (text.empty() || ptr != end) {
    throw InputError(where + ": column '" + column + "': expected a number, got '" +
                     std::string(text) + "'");
  }
  throw InputError(where + ": column '" + column + "': expected a finite number, got '" +
                   std::string(text) + "'");
}

}  // namespace

int CsvTable::find(const std::string& name) const {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name || name_and_unit(header[i]).first == name) return static_cast<int>(i);
  }
  return -1;
}

int CsvTable::column(const std::string& name) const {
  const int i = find(name);
  if (i < 0) {
    std::ostringstream msg;
    msg << source << ":1: no column '" << name << "' (columns:";
    for (const auto& h : header) msg << ' ' << h;
    msg << ')';
    throw InputError(msg.str());
  }
  return i;
}

std::string CsvTable::where(int row, int col) const {
  return source + ":" + std::to_string(line_numbers[row]) + ":" + std::to_string(col + 1);
}

double CsvTable::number(int row, int col) const {
  return parse_number(cells[row][col], source, line_numbers[row], col, header[col]);
}

CsvTable parse_csv(const std::string& text, const std::string& source) {
  CsvTable table;
  table.source = source;
  std::istringstream in(text.substr(bom_length(text)));
  std::string line;
  int line_number = 0;
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_number;
    if (skipped(line)) continue;
    std::vector<std::string> cells = split_line(line);
    if (!have_header) {
      check_header(cells, source, line_number);
      table.header = std::move(cells);
      have_header = true;
      continue;
    }
    if (cells.size() != table.header.size()) {
      throw ragged(source, line_number, cells.size(), table.header.size());
    }
    table.cells.push_back(std::move(cells));
    table.line_numbers.push_back(line_number);
  }
  if (!have_header) throw InputError(source + ": empty file, expected a header row");
  return table;
}

CsvTable read_csv(const std::string& path) { return parse_csv(read_text_file(path), path); }

namespace {

// Shortest text that reads back as `v` (what the user most likely wrote).
std::string shortest(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, result.ptr);
}

// A trial file's numbers: the header cells, the index of the time column (-1: none), the other
// columns in file order as channels (rows x channels, column-major: a trial's layout), the time
// column, and the 1-based line of each row, for messages.
struct NumericCsv {
  std::vector<std::string> header;
  int time_col = -1;
  Eigen::MatrixXd channels;
  Eigen::VectorXd time;
  std::vector<int> lines;
  int rows() const { return static_cast<int>(lines.size()); }
};

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// The line starting at p (the text runs to `end`) when it is a row of exactly `columns` plain
// numbers (optional blanks around each, no quotes) ending at a newline or at `end`: parsed in place
// into out[0..columns), returning the start of the next line (or `end`). nullptr for anything else
// (a blank or comment line, quotes, a ragged or non-numeric row): the caller then cuts the line
// out and takes the checked path, which names what is wrong. The row's end is found by the parse
// itself, so a plain trial is read in one pass.
const char* parse_plain_line(const char* p, const char* const end, std::size_t columns,
                             double* out) {
  for (std::size_t c = 0; c < columns; ++c) {
    while (p < end && is_blank(*p)) ++p;
    p = read_number(p, end, out[c]);
    if (p == nullptr || !std::isfinite(out[c])) return nullptr;
    while (p < end && is_blank(*p)) ++p;
    if (c + 1 < columns) {
      if (p == end || *p != ',') return nullptr;
      ++p;
    }
  }
  if (p == end) return end;
  return *p == '\n' ? p + 1 : nullptr;
}

// The checked path for one data row: every cell as a finite double into out[0..columns), or an
// InputError naming source:line:column (ragged row, non-numeric or non-finite cell).
void parse_checked_row(std::string_view row, const std::vector<std::string>& header,
                       const std::string& source, int line, double* out) {
  const std::size_t columns = header.size();
  const std::vector<std::string> split = split_line(std::string(row));
  if (split.size() != columns) throw ragged(source, line, split.size(), columns);
  for (std::size_t c = 0; c < columns; ++c) {
    out[c] = parse_number(split[c], source, line, static_cast<int>(c), header[c]);
  }
}

// A run of whole lines text[begin, end) parsed by one thread: its number of lines (counted first,
// an upper bound on its data rows), the 1-based line and the row index at which it starts, and the
// data rows it held (blank and comment lines are not rows).
struct Chunk {
  std::size_t begin = 0;
  std::size_t end = 0;
  int lines = 0;
  int first_line = 0;
  int first_row = 0;
  int rows = 0;
};

// A line that is a data row: not blank, not a comment. Most rows start with a digit or a sign,
// which settles it without trimming.
bool data_row(std::string_view row) {
  if (!row.empty() && !is_blank(row[0])) return row[0] != '#';
  return !skipped(row);
}

// Counted with memchr, not std::count: glibc's vectorized memchr scans a 40 MB trial about 3x
// faster than the byte loop std::count compiles to.
void count_lines(std::string_view text, Chunk& chunk) {
  const char* p = text.data() + chunk.begin;
  const char* const last = text.data() + chunk.end;
  int lines = 0;
  while (p < last) {
    const void* eol = std::memchr(p, '\n', static_cast<std::size_t>(last - p));
    if (eol == nullptr) break;
    ++lines;
    p = static_cast<const char*>(eol) + 1;
  }
  if (chunk.end > chunk.begin && text[chunk.end - 1] != '\n') ++lines;  // unterminated
  chunk.lines = lines;
}

// Parses the data rows of a chunk into the destination columns: file column c of row r goes to
// columns[c][r], its line to lines[r].
void parse_rows(std::string_view text, Chunk& chunk, const std::vector<std::string>& header,
                const std::string& source, const std::vector<double*>& columns, int* lines) {
  const std::size_t count = header.size();
  std::vector<double> cells(count);
  int line = chunk.first_line - 1;
  int row_index = chunk.first_row;  // rows go to first_row, first_row + 1, ...
  const char* p = text.data() + chunk.begin;
  const char* const end = text.data() + chunk.end;
  while (p < end) {
    ++line;
    const char* next = parse_plain_line(p, end, count, cells.data());
    if (next == nullptr) {  // not a plain row: cut the line out, skip it or check it
      const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
      if (eol == nullptr) eol = end;
      const std::string_view row(p, static_cast<std::size_t>(eol - p));
      next = eol < end ? eol + 1 : end;
      if (!data_row(row)) {
        p = next;
        continue;
      }
      parse_checked_row(row, header, source, line, cells.data());
    }
    p = next;
    for (std::size_t c = 0; c < count; ++c) columns[c][row_index] = cells[c];
    lines[row_index++] = line;
  }
  chunk.rows = row_index - chunk.first_row;
}

// Below this many bytes of rows a trial is parsed on the calling thread alone.
constexpr std::size_t kParallelParseBytes = 1 << 20;
constexpr std::size_t kChunksPerThread = 4;

// Reads the header, then the data rows in up to kChunksPerThread x max_threads() chunks of whole
// lines, in parallel, in two passes: count each chunk's lines, then parse every row straight into
// its place in the trial's columns. The values do not depend on the thread count;
// when several chunks are bad, the error reported is the first in the file, as a single-threaded
// parse would report it.
NumericCsv parse_numeric(std::string_view text, const std::string& source,
                         const std::string& time_column) {
  NumericCsv out;
  std::size_t pos = bom_length(text);
  int line = 0;
  while (pos < text.size() && out.header.empty()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view row = text.substr(pos, eol - pos);
    pos = std::min(eol + 1, text.size());
    ++line;
    if (skipped(row)) continue;
    out.header = split_line(std::string(row));
    check_header(out.header, source, line);
  }
  if (out.header.empty()) throw InputError(source + ": empty file, expected a header row");
  const int columns = static_cast<int>(out.header.size());
  for (int c = 0; c < columns; ++c) {
    if (name_and_unit(out.header[c]).first == time_column) out.time_col = c;
  }

  const std::size_t bytes = text.size() - pos;
  // Chunks: up to kChunksPerThread per thread, so that a thread slowed down by other work on the
  // machine leaves its remaining chunks to the others (their boundaries do not change the values
  // parsed).
  const auto threads = static_cast<std::size_t>(std::max(1, max_threads()));
  const std::size_t wanted =
      bytes < kParallelParseBytes
          ? 1
          : std::min(threads * kChunksPerThread, bytes / (kParallelParseBytes / 2));
  std::vector<Chunk> chunks(1);
  chunks[0].begin = pos;
  for (std::size_t k = 1; k < wanted; ++k) {
    const std::size_t from = std::max(pos + bytes * k / wanted, chunks.back().begin);
    const std::size_t eol = text.find('\n', from);
    if (eol == std::string_view::npos) break;
    chunks.back().end = eol + 1;
    chunks.emplace_back().begin = eol + 1;
  }
  chunks.back().end = text.size();
  // Each chunk gets room for as many rows as it has lines; blank and comment lines leave gaps,
  // closed afterwards (rare: a plain trial has none, and then nothing is moved).
  parallel_for_index(chunks.size(), [&](std::size_t k) { count_lines(text, chunks[k]); });
  int capacity = 0;
  chunks[0].first_line = line + 1;
  for (std::size_t k = 0; k < chunks.size(); ++k) {
    if (k > 0) chunks[k].first_line = chunks[k - 1].first_line + chunks[k - 1].lines;
    chunks[k].first_row = capacity;
    capacity += chunks[k].lines;
  }
  const int channels = columns - (out.time_col >= 0 ? 1 : 0);
  out.channels.resize(capacity, channels);
  out.time.resize(out.time_col >= 0 ? capacity : 0);
  out.lines.resize(capacity);
  std::vector<double*> destination;
  for (int c = 0, k = 0; c < columns; ++c) {
    destination.push_back(c == out.time_col ? out.time.data() : out.channels.col(k++).data());
  }
  parallel_for_index(chunks.size(), [&](std::size_t k) {
    parse_rows(text, chunks[k], out.header, source, destination, out.lines.data());
  });
  int rows = 0;
  for (const Chunk& chunk : chunks) rows += chunk.rows;
  if (rows < capacity) {
    NumericCsv packed;
    packed.header = std::move(out.header);
    packed.time_col = out.time_col;
    packed.channels.resize(rows, channels);
    packed.time.resize(out.time_col >= 0 ? rows : 0);
    packed.lines.resize(rows);
    int to = 0;
    for (const Chunk& chunk : chunks) {
      const int from = chunk.first_row;
      packed.channels.middleRows(to, chunk.rows) = out.channels.middleRows(from, chunk.rows);
      if (out.time_col >= 0) {
        packed.time.segment(to, chunk.rows) = out.time.segment(from, chunk.rows);
      }
      std::copy_n(out.lines.begin() + from, chunk.rows, packed.lines.begin() + to);
      to += chunk.rows;
    }
    return packed;
  }
  return out;
}

std::string at(const std::string& source, int line, int col) {
  return source + ":" + std::to_string(line) + ":" + std::to_string(col + 1);
}

// The message for a time column off its uniform grid (row `off` is the first row further than
// `tolerance` steps from the line through the first and last times): where one interval differs
// from the typical (median) one by more than the tolerance, that interval (missing or repeated
// rows), else row `off` (a clock that drifts).
std::string non_uniform(const Eigen::VectorXd& time, const std::vector<int>& lines,
                        const std::string& source, int time_col, double tolerance, int off) {
  const Eigen::Index rows = time.size();
  std::vector<double> intervals(static_cast<std::size_t>(rows - 1));
  for (Eigen::Index r = 1; r < rows; ++r) intervals[r - 1] = time(r) - time(r - 1);
  std::vector<double> sorted = intervals;
  const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), middle, sorted.end());
  const double typical = *middle;
  std::ostringstream msg;
  msg << "non-uniform sampling: ";
  for (Eigen::Index r = 1; r < rows; ++r) {
    if (std::abs(intervals[r - 1] - typical) > tolerance * typical) {
      msg << "t goes from " << shortest(time(r - 1)) << " to " << shortest(time(r)) << " s, "
          << intervals[r - 1] / typical << " times the typical step of " << typical
          << " s (missing or repeated rows?; tolerance " << tolerance << " step)";
      return at(source, lines[r], time_col) + ": " + msg.str();
    }
  }
  const double step = (time(rows - 1) - time(0)) / double(rows - 1);
  msg << "t = " << shortest(time(off)) << " s is "
      << std::abs(time(off) - (time(0) + off * step)) / step
      << " steps off the uniform grid of step " << step << " s (tolerance " << tolerance
      << " step)";
  return at(source, lines[off], time_col) + ": " + msg.str();
}

Trial build_trial(NumericCsv&& csv, const std::string& source, const TrialCsvOptions& options) {
  const int columns = static_cast<int>(csv.header.size());
  const int rows = csv.rows();
  const int time_col = csv.time_col;
  if (time_col < 0 && options.sample_rate_hz <= 0.0) {
    throw InputError(source + ":1: no time column '" + options.time_column +
                     "'; give the sampling rate (--fs HZ)");
  }
  if (rows < 2)
    throw InputError(source + ": " + std::to_string(rows) + " data rows, need at least 2");

  Trial trial;
  trial.source = source;
  for (int c = 0; c < columns; ++c) {
    if (c == time_col) continue;
    const auto [name, unit] = name_and_unit(csv.header[c]);
    trial.names.push_back(name);
    trial.units.push_back(unit);
  }
  trial.samples = std::move(csv.channels);
  const Eigen::VectorXd& time = csv.time;
  const std::vector<int>& lines = csv.lines;
  if (time_col < 0) {
    trial.sample_rate_hz = options.sample_rate_hz;
    return trial;
  }

  for (int r = 1; r < rows; ++r) {
    if (!(time(r) > time(r - 1))) {
      throw InputError(at(source, lines[r], time_col) + ": time must increase, got " +
                       shortest(time(r)) + " after " + shortest(time(r - 1)));
    }
  }
  const double step = (time(rows - 1) - time(0)) / (rows - 1);
  for (int r = 0; r < rows; ++r) {
    const double deviation = std::abs(time(r) - (time(0) + r * step));
    if (deviation > options.time_tolerance * step) {
      throw InputError(non_uniform(time, lines, source, time_col, options.time_tolerance, r));
    }
  }
  trial.sample_rate_hz = 1.0 / step;
  trial.start_time_s = time(0);
  if (options.sample_rate_hz > 0.0 &&
      std::abs(trial.sample_rate_hz - options.sample_rate_hz) > 1e-6 * options.sample_rate_hz) {
    std::ostringstream msg;
    msg << source << ": --fs " << options.sample_rate_hz << " Hz disagrees with the time column ("
        << trial.sample_rate_hz << " Hz)";
    throw InputError(msg.str());
  }
  return trial;
}

}  // namespace

Trial parse_trial_csv(std::string_view text, const std::string& source,
                      const TrialCsvOptions& options) {
  return build_trial(parse_numeric(text, source, options.time_column), source, options);
}

Trial read_trial_csv(const std::string& path, const TrialCsvOptions& options) {
  const MappedText text(path);
  return parse_trial_csv(text.view(), path, options);
}

std::string trial_to_csv(const Trial& trial, bool with_units) {
  std::ostringstream out;
  out << "t";
  for (int c = 0; c < trial.channel_count(); ++c) {
    out << ',' << trial.names[c];
    if (with_units && !trial.units[c].empty()) out << '[' << trial.units[c] << ']';
  }
  out << '\n' << std::setprecision(17);
  for (int r = 0; r < trial.sample_count(); ++r) {
    out << trial.start_time_s + r / trial.sample_rate_hz;
    for (int c = 0; c < trial.channel_count(); ++c) out << ',' << trial.samples(r, c);
    out << '\n';
  }
  return out.str();
}

void write_trial_csv(const std::string& path, const Trial& trial, bool with_units) {
  write_file_atomically(path, trial_to_csv(trial, with_units));
}

std::vector<std::string> split_list(const std::string& text, const std::string& what) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    item = trim(item);
    if (item.empty()) throw InputError(what + ": empty name in '" + text + "'");
    out.push_back(item);
  }
  if (out.empty()) throw InputError(what + ": expected a comma-separated list of names");
  return out;
}

}  // namespace stiffid::data
