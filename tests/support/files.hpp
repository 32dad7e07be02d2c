#pragma once
// Test support shared by the test programs: a scratch folder that is removed when the test ends,
// and whole-file reading that gives "" for a file that is missing (so a failed run reports its
// own message instead of an exception from the reader).

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace stiffid::test {

/// A fresh folder in the system temporary folder, named after `tag` and the process id.
struct TempFolder {
  std::filesystem::path path;
  explicit TempFolder(const std::string& tag)
      : path(std::filesystem::temp_directory_path() /
             ("stiffid_test_" + tag + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempFolder() { std::filesystem::remove_all(path); }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  std::string file(const std::string& name) const { return (path / name).string(); }
};

/// The whole file, or "" when it cannot be opened.
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace stiffid::test
