#pragma once
// A one-line progress bar on stderr for long runs: cells done / total, rate and ETA.

#include <chrono>
#include <mutex>
#include <string>

namespace stiffid::validation {

/// True when stderr is a terminal (isatty), the only case where a progress bar is drawn.
bool stderr_is_terminal();

class ProgressBar {
 public:
  /// `total` units of work of which `already_done` were done before (resumed); draws nothing when
  /// `enabled` is false. Thread-safe.
  ProgressBar(std::string label, int total, int already_done, bool enabled);
  ~ProgressBar();
  /// One more unit done; redraws at most every 100 ms.
  void tick();
  /// Draws the final state and ends the line (called by the destructor when not called before).
  void finish();

  /// The bar's text for `done` of `total` after `elapsed_s` seconds in which `fresh` units were
  /// computed in this run (the rate and ETA count only those). Pure, for tests.
  static std::string render(const std::string& label, int done, int total, int fresh,
                            double elapsed_s, int width = 24);

 private:
  void draw();
  std::string label_;
  int total_;
  int done_;
  int fresh_ = 0;
  bool enabled_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  std::mutex mutex_;
};

}  // namespace stiffid::validation
