#include "data/csv.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "data/error.hpp"
#include "data/output.hpp"

namespace stiffid::data {
namespace {

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

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

bool skipped(const std::string& line) {
  const std::string t = trim(line);
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
  const std::string& text = cells[row][col];
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end) {
    throw InputError(where(row, col) + ": column '" + header[col] + "': expected a number, got '" +
                     text + "'");
  }
  if (!std::isfinite(value)) {
    throw InputError(where(row, col) + ": column '" + header[col] +
                     "': expected a finite number, got '" + text + "'");
  }
  return value;
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
      std::set<std::string> seen;
      for (size_t c = 0; c < cells.size(); ++c) {
        const std::string name = name_and_unit(cells[c]).first;
        const std::string at = source + ":" + std::to_string(line_number) + ":" + std::to_string(c + 1);
        if (name.empty()) throw InputError(at + ": empty column name in the header");
        if (!seen.insert(name).second) throw InputError(at + ": duplicate column '" + name + "'");
      }
      table.header = std::move(cells);
      have_header = true;
      continue;
    }
    if (cells.size() != table.header.size()) {
      throw InputError(source + ":" + std::to_string(line_number) + ": ragged row: " +
                       std::to_string(cells.size()) + " cells, expected " +
                       std::to_string(table.header.size()) + " as in the header");
    }
    table.cells.push_back(std::move(cells));
    table.line_numbers.push_back(line_number);
  }
  if (!have_header) throw InputError(source + ": empty file, expected a header row");
  return table;
}

CsvTable read_csv(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open (missing file or no permission)");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_csv(text.str(), path);
}

Trial trial_from_csv(const CsvTable& table, const TrialCsvOptions& options) {
  Trial trial;
  trial.source = table.source;
  const int time_col = table.find(options.time_column);
  const int rows = table.row_count();
  if (time_col < 0 && options.sample_rate_hz <= 0.0) {
    throw InputError(table.source + ":1: no time column '" + options.time_column +
                     "'; give the sampling rate (--fs HZ)");
  }
  if (rows < 2) throw InputError(table.source + ": " + std::to_string(rows) + " data rows, need at least 2");

  trial.samples.resize(rows, table.column_count() - (time_col >= 0 ? 1 : 0));
  for (int c = 0; c < table.column_count(); ++c) {
    if (c == time_col) continue;
    const auto [name, unit] = name_and_unit(table.header[c]);
    trial.names.push_back(name);
    trial.units.push_back(unit);
  }
  Eigen::VectorXd time(rows);
  for (int r = 0; r < rows; ++r) {
    int k = 0;
    for (int c = 0; c < table.column_count(); ++c) {
      const double v = table.number(r, c);
      if (c == time_col) {
        time(r) = v;
      } else {
        trial.samples(r, k++) = v;
      }
    }
  }

  if (time_col < 0) {
    trial.sample_rate_hz = options.sample_rate_hz;
    return trial;
  }
  for (int r = 1; r < rows; ++r) {
    if (!(time(r) > time(r - 1))) {
      throw InputError(table.where(r, time_col) + ": time must increase, got " +
                       table.cells[r][time_col] + " after " + table.cells[r - 1][time_col]);
    }
  }
  const double step = (time(rows - 1) - time(0)) / (rows - 1);
  for (int r = 0; r < rows; ++r) {
    const double deviation = std::abs(time(r) - (time(0) + r * step));
    if (deviation > options.time_tolerance * step) {
      std::ostringstream msg;
      msg << table.where(r, time_col) << ": non-uniform sampling: t = " << table.cells[r][time_col]
          << " s is " << deviation / step << " steps off the uniform grid of step " << step
          << " s (tolerance " << options.time_tolerance << " step)";
      throw InputError(msg.str());
    }
  }
  trial.sample_rate_hz = 1.0 / step;
  trial.start_time_s = time(0);
  if (options.sample_rate_hz > 0.0 &&
      std::abs(trial.sample_rate_hz - options.sample_rate_hz) > 1e-6 * options.sample_rate_hz) {
    std::ostringstream msg;
    msg << table.source << ": --fs " << options.sample_rate_hz << " Hz disagrees with the time column ("
        << trial.sample_rate_hz << " Hz)";
    throw InputError(msg.str());
  }
  return trial;
}

Trial read_trial_csv(const std::string& path, const TrialCsvOptions& options) {
  return trial_from_csv(read_csv(path), options);
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
