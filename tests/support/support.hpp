#pragma once
// Test support shared by the test programs: a scratch folder that is removed when the test ends,
// whole-file reading that gives "" for a file that is missing (so a failed run reports its own
// message instead of an exception from the reader), and checks on InputError messages.

#include <unistd.h>

#include <boost/test/unit_test.hpp>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "data/error.hpp"

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

/// The message of the InputError `f` throws, or "" when it throws none.
inline std::string input_error_message(const std::function<void()>& f) {
  try {
    f();
  } catch (const stiffid::InputError& e) {
    return e.what();
  }
  return "";
}

/// Whether `message` holds `text`; says what it lacks when it does not.
inline bool mentions(const std::string& message, const std::string& text) {
  if (message.find(text) != std::string::npos) return true;
  BOOST_TEST_MESSAGE("\"" << message << "\" does not mention \"" << text << "\"");
  return false;
}

/// Checks that `f` throws InputError and that its message holds every one of `parts`.
inline void expect_input_error(const std::function<void()>& f,
                               const std::vector<std::string>& parts) {
  try {
    f();
    BOOST_ERROR("no InputError");
  } catch (const stiffid::InputError& e) {
    for (const auto& p : parts) {
      BOOST_CHECK_MESSAGE(std::string(e.what()).find(p) != std::string::npos,
                          "'" << e.what() << "' lacks '" << p << "'");
    }
  }
}

}  // namespace stiffid::test
