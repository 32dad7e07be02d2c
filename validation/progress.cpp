#include "validation/progress.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace stiffid::validation {
namespace {

std::string duration_text(double seconds) {
  const long s = std::lround(seconds);
  char buffer[32];
  if (s >= 3600) {
    std::snprintf(buffer, sizeof buffer, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  } else {
    std::snprintf(buffer, sizeof buffer, "%ld:%02ld", s / 60, s % 60);
  }
  return buffer;
}

}  // namespace

bool stderr_is_terminal() { return isatty(STDERR_FILENO) == 1; }

ProgressBar::ProgressBar(std::string label, int total, int already_done, bool enabled)
    : label_(std::move(label)),
      total_(total),
      done_(already_done),
      enabled_(enabled),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {
  if (enabled_) draw();
}

ProgressBar::~ProgressBar() { finish(); }

std::string ProgressBar::render(const std::string& label, int done, int total, int fresh,
                                double elapsed_s, int width) {
  const double fraction = total > 0 ? static_cast<double>(done) / total : 1.0;
  const int filled = static_cast<int>(std::floor(fraction * width));
  std::string bar(static_cast<std::size_t>(filled), '=');
  bar.resize(static_cast<std::size_t>(width), ' ');
  char buffer[160];
  std::string rate = "-";
  std::string eta = "-";
  if (fresh > 0 && elapsed_s > 0.0) {
    const double per_s = fresh / elapsed_s;
    char r[32];
    std::snprintf(r, sizeof r, "%.1f", per_s);
    rate = r;
    eta = duration_text((total - done) / per_s);
  }
  std::snprintf(buffer, sizeof buffer, "%s [%s] %d/%d cells  %s cells/s  ETA %s", label.c_str(),
                bar.c_str(), done, total, rate.c_str(), eta.c_str());
  return buffer;
}

void ProgressBar::draw() {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  // \r returns to the line start; \033[K clears what a longer previous line left behind.
  std::fprintf(stderr, "\r%s\033[K", render(label_, done_, total_, fresh_, elapsed).c_str());
  std::fflush(stderr);
}

void ProgressBar::tick() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++done_;
  ++fresh_;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(100) && done_ < total_) return;
  last_draw_ = now;
  draw();
}

void ProgressBar::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (!enabled_) return;
  draw();
  std::fputc('\n', stderr);
}

}  // namespace stiffid::validation
