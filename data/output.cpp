#include "data/output.hpp"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <vector>

#include "data/error.hpp"
#include "data/parallel.hpp"

namespace stiffid::data {

void write_file_atomically(const std::string& path, const std::string& content) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  std::error_code ec;
  if (fs::is_directory(target, ec) || !target.has_filename()) {
    throw InputError(path + ": is a folder; give a file name to write");
  }
  const fs::path temporary =
      target.parent_path() / ("." + target.filename().string() + ".tmp" + std::to_string(getpid()));
  std::FILE* file = std::fopen(temporary.c_str(), "wb");
  if (file == nullptr) throw InputError(path + ": cannot write (folder missing or not writable)");
  const bool written = std::fwrite(content.data(), 1, content.size(), file) == content.size();
  const bool flushed = std::fflush(file) == 0 && fsync(fileno(file)) == 0;
  const bool closed = std::fclose(file) == 0;
  if (!(written && flushed && closed)) {
    fs::remove(temporary, ec);
    throw InputError(path + ": write failed (disk full?)");
  }
  std::error_code renamed;
  fs::rename(temporary, target, renamed);
  if (renamed) {
    fs::remove(temporary, ec);
    throw InputError(path + ": cannot rename the finished file into place: " + renamed.message());
  }
}

std::string dump_json(const nlohmann::json& value) {
  if (!value.is_object() || value.size() < 2) return value.dump(2);
  // nlohmann's indented object: "{\n", then per member two spaces, the quoted key, ": " and the
  // member's own indented text with every line after its first moved in by two, ",\n" between
  // members, "\n}". Strings hold no raw newline (they are escaped), so the only newlines of a
  // member's text are its line breaks.
  std::vector<const std::string*> keys;
  std::vector<const nlohmann::json*> members;
  for (auto it = value.begin(); it != value.end(); ++it) {
    keys.push_back(&it.key());
    members.push_back(&it.value());
  }
  std::vector<std::string> parts(members.size());
  parallel_for_index(members.size(), [&](std::size_t k) {
    const std::string text = members[k]->dump(2);
    std::string& out = parts[k];
    out.reserve(text.size() + text.size() / 8);
    out += "  ";
    out += nlohmann::json(*keys[k]).dump();
    out += ": ";
    for (std::size_t from = 0; from < text.size();) {
      const std::size_t line_end = text.find('\n', from);
      if (line_end == std::string::npos) {
        out.append(text, from, std::string::npos);
        break;
      }
      out.append(text, from, line_end + 1 - from);
      out += "  ";
      from = line_end + 1;
    }
  });
  std::size_t size = 4;
  for (const std::string& part : parts) size += part.size() + 2;
  std::string text;
  text.reserve(size);
  text += "{\n";
  for (std::size_t k = 0; k < parts.size(); ++k) {
    text += parts[k];
    text += k + 1 < parts.size() ? ",\n" : "\n";
  }
  text += '}';
  return text;
}

void write_json(const std::string& path, const nlohmann::json& value) {
  if (path.empty() || path == "-") {
    std::cout << dump_json(value) << '\n';
  } else {
    std::string text = dump_json(value);
    text += '\n';  // appended in place: no second copy of a multi-megabyte text
    write_file_atomically(path, text);
  }
}

}  // namespace stiffid::data
