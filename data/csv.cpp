#include "data/csv.hpp"

#include <algorithm>
#include <charconv>
#include <string_view>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "data/error.hpp"
#include "data/text_input.hpp"
#include "data/output.hpp"

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

void check_header(const std::vector<std::string>& cells, const std::string& source, int line) {
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

// A cell as a finite double, or an InputError naming file:line:column, the column and the text.
double parse_number(std::string_view text, const std::string& source, int line, int col,
                    const std::string& column) {
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (!text.empty() && ec == std::errc() && ptr == end && std::isfinite(value)) return value;
  // The location is spelled out only on failure: this runs for every cell of a long trial.
  const std::string where = source + ":" + std::to_string(line) + ":" + std::to_string(col + 1);
  if (text.empty() || ec != std::errc() || ptr != end) {
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
  std::istringstream in(text);
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

// A trial file's numbers: header cells, values row-major (rows x header.size()), and the 1-based
// line of each row, for messages.
struct NumericCsv {
  std::vector<std::string> header;
  std::vector<double> values;
  std::vector<int> lines;
};

// Streams the text once, converting cells to doubles as they are met (no per-cell strings: a
// 10-minute, 1 kHz trial has millions of cells). Quoted cells take the general splitter.
NumericCsv parse_numeric(const std::string& text, const std::string& source) {
  NumericCsv out;
  size_t pos = 0;
  int line = 0;
  while (pos < text.size()) {
    size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    const std::string_view row(text.data() + pos, eol - pos);
    pos = eol + 1;
    ++line;
    if (skipped(row)) continue;
    if (out.header.empty()) {
      out.header = split_line(std::string(row));
      check_header(out.header, source, line);
      // At most one row per remaining line: reserve once instead of regrowing a large buffer.
      const size_t lines_left = 1 + std::count(text.begin() + std::min(pos, text.size()), text.end(), '\n');
      out.values.reserve(lines_left * out.header.size());
      continue;
    }
    const size_t columns = out.header.size();
    const size_t cells = 1 + std::count(row.begin(), row.end(), ',');
    const bool quoted = row.find('"') != std::string_view::npos;
    if (!quoted && cells != columns) throw ragged(source, line, cells, columns);
    std::vector<std::string> split;
    if (quoted) {
      split = split_line(std::string(row));
      if (split.size() != columns) throw ragged(source, line, split.size(), columns);
    }
    size_t start = 0;
    for (size_t c = 0; c < columns; ++c) {
      std::string_view cell;
      if (quoted) {
        cell = split[c];
      } else {
        const size_t comma = std::min(row.find(',', start), row.size());
        cell = trim_view(row.substr(start, comma - start));
        start = comma + 1;
      }
      out.values.push_back(parse_number(cell, source, line, static_cast<int>(c), out.header[c]));
    }
    out.lines.push_back(line);
  }
  if (out.header.empty()) throw InputError(source + ": empty file, expected a header row");
  return out;
}

std::string at(const std::string& source, int line, int col) {
  return source + ":" + std::to_string(line) + ":" + std::to_string(col + 1);
}

Trial build_trial(const NumericCsv& csv, const std::string& source, const TrialCsvOptions& options) {
  const int columns = static_cast<int>(csv.header.size());
  const int rows = static_cast<int>(csv.lines.size());
  int time_col = -1;
  for (int c = 0; c < columns; ++c) {
    if (name_and_unit(csv.header[c]).first == options.time_column) time_col = c;
  }
  if (time_col < 0 && options.sample_rate_hz <= 0.0) {
    throw InputError(source + ":1: no time column '" + options.time_column +
                     "'; give the sampling rate (--fs HZ)");
  }
  if (rows < 2) throw InputError(source + ": " + std::to_string(rows) + " data rows, need at least 2");

  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      all(csv.values.data(), rows, columns);
  Trial trial;
  trial.source = source;
  trial.samples.resize(rows, columns - (time_col >= 0 ? 1 : 0));
  for (int c = 0, k = 0; c < columns; ++c) {
    if (c == time_col) continue;
    const auto [name, unit] = name_and_unit(csv.header[c]);
    trial.names.push_back(name);
    trial.units.push_back(unit);
    trial.samples.col(k++) = all.col(c);
  }
  if (time_col < 0) {
    trial.sample_rate_hz = options.sample_rate_hz;
    return trial;
  }

  const Eigen::VectorXd time = all.col(time_col);
  for (int r = 1; r < rows; ++r) {
    if (!(time(r) > time(r - 1))) {
      throw InputError(at(source, csv.lines[r], time_col) + ": time must increase, got " +
                       shortest(time(r)) + " after " + shortest(time(r - 1)));
    }
  }
  const double step = (time(rows - 1) - time(0)) / (rows - 1);
  for (int r = 0; r < rows; ++r) {
    const double deviation = std::abs(time(r) - (time(0) + r * step));
    if (deviation > options.time_tolerance * step) {
      std::ostringstream msg;
      msg << at(source, csv.lines[r], time_col) << ": non-uniform sampling: t = "
          << shortest(time(r)) << " s is " << deviation / step
          << " steps off the uniform grid of step " << step << " s (tolerance "
          << options.time_tolerance << " step)";
      throw InputError(msg.str());
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

Trial parse_trial_csv(const std::string& text, const std::string& source,
                      const TrialCsvOptions& options) {
  return build_trial(parse_numeric(text, source), source, options);
}

Trial read_trial_csv(const std::string& path, const TrialCsvOptions& options) {
  return parse_trial_csv(read_text_file(path), path, options);
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
