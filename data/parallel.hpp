#pragma once
// Parallel loops for stiffid's numerical kernels, on oneTBB (the task scheduler the study runner
// uses too, so nested loops share one pool instead of oversubscribing the cores).
//
// Determinism: every caller splits its work into pieces whose number and boundaries do not depend
// on the thread count (fixed groups of Welch segments, of correlation blocks, of CSV lines) and
// combines their results in index order, so results are bit-identical at any thread count.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <cstddef>
#include <exception>
#include <vector>

namespace stiffid::data {

/// Threads the current task arena may use (the machine's cores unless a caller limited them).
inline int max_threads() { return tbb::this_task_arena::max_concurrency(); }

/// Runs work(k) once for every k = 0..count-1, in parallel, and returns when all are done. When
/// some throw, rethrows the exception of the lowest k that threw (what a sequential loop that
/// stopped at its first failure would report); the others still ran.
template <typename Work>
void parallel_for_index(std::size_t count, Work&& work) {
  if (count == 0) return;
  std::vector<std::exception_ptr> errors(count);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, count, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
          try {
            work(k);
          } catch (...) {
            errors[k] = std::current_exception();
          }
        }
      },
      tbb::simple_partitioner());
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

/// Splits the indices 0..count-1 into `groups` (>= 1) fixed runs of consecutive indices, run g
/// being [count g / groups, count (g + 1) / groups), and calls work(g, begin, end) for every run
/// in parallel (parallel_for_index). The runs depend only on count and groups, never on the
/// thread count.
template <typename Work>
void parallel_for_groups(int count, int groups, Work&& work) {
  parallel_for_index(static_cast<std::size_t>(groups), [&](std::size_t g) {
    const int begin = static_cast<int>(static_cast<long>(count) * static_cast<long>(g) / groups);
    const int end = static_cast<int>(static_cast<long>(count) * static_cast<long>(g + 1) / groups);
    work(g, begin, end);
  });
}

}  // namespace stiffid::data
