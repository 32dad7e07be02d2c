#pragma once
// Long-format input of the ANOVA engine: one row per observation, factor columns holding text
// labels and one numeric dependent variable (the layout of R's afex::aov_ez and of SPSS "long"
// files).

#include <string>
#include <vector>

#include "data/csv.hpp"

namespace stiffid::validation {

/// A long-format data set. Row r has the label `labels[r][f]` for factor f and the value
/// `values[r]` of the dependent variable. Filled from a CSV file by long_table_from_csv or in
/// memory by a caller.
struct LongTable {
  std::string source;                            ///< file path or label, for messages
  std::string value_name = "value";              ///< name of the dependent variable
  std::vector<std::string> factor_names;         ///< [F] names of the factor columns
  std::vector<std::vector<std::string>> labels;  ///< [R][F] level label of every factor per row
  std::vector<double> values;                    ///< [R] dependent variable
  std::vector<int> line_numbers;                 ///< [R] 1-based source line per row (empty or 0:
                                                 ///< unknown)

  int row_count() const { return static_cast<int>(values.size()); }
  /// Index of a factor column; throws InputError naming `flag` and the factors the table has.
  int factor(const std::string& name, const std::string& flag) const;
  /// "source:line" of a row (just "source" when the line is unknown), for messages.
  std::string where(int row) const;
};

/// Picks the dependent variable `dv` (every cell a finite number, else InputError with
/// file:line:column) and the factor columns `factors` (text labels, none empty) from a CSV table.
/// Columns may not repeat: the same name twice among dv and factors is an InputError.
LongTable long_table_from_csv(const data::CsvTable& csv, const std::string& dv,
                              const std::vector<std::string>& factors);

/// A factor coded as level indices: levels in order of first appearance in the table.
struct FactorCoding {
  std::string name;                 ///< column name
  std::vector<std::string> levels;  ///< [L] labels in order of first appearance
  std::vector<int> codes;           ///< [R] level index of every row
  int level_count() const { return static_cast<int>(levels.size()); }
};

/// Codes factor column `name` of the table. `flag` names the command-line option (or option
/// field) that asked for it, for messages. A factor with fewer than `min_levels` levels is an
/// InputError naming the flag and the single level found.
FactorCoding code_factor(const LongTable& table, const std::string& name, const std::string& flag,
                         int min_levels = 2);

}  // namespace stiffid::validation
