// `stiffid study` as a user runs it: exit codes, and SIGKILL then --resume.
#include <fcntl.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <boost/test/unit_test.hpp>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "tests/support/support.hpp"

namespace fs = std::filesystem;
using stiffid::test::read_text;
using stiffid::test::TempFolder;

namespace {

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Runs a shell command; returns its exit status (or -1 when it did not exit normally).
int run(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// 10 levels x 3 replicates = 30 cells of 60 ms each (the delay makes a kill land mid-study).
std::string slow_spec(int delay_ms) {
  return R"({"name": "slow", "seed": 11, "replicates": 3, "designs": [{"name": "d",
    "evaluator": "synthetic", "factors": {"mean": [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]},
    "template": {"mean": "${mean}", "samples": 30, "delay_ms": )" +
         std::to_string(delay_ms) + "}}]}";
}

int stored_cells(const std::string& store) {
  if (!fs::exists(store)) return 0;
  sqlite3* db = nullptr;
  int n = 0;
  if (sqlite3_open_v2(store.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_busy_timeout(db, 1000);
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, "SELECT count(*) FROM cells", -1, &stmt, nullptr) == SQLITE_OK &&
        sqlite3_step(stmt) == SQLITE_ROW) {
      n = sqlite3_column_int(stmt, 0);
    }
    sqlite3_finalize(stmt);
  }
  sqlite3_close(db);
  return n;
}

int line_count(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

}  // namespace

BOOST_AUTO_TEST_CASE(killed_study_resumes_to_the_same_table_without_duplicates) {
  TempFolder folder("study_cli");
  const std::string spec = folder.file("slow.json");
  write_text(spec, slow_spec(60));
  const std::string binary = STIFFID_BINARY;
  BOOST_REQUIRE_EQUAL(
      run(binary + " study " + spec + " --threads 2 --store " + folder.file("full.sqlite") +
          " --csv " + folder.file("full.csv") + " > " + folder.file("full.out")),
      0);

  const std::string store = folder.file("killed.sqlite");
  const pid_t child = fork();
  BOOST_REQUIRE(child >= 0);
  if (child == 0) {
    const int devnull = open("/dev/null", O_WRONLY);
    dup2(devnull, STDOUT_FILENO);
    execl(binary.c_str(), binary.c_str(), "study", spec.c_str(), "--threads", "1", "--store",
          store.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until some cells are stored, then kill without warning.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (stored_cells(store) < 5 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  BOOST_REQUIRE(WIFSIGNALED(status));
  const int before = stored_cells(store);
  BOOST_TEST_MESSAGE("cells stored when killed: " << before);
  BOOST_REQUIRE_GE(before, 5);
  BOOST_REQUIRE_LT(before, 30);

  const std::string out = folder.file("resume.out");
  BOOST_REQUIRE_EQUAL(run(binary + " study " + spec + " --threads 2 --resume --store " + store +
                          " --csv " + folder.file("resumed.csv") + " > " + out),
                      0);
  const std::string summary = read_text(out);
  BOOST_TEST_MESSAGE(summary);
  const std::string expected = "30 cells (" + std::to_string(before) + " resumed, " +
                               std::to_string(30 - before) + " computed, 0 failed)";
  BOOST_CHECK(summary.find(expected) != std::string::npos);
  const std::string full = read_text(folder.file("full.csv"));
  BOOST_CHECK_EQUAL(line_count(full), 30 * 3 + 1);  // header + 30 cells x 3 metrics
  BOOST_CHECK_EQUAL(read_text(folder.file("resumed.csv")), full);
}

BOOST_AUTO_TEST_CASE(exit_codes_follow_the_error_tiers) {
  TempFolder folder("study_cli");
  const std::string binary = STIFFID_BINARY;
  write_text(folder.file("bad.json"), R"({"name": "bad", "designs": [{"name": "d",
    "evaluator": "synthetic", "template": {"samples": -3}}]})");
  const std::string err = folder.file("bad.err");
  BOOST_CHECK_EQUAL(run(binary + " study " + folder.file("bad.json") + " --store " +
                        folder.file("bad.sqlite") + " 2> " + err + " > /dev/null"),
                    2);
  BOOST_CHECK(read_text(err).find("'samples'") != std::string::npos);
  BOOST_CHECK_EQUAL(run(binary + " study no_such_study --store " + folder.file("x.sqlite") +
                        " 2> /dev/null > /dev/null"),
                    2);
  BOOST_CHECK_EQUAL(run(binary + " study " + folder.file("bad.json") + " --resume --store " +
                        folder.file("never.sqlite") + " 2> /dev/null > /dev/null"),
                    2);
  write_text(folder.file("fail.json"), R"({"name": "fail", "designs": [{"name": "d",
    "evaluator": "synthetic", "template": {"fail": true}}]})");
  BOOST_CHECK_EQUAL(
      run(binary + " study " + folder.file("fail.json") + " --store " + folder.file("fail.sqlite") +
          " --csv " + folder.file("fail.csv") + " 2> /dev/null > /dev/null"),
      1);
  BOOST_CHECK(fs::exists(folder.file("fail.csv")));  // the table of what succeeded is written
}
