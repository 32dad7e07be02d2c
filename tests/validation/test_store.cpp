#include <sqlite3.h>
#include <unistd.h>

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <filesystem>
#include <limits>

#include "data/error.hpp"
#include "tests/support/support.hpp"
#include "validation/store.hpp"

namespace v = stiffid::validation;
namespace fs = std::filesystem;
using stiffid::test::TempFolder;

namespace {

v::StoreHeader header(const std::string& hash = "00000000000000aa") {
  return {"unit", hash, "{\"name\":\"unit\"}", "test"};
}

v::CellRecord record(int cell, std::map<std::string, double> metrics) {
  v::CellRecord r;
  r.cell = cell;
  r.design = "d";
  r.levels_json = "{\"x\":" + std::to_string(cell) + "}";
  r.replicate = cell % 2;
  r.seed = 0xfedcba9876543210ULL + static_cast<unsigned>(cell);  // above INT64_MAX on purpose
  r.started_utc = v::ResultStore::utc_now();
  r.finished_utc = v::ResultStore::utc_now();
  r.metrics = std::move(metrics);
  return r;
}

int count_rows(const std::string& path, const std::string& table) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* stmt = nullptr;
  sqlite3_prepare_v2(db, ("SELECT count(*) FROM " + table).c_str(), -1, &stmt, nullptr);
  sqlite3_step(stmt);
  const int n = sqlite3_column_int(stmt, 0);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return n;
}

}  // namespace

BOOST_AUTO_TEST_CASE(cells_round_trip_with_exact_values_and_64_bit_seeds) {
  TempFolder folder("store");
  const std::string path = folder.file("a.sqlite");
  {
    v::ResultStore store(path, v::ResultStore::Mode::create, header());
    store.write_cell(record(1, {{"b", 0.1}, {"a", -1.0 / 3.0}}));
    store.write_cell(record(0, {{"nan", std::numeric_limits<double>::quiet_NaN()}}));
  }
  const v::ResultStore store(path, v::ResultStore::Mode::read_only);
  BOOST_CHECK_EQUAL(store.header().spec_hash, "00000000000000aa");
  BOOST_CHECK_EQUAL(store.header().stiffid_version, "test");
  const auto rows = store.rows();
  BOOST_REQUIRE_EQUAL(rows.size(), 3u);
  // Ordered by cell, then metric name.
  BOOST_CHECK_EQUAL(rows[0].cell, 0);
  BOOST_CHECK(std::isnan(rows[0].value));
  BOOST_CHECK_EQUAL(rows[1].metric, "a");
  BOOST_CHECK_EQUAL(rows[1].value, -1.0 / 3.0);  // REAL is an IEEE double: bit-exact
  BOOST_CHECK_EQUAL(rows[2].value, 0.1);
  BOOST_CHECK_EQUAL(rows[2].seed, 0xfedcba9876543211ULL);
  BOOST_CHECK_EQUAL(rows[2].levels_json, "{\"x\":1}");
  BOOST_CHECK(store.stored_cells() == (std::set<int>{0, 1}));
}

BOOST_AUTO_TEST_CASE(a_cell_cannot_be_written_twice_and_a_rejected_cell_leaves_nothing) {
  TempFolder folder("store");
  const std::string path = folder.file("b.sqlite");
  v::ResultStore store(path, v::ResultStore::Mode::create, header());
  store.write_cell(record(3, {{"m", 1.0}, {"n", 2.0}}));
  BOOST_CHECK_THROW(store.write_cell(record(3, {{"m", 5.0}})), stiffid::InputError);
  BOOST_CHECK_EQUAL(count_rows(path, "results"), 2);
  BOOST_CHECK_EQUAL(count_rows(path, "cells"), 1);
  BOOST_CHECK_EQUAL(store.rows()[0].value, 1.0);
}

BOOST_AUTO_TEST_CASE(failed_cells_are_stored_without_metrics) {
  TempFolder folder("store");
  v::ResultStore store(folder.file("c.sqlite"), v::ResultStore::Mode::create, header());
  v::CellRecord failed = record(7, {});
  failed.ok = false;
  failed.message = "singular Gxx";
  store.write_cell(failed);
  const auto list = store.failed_cells();
  BOOST_REQUIRE_EQUAL(list.size(), 1u);
  BOOST_CHECK_EQUAL(list[0].first, 7);
  BOOST_CHECK_EQUAL(list[0].second, "singular Gxx");
  BOOST_CHECK(store.rows().empty());
  BOOST_CHECK(store.stored_cells().count(7));
}

BOOST_AUTO_TEST_CASE(resuming_checks_the_spec_hash_and_creating_replaces) {
  TempFolder folder("store");
  const std::string path = folder.file("d.sqlite");
  {
    v::ResultStore store(path, v::ResultStore::Mode::create, header());
    store.write_cell(record(0, {{"m", 1.0}}));
  }
  BOOST_CHECK_THROW(v::ResultStore(path, v::ResultStore::Mode::open_existing, header("bb")),
                    stiffid::InputError);
  {
    v::ResultStore resumed(path, v::ResultStore::Mode::open_existing, header());
    BOOST_CHECK_EQUAL(resumed.stored_cells().size(), 1u);
  }
  v::ResultStore fresh(path, v::ResultStore::Mode::create, header());
  BOOST_CHECK(fresh.stored_cells().empty());
  BOOST_CHECK_THROW(
      v::ResultStore(folder.file("missing.sqlite"), v::ResultStore::Mode::open_existing, header()),
      stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(merge_copies_missing_cells_and_keeps_present_ones) {
  TempFolder folder("store");
  const std::string main_path = folder.file("main.sqlite");
  const std::string part_path = folder.file("main.sqlite.rank1");
  v::ResultStore main_store(main_path, v::ResultStore::Mode::create, header());
  main_store.write_cell(record(0, {{"m", 1.0}}));
  {
    v::ResultStore part(part_path, v::ResultStore::Mode::create, header());
    part.write_cell(record(0, {{"m", 99.0}}));
    part.write_cell(record(1, {{"m", 2.0}, {"n", 3.0}}));
  }
  main_store.merge_from(part_path);
  const auto rows = main_store.rows();
  BOOST_REQUIRE_EQUAL(rows.size(), 3u);
  BOOST_CHECK_EQUAL(rows[0].value, 1.0);  // not replaced by the part's 99
  BOOST_CHECK_EQUAL(rows[2].value, 3.0);
  // A part of another study is refused.
  const std::string other = folder.file("other.sqlite");
  { v::ResultStore o(other, v::ResultStore::Mode::create, header("cc")); }
  BOOST_CHECK_THROW(main_store.merge_from(other), stiffid::InputError);
}
