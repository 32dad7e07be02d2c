#pragma once
// Reading whole text files and JSON with errors that name the file, line and column. One place
// for every reader of the project (trial CSVs, trial and study specs, bounds, FRF and subject
// files).

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "data/error.hpp"

namespace stiffid::data {

/// The whole file in one allocation. Throws InputError "PATH: cannot open (missing file or no
/// permission)" or "PATH: read failed".
std::string read_text_file(const std::string& path);

/// A whole file's bytes, memory-mapped read-only when it is a regular file (no copy: a 40 MB trial
/// is read ~3x faster than into a string), read into memory otherwise (pipes, devices). Throws
/// the same InputErrors as read_text_file.
class MappedText {
 public:
  explicit MappedText(const std::string& path);
  ~MappedText();
  MappedText(const MappedText&) = delete;
  MappedText& operator=(const MappedText&) = delete;
  std::string_view view() const { return view_; }

 private:
  void* map_ = nullptr;
  std::size_t size_ = 0;
  std::string copy_;
  std::string_view view_;
};

/// "LINE:COLUMN" (both from 1) of the character at `offset` of `text` (clamped to its end).
std::string line_column(const std::string& text, std::size_t offset);

/// Parses `text` read from `source` as JSON (nlohmann::json or nlohmann::ordered_json). Throws
/// InputError "SOURCE:LINE:COLUMN: invalid JSON (parser message)".
template <typename Json = nlohmann::json>
Json parse_json_text(const std::string& text, const std::string& source) {
  try {
    return Json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    // nlohmann reports the 1-based byte of the error (0: before the first byte).
    throw InputError(source + ":" + line_column(text, e.byte == 0 ? 0 : e.byte - 1) +
                     ": invalid JSON (" + e.what() + ")");
  }
}

/// read_text_file then parse_json_text.
template <typename Json = nlohmann::json>
Json read_json_file(const std::string& path) {
  return parse_json_text<Json>(read_text_file(path), path);
}

/// j[key] of a JSON object read from `path`. Throws InputError "PATH: missing key 'WHERE KEY'
/// (expected EXPECTED)" when j is not an object or has no such key; `where` is the key path of j
/// (e.g. "coherence.").
const nlohmann::json& json_member(const nlohmann::json& j, const std::string& key,
                                  const std::string& path, const std::string& where,
                                  const std::string& expected);

/// The numbers of a JSON array at key path `key` of `path`, `size` of them when size > 0. A null
/// entry reads as NaN when `allow_null` (how stiffid writes non-finite values), else it is an
/// error like any non-number. Throws InputError naming the file and key.
std::vector<double> json_numbers(const nlohmann::json& j, const std::string& path,
                                 const std::string& key, std::size_t size, bool allow_null = false);

}  // namespace stiffid::data
