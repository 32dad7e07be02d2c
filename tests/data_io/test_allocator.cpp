// The allocator settings of stiffid's programs (data/allocator.hpp): the GLIBC_TUNABLES value the
// front end hands to stiffid-full, and where the heap's large blocks come from.
#include <sys/resource.h>
#include <unistd.h>

#include <boost/test/unit_test.hpp>
#include <cstdint>
#include <cstdlib>
#include <fstream>
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

// A counter of /proc/vmstat (-1 where it cannot be read).
long vmstat(const std::string& name) {
  std::ifstream in("/proc/vmstat");
  std::string key;
  long value = 0;
  while (in >> key >> value)
    if (key == name) return value;
  return -1;
}

// Transparent huge pages offered on request ("[always]" or "[madvise]").
bool huge_pages_on_request() {
  std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(in, line);
  return line.find("[always]") != std::string::npos || line.find("[madvise]") != std::string::npos;
}

long minor_faults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

}  // namespace

// After the call a 1 MiB block comes from the heap (not a fresh mapping) and is faulted in as a
// huge page, not 256 pages of 4 KiB: the heap's top starts on a 2 MiB boundary whatever the
// address-space randomisation made of the heap's start (glibc with transparent huge pages on
// request; elsewhere, or when the kernel has no free huge page right now, only that the block
// is usable is checked).
BOOST_AUTO_TEST_CASE(a_large_block_after_the_call_is_faulted_in_as_a_huge_page) {
  stiffid::data::keep_large_blocks_for_reuse();
  constexpr std::size_t size = 1 << 20;
  const long fallbacks = vmstat("thp_fault_fallback");
  const long before = minor_faults();
  auto* block = static_cast<volatile char*>(std::malloc(size));
  BOOST_REQUIRE(block != nullptr);
  for (std::size_t i = 0; i < size; i += 4096) block[i] = 1;
  const long faults = minor_faults() - before;
  const bool from_heap =
      reinterpret_cast<std::uintptr_t>(block) < reinterpret_cast<std::uintptr_t>(sbrk(0));
  std::free(const_cast<char*>(block));
  BOOST_TEST_MESSAGE("1 MiB block: " << faults << " page faults");
#if defined(__GLIBC__)
  BOOST_CHECK(from_heap);
  if (huge_pages_on_request() && fallbacks >= 0 && vmstat("thp_fault_fallback") == fallbacks)
    BOOST_CHECK_LT(faults, 16);
#endif
}
