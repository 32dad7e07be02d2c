#pragma once
// Output that never leaves a partial file behind.

#include <nlohmann/json.hpp>
#include <string>

namespace stiffid::data {

/// Writes `content` to a temporary file in the folder of `path`, flushes it, then renames it over
/// `path`, so readers see either the old file or the whole new one. Throws InputError when the
/// folder is not writable.
void write_file_atomically(const std::string& path, const std::string& content);

/// The text of value.dump(2), byte for byte; the members of an object are formatted in parallel
/// (a tfa result holds ~100 000 numbers).
std::string dump_json(const nlohmann::json& value);

/// Writes JSON (indented by 2) to `path` atomically, or to stdout when `path` is empty or "-".
void write_json(const std::string& path, const nlohmann::json& value);

}  // namespace stiffid::data
