#pragma once
// A study file: a declarative factorial design. Its JSON layout (see docs/studies.md):
//
//   {
//     "name": "coupling_demo",             study name, [A-Za-z0-9_.-]+
//     "seed": 42,                          study seed, unsigned 64-bit integer
//     "replicates": 10,                    seed replicates per combination of levels, >= 1
//     "report": "summary",                 optional: reporter used by --report (default summary)
//     "designs": [ {                       one or more designs, run in this order
//       "name": "table1",                  design name, unique, [A-Za-z0-9_.-]+
//       "evaluator": "perreault1999.linear",   cell evaluator (see study.hpp)
//       "factors": {"coupling_percent": [0, 25, 50, 75], "snr_db": [20]},
//       "template": {"coupling_percent": "${coupling_percent}", ...},
//       "metrics": ["r2_percent", "irf_vaf_h11_percent"]   optional: metrics to keep (default all)
//     } ]
//   }
//
// Placeholders: a template string that is exactly "${f}" becomes the level of factor f with its
// JSON type (number, string, array, object); "${f}" inside a longer string is replaced by the
// level's text. "${replicate}" is the replicate index. Any other placeholder is an InputError.
//
// Cells: for each design in order, the Cartesian product of its factors' levels (the first factor
// varies slowest), then the replicates (fastest). Cell indices run over all designs from 0.
//
// Seeds (stable across versions, platforms, thread counts and cell order): the cell's identity is
// the canonical JSON text (keys sorted, no spaces, as nlohmann::json::dump() writes it) of
//   {"design": NAME, "levels": {FACTOR: LEVEL, ...}, "replicate": R}
// hashed with 64-bit FNV-1a; seed = splitmix64(splitmix64(study_seed) XOR hash). Levels hash as
// written: 25 and 25.0 are different levels.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace stiffid::validation {

/// One factor of a design and its levels (as written in the study file).
struct Factor {
  std::string name;
  std::vector<nlohmann::json> levels;  ///< [L] at least one
};

struct Design {
  std::string name;
  std::string evaluator;             ///< name of a cell evaluator in the registry
  std::vector<Factor> factors;       ///< in file order; may be empty (one combination)
  nlohmann::json trial_template;     ///< the "template" with ${...} placeholders
  std::vector<std::string> metrics;  ///< metrics to keep; empty = every metric the evaluator makes
};

struct StudySpec {
  std::string name;
  std::uint64_t seed = 0;
  int replicates = 1;
  std::string report = "summary";
  std::vector<Design> designs;
  std::string source;  ///< file path or built-in name, for messages

  /// Canonical JSON of the effective spec (what the spec hash is computed from).
  nlohmann::json to_json() const;
  /// 16 hex digits: FNV-1a 64 of to_json().dump().
  std::string hash() const;
  /// Factor names of all designs in order of first appearance (columns of the tidy CSV).
  std::vector<std::string> factor_names() const;
};

/// One cell of a study: a design, one level per factor, one replicate.
struct Cell {
  int index = 0;           ///< global cell index, from 0
  int design = 0;          ///< index into StudySpec::designs
  nlohmann::json levels;   ///< {factor: level} (object, keys sorted)
  int replicate = 0;       ///< 0 .. replicates-1
  std::uint64_t seed = 0;  ///< cell_seed(...)
};

/// Parses a study file's text; `source` names it in messages (InputError with line:column for a
/// syntax error, the key path for a wrong or unknown key).
StudySpec parse_study_spec(const std::string& text, const std::string& source);
/// Reads and parses a study file.
StudySpec read_study_spec(const std::string& path);

/// Every cell of the study, in cell-index order.
std::vector<Cell> enumerate_cells(const StudySpec& spec);
/// Stable seed of a cell, as documented above.
std::uint64_t cell_seed(std::uint64_t study_seed, const std::string& design,
                        const nlohmann::json& levels, int replicate);
/// The design's template with its placeholders filled from the cell's levels.
nlohmann::json fill_template(const Design& design, const Cell& cell);

/// SplitMix64 finalizer (Steele, Lea & Flood 2014): a bijective mix of 64 bits.
std::uint64_t splitmix64(std::uint64_t x);
/// 64-bit FNV-1a hash of bytes.
std::uint64_t fnv1a64(const std::string& bytes);
/// 16 lowercase hex digits.
std::string hex64(std::uint64_t value);

}  // namespace stiffid::validation
