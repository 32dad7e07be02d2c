// The allocator settings of stiffid's programs (data/allocator.hpp): the GLIBC_TUNABLES value the
// front end hands to stiffid-full.
#include <boost/test/unit_test.hpp>
#include <cstdlib>
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
