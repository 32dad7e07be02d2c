#pragma once
// Error tiers of stiffid (see STYLE.md): bad user input throws InputError; numerical outcomes that
// are not bugs are reported in result structs (Status); broken invariants are asserts.

#include <cstdio>
#include <stdexcept>
#include <string>

namespace stiffid {

/// Bad input from a user: a file, a flag, a spec key. The message names where (file:line:column,
/// key or flag) and what was expected. The CLI prints it on one line and exits 2.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

/// Outcome of a numerical procedure that can legitimately fail on valid input (singular spectra, a
/// fit that did not converge). The CLI exits 1 with the message when `ok` is false.
struct Status {
  bool ok = true;
  std::string message;  ///< why it failed (empty when ok)

  static Status success() { return {}; }
  static Status failure(std::string why) { return {false, std::move(why)}; }
};

/// A number as messages print it: six significant digits without trailing zeros (2.5, 0.0025,
/// 4000, -0.01), where std::to_string prints six fixed decimals (2.500000, 0.002500).
inline std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

/// Version string of the build (CMake project version).
inline const char* version() { return STIFFID_VERSION; }

}  // namespace stiffid
