// The allocator settings of stiffid's programs (data/allocator.hpp): the GLIBC_TUNABLES value the
// front end hands to stiffid-full, and where the heap's large blocks come from.
#include <sys/resource.h>
#include <unistd.h>

#include <boost/test/unit_test.hpp>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "data/allocator.hpp"

using stiffid::data::tunables_with_huge_pages;

BOOST_AUTO_TEST_CASE(huge_pages_are_added_to_the_users_tunables_never_overriding_them) {
  BOOST_CHECK_EQUAL(tunables_with_huge_pages(nullptr), "glibc.malloc.hugetlb=1");
  BOOST_CHECK_EQUAL(tunables_with_huge_pages(""), "glibc.malloc.hugetlb=1");
  BOOST_CHECK_EQUAL(tunables_with_huge_pages("glibc.malloc.arena_max=2"),
                    "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1");
  // The user's own choice of the tunable stays, wherever it is in the list.
  BOOST_CHECK_EQUAL(tunables_with_huge_pages("glibc.malloc.hugetlb=0"), "glibc.malloc.hugetlb=0");
  BOOST_CHECK_EQUAL(tunables_with_huge_pages("glibc.malloc.arena_max=2:glibc.malloc.hugetlb=2"),
                    "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=2");
  // A tunable whose name only starts like it is another one.
  BOOST_CHECK_EQUAL(tunables_with_huge_pages("glibc.malloc.hugetlbx=1"),
                    "glibc.malloc.hugetlbx=1:glibc.malloc.hugetlb=1");
}

BOOST_AUTO_TEST_CASE(the_variable_is_set_for_the_program_started_next) {
  setenv("GLIBC_TUNABLES", "glibc.malloc.arena_max=3", 1);
  stiffid::data::ask_huge_pages_after_exec();
  BOOST_CHECK_EQUAL(std::string(std::getenv("GLIBC_TUNABLES")),
                    "glibc.malloc.arena_max=3:glibc.malloc.hugetlb=1");
  unsetenv("GLIBC_TUNABLES");
  stiffid::data::ask_huge_pages_after_exec();
  BOOST_CHECK_EQUAL(std::string(std::getenv("GLIBC_TUNABLES")), "glibc.malloc.hugetlb=1");
}

namespace {

// Transparent huge pages offered on request ("[always]" or "[madvise]").
bool huge_pages_on_request() {
  std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(in, line);
  return line.find("[always]") != std::string::npos || line.find("[madvise]") != std::string::npos;
}

// True when the 2 MiB-aligned range around `address` lies inside one mapping that is advised for
// transparent huge pages ("hg" among its VmFlags in /proc/self/smaps): where the kernel can
// fault it in as one huge page. False when it cannot be read.
bool in_huge_page_advised_range(std::uintptr_t address) {
  constexpr std::uintptr_t huge = std::uintptr_t{1} << 21;
  const std::uintptr_t first = address & ~(huge - 1), last = first + huge;
  std::ifstream in("/proc/self/smaps");
  bool inside = false;
  for (std::string line; std::getline(in, line);) {
    std::uintptr_t start = 0, end = 0;
    char dash = 0;
    std::istringstream header(line);
    if (header >> std::hex >> start >> dash >> end && dash == '-') {
      inside = start <= first && last <= end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      std::istringstream flags(line.substr(8));
      for (std::string flag; flags >> flag;)
        if (flag == "hg") return true;
      return false;
    }
  }
  return false;
}

long minor_faults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

}  // namespace

// After the call a 1 MiB block comes from the heap (not a fresh mapping), and the 2 MiB range it
// lies in (all but its first page) is advised for huge pages: the heap's top starts on a 2 MiB
// boundary whatever the address-space randomisation made of the heap's start, so the kernel can
// fault the block in as one huge page instead of 256 pages of 4 KiB (glibc with transparent huge
// pages on request; elsewhere only that the block is usable is checked). How the kernel then
// faults it in is its own affair, so the page faults are reported, not checked: 1 here on a quiet
// machine and 7-256 without the spacer block (wherever randomisation put the heap), but 16 once
// during a parallel build, with no fallback counted in /proc/vmstat.
BOOST_AUTO_TEST_CASE(a_large_block_after_the_call_is_faulted_in_as_a_huge_page) {
  stiffid::data::keep_large_blocks_for_reuse();
  constexpr std::size_t size = 1 << 20;
  const long before = minor_faults();
  auto* block = static_cast<volatile char*>(std::malloc(size));
  BOOST_REQUIRE(block != nullptr);
  for (std::size_t i = 0; i < size; i += 4096) block[i] = 1;
  const long faults = minor_faults() - before;
  const auto address = reinterpret_cast<std::uintptr_t>(block);
  const bool from_heap = address < reinterpret_cast<std::uintptr_t>(sbrk(0));
  // Its first page may hold the block's header just below the boundary, outside the advice.
  const bool advised =
      in_huge_page_advised_range(address + 4096) && in_huge_page_advised_range(address + size - 1);
  std::free(const_cast<char*>(block));
  BOOST_TEST_MESSAGE("1 MiB block: " << faults << " page faults");
#if defined(__GLIBC__)
  BOOST_CHECK(from_heap);
  if (huge_pages_on_request()) BOOST_CHECK(advised);
#endif
}
