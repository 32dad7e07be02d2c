#include "validation/anova_table.hpp"

#include <map>
#include <set>
#include <sstream>

#include "data/error.hpp"

namespace stiffid::validation {

int LongTable::factor(const std::string& name, const std::string& flag) const {
  for (size_t i = 0; i < factor_names.size(); ++i) {
    if (factor_names[i] == name) return static_cast<int>(i);
  }
  std::ostringstream msg;
  msg << source << ": " << flag << ": no factor column '" << name << "' (factors:";
  for (const auto& f : factor_names) msg << ' ' << f;
  msg << ')';
  throw InputError(msg.str());
}

std::string LongTable::where(int row) const {
  if (row >= 0 && row < static_cast<int>(line_numbers.size()) && line_numbers[row] > 0) {
    return source + ":" + std::to_string(line_numbers[row]);
  }
  return source;
}

LongTable long_table_from_csv(const data::CsvTable& csv, const std::string& dv,
                              const std::vector<std::string>& factors) {
  LongTable table;
  table.source = csv.source;
  table.value_name = dv;
  table.factor_names = factors;
  std::set<std::string> seen{dv};
  for (const auto& f : factors) {
    if (!seen.insert(f).second) {
      throw InputError(csv.source + ": column '" + f +
                       "' is named twice among the dependent variable and the factors; each "
                       "column may play one role");
    }
  }
  const int dv_col = csv.column(dv);
  std::vector<int> cols;
  for (const auto& f : factors) cols.push_back(csv.column(f));
  const int rows = csv.row_count();
  if (rows == 0) throw InputError(csv.source + ": no data rows after the header");
  table.values.resize(rows);
  table.labels.resize(rows);
  table.line_numbers = csv.line_numbers;
  for (int r = 0; r < rows; ++r) {
    table.values[r] = csv.number(r, dv_col);
    table.labels[r].reserve(cols.size());
    for (const int c : cols) {
      if (csv.cells[r][c].empty()) {
        throw InputError(csv.where(r, c) + ": column '" + csv.header[c] +
                         "': empty factor label, expected a level name");
      }
      table.labels[r].push_back(csv.cells[r][c]);
    }
  }
  return table;
}

FactorCoding code_factor(const LongTable& table, const std::string& name, const std::string& flag,
                         int min_levels) {
  const int f = table.factor(name, flag);
  FactorCoding coding;
  coding.name = name;
  coding.codes.resize(table.row_count());
  std::map<std::string, int> index;
  for (int r = 0; r < table.row_count(); ++r) {
    const std::string& label = table.labels[r][f];
    const auto [it, inserted] = index.emplace(label, coding.level_count());
    if (inserted) coding.levels.push_back(label);
    coding.codes[r] = it->second;
  }
  if (coding.level_count() < min_levels) {
    std::ostringstream msg;
    msg << table.source << ": " << flag << " factor '" << name << "' has " << coding.level_count()
        << " level" << (coding.level_count() == 1 ? "" : "s");
    if (coding.level_count() == 1) msg << " ('" << coding.levels[0] << "')";
    msg << "; an effect needs at least " << min_levels << " levels to compare";
    throw InputError(msg.str());
  }
  return coding;
}

}  // namespace stiffid::validation
