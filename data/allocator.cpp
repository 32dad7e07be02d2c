#include "data/allocator.hpp"

#include <cstdint>
#include <cstdlib>  // defines __GLIBC__ on glibc systems
#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace stiffid::data {

void keep_large_blocks_for_reuse() {
#if defined(__GLIBC__)
  // 32 MiB is glibc's largest accepted mmap threshold on 64-bit systems.
  constexpr std::size_t mib = 1024 * 1024;
  mallopt(M_MMAP_THRESHOLD, 32 * mib);
  mallopt(M_TRIM_THRESHOLD, 1024 * mib);
  mallopt(M_TOP_PAD, 64 * mib);
#if defined(MADV_HUGEPAGE)
  // Grow the heap by its pad now, from where the next blocks will be carved (the top), and ask
  // for transparent huge pages on all of it: a 2 MiB page is faulted in once instead of 512 4 KiB
  // pages (under THP "madvise", Debian's default; the advice is ignored where THP is off). The
  // block asked for is larger than anything the start-up left at the top, so that malloc extends
  // the break by it plus the pad.
  constexpr std::uintptr_t huge = 2 * mib;
  void* block = std::malloc(4 * mib);
  if (block == nullptr) return;
  const auto low = reinterpret_cast<std::uintptr_t>(block);
  const auto high = reinterpret_cast<std::uintptr_t>(sbrk(0));
  const std::uintptr_t page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const std::uintptr_t from = low & ~(page - 1);
  if (high > from) madvise(reinterpret_cast<void*>(from), high - from, MADV_HUGEPAGE);
  std::free(block);
  // Only whole 2 MiB-aligned ranges can be huge pages: the top starts at a random place within
  // one (address-space randomisation), and the blocks carved below the next 2 MiB boundary would
  // be faulted in 4 KiB at a time (up to 512 faults). A spacer block up to just below that
  // boundary is kept for the life of the program and never touched beyond its header, so the
  // blocks after it start on huge pages.
  const std::uintptr_t boundary = (low + huge - 1) & ~(huge - 1);
  constexpr std::uintptr_t slack = 256;  // malloc's headers and rounding, bytes
  static void* spacer = nullptr;
  if (spacer == nullptr && boundary > low + slack + page && boundary <= high)
    spacer = std::malloc(boundary - low - slack);
#endif
#endif
}

void one_heap_for_all_threads() {
#if defined(__GLIBC__)
  mallopt(M_ARENA_MAX, 1);
#endif
}

std::string tunables_with_huge_pages(const char* current) {
  const std::string value = current == nullptr ? "" : current;
  // Entries are NAME=VALUE separated by ':'; one setting the tunable already wins.
  if ((":" + value).find(":glibc.malloc.hugetlb=") != std::string::npos) return value;
  return value + (value.empty() ? "" : ":") + "glibc.malloc.hugetlb=1";
}

void ask_huge_pages_after_exec() {
  setenv("GLIBC_TUNABLES", tunables_with_huge_pages(std::getenv("GLIBC_TUNABLES")).c_str(), 1);
}

}  // namespace stiffid::data
