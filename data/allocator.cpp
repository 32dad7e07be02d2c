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
  // Grow the heap by its 64 MiB pad now and ask for transparent huge pages on it: a 2 MiB page
  // is faulted in once instead of 512 4 KiB pages (under THP "madvise", Debian's default; the
  // advice is ignored where THP is off).
  void* block = std::malloc(mib);  // from the heap's top: grows it by the pad
  const auto low = reinterpret_cast<std::uintptr_t>(block);
  const auto high = reinterpret_cast<std::uintptr_t>(sbrk(0));
  constexpr std::uintptr_t huge = 2 * mib;
  const std::uintptr_t first = (low + huge - 1) & ~(huge - 1);
  const std::uintptr_t last = high & ~(huge - 1);
  if (block != nullptr && last > first)
    madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
  std::free(block);
#endif
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
