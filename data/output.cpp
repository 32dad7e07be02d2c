#include "data/output.hpp"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "data/error.hpp"

namespace stiffid::data {

void write_file_atomically(const std::string& path, const std::string& content) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path temporary =
      target.parent_path() / ("." + target.filename().string() + ".tmp" + std::to_string(getpid()));
  std::FILE* file = std::fopen(temporary.c_str(), "wb");
  if (file == nullptr) throw InputError(path + ": cannot write (folder missing or not writable)");
  const bool written = std::fwrite(content.data(), 1, content.size(), file) == content.size();
  const bool flushed = std::fflush(file) == 0 && fsync(fileno(file)) == 0;
  const bool closed = std::fclose(file) == 0;
  std::error_code ec;
  if (!(written && flushed && closed)) {
    fs::remove(temporary, ec);
    throw InputError(path + ": write failed (disk full?)");
  }
  fs::rename(temporary, target, ec);
  if (ec) {
    fs::remove(temporary, ec);
    throw InputError(path + ": cannot rename the finished file into place: " + ec.message());
  }
}

void write_json(const std::string& path, const nlohmann::json& value) {
  if (path.empty() || path == "-") {
    std::cout << value.dump(2) << '\n';
  } else {
    std::string text = value.dump(2);
    text += '\n';  // appended in place: no second copy of a multi-megabyte text
    write_file_atomically(path, text);
  }
}

}  // namespace stiffid::data
