// `mpirun -n 2 stiffid study SPEC` gives the same table as one process (issue 5).
#include <boost/test/unit_test.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/support/support.hpp"

namespace fs = std::filesystem;
using stiffid::test::read_text;

namespace {

int run(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}
}  // namespace

BOOST_AUTO_TEST_CASE(two_mpi_ranks_give_the_single_process_table) {
  if (run("command -v mpirun > /dev/null 2>&1") != 0) {
    BOOST_TEST_MESSAGE("mpirun not installed: the MPI backend is not exercised");
    return;
  }
  const stiffid::test::TempFolder folder("study_mpi");
  const fs::path& dir = folder.path;
  std::ofstream(dir / "spec.json") << R"({"name": "mpi", "seed": 5, "replicates": 3, "designs": [
    {"name": "d", "evaluator": "synthetic", "factors": {"mean": [0, 1, 2, 3, 4, 5, 6]},
     "template": {"mean": "${mean}", "samples": 20}}]})";
  const std::string bin = STIFFID_BINARY;
  const std::string spec = (dir / "spec.json").string();
  BOOST_REQUIRE_EQUAL(run(bin + " study " + spec + " --store " + (dir / "one.sqlite").string() +
                          " --csv " + (dir / "one.csv").string() + " 2> /dev/null"),
                      0);
  const int mpi = run("mpirun --allow-run-as-root --oversubscribe -n 2 " + bin + " study " + spec +
                      " --store " + (dir / "two.sqlite").string() + " --csv " +
                      (dir / "two.csv").string() + " > " + (dir / "mpi.log").string() + " 2>&1");
  BOOST_REQUIRE_MESSAGE(mpi == 0, "mpirun exit " << mpi << ":\n" << read_text(dir / "mpi.log"));
  const std::string one = read_text(dir / "one.csv");
  BOOST_CHECK_GT(one.size(), 100u);
  BOOST_CHECK(one == read_text(dir / "two.csv"));  // same cells, seeds and values, byte for byte
}
