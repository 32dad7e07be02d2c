#include <boost/test/unit_test.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "tests/support/support.hpp"

namespace d = stiffid::data;

namespace {
// Expects parse_trial_csv to throw InputError whose message contains every fragment.
void expect_error(const std::string& text, const std::vector<std::string>& fragments,
                  const d::TrialCsvOptions& options = {}) {
  try {
    d::parse_trial_csv(text, "trial.csv", options);
    BOOST_ERROR("no error for:\n" << text);
  } catch (const stiffid::InputError& e) {
    for (const auto& f : fragments) {
      BOOST_CHECK_MESSAGE(std::string(e.what()).find(f) != std::string::npos,
                          "'" << e.what() << "' lacks '" << f << "'");
    }
  }
}
}  // namespace

BOOST_AUTO_TEST_CASE(reads_channels_units_and_rate_from_time_column) {
  const auto trial = d::parse_trial_csv("t,fx[N],x (m)\n0.0,1,2\n0.02,3,4\n0.04,5,6\n", "a.csv");
  BOOST_CHECK_CLOSE(trial.sample_rate_hz, 50.0, 1e-9);
  BOOST_REQUIRE_EQUAL(trial.channel_count(), 2);
  BOOST_CHECK_EQUAL(trial.names[0], "fx");
  BOOST_CHECK_EQUAL(trial.units[0], "N");
  BOOST_CHECK_EQUAL(trial.units[1], "m");
  BOOST_CHECK_EQUAL(trial.samples(2, trial.index("x")), 6.0);
}

BOOST_AUTO_TEST_CASE(accepts_quoted_cells_crlf_and_comment_lines) {
  const auto trial =
      d::parse_trial_csv("# made by hand\r\nt,\"fx\"\r\n0,\"1.5\"\r\n\r\n0.5,2\r\n", "q.csv");
  BOOST_CHECK_CLOSE(trial.sample_rate_hz, 2.0, 1e-12);
  BOOST_CHECK_EQUAL(trial.samples(0, trial.index("fx")), 1.5);
  BOOST_CHECK_EQUAL(trial.samples(1, 0), 2.0);
  expect_error("t,x\n0,\"1,2\"\n", {"trial.csv:2:2", "'1,2'"});
}

BOOST_AUTO_TEST_CASE(uses_given_rate_without_time_column) {
  d::TrialCsvOptions options;
  options.sample_rate_hz = 1000.0;
  const auto trial = d::parse_trial_csv("a,b\n1,2\n3,4\n", "b.csv", options);
  BOOST_CHECK_EQUAL(trial.sample_rate_hz, 1000.0);
  expect_error("a,b\n1,2\n3,4\n", {"no time column", "--fs"});
}

BOOST_AUTO_TEST_CASE(bad_cells_are_named_by_file_line_and_column) {
  expect_error("t,x\n0,1\n0.1,abc\n", {"trial.csv:3:2", "'x'", "abc"});
  expect_error("t,x\n0,1\n0.1,nan\n", {"trial.csv:3:2", "finite"});
  expect_error("t,x\n0,1\n0.1,inf\n", {"trial.csv:3:2", "finite"});
  expect_error("t,x\n0,1\n0.1,\n", {"trial.csv:3:2"});
}

BOOST_AUTO_TEST_CASE(structural_errors_are_named) {
  expect_error("t,x,x\n0,1,2\n", {"trial.csv:1:3", "duplicate column 'x'"});
  expect_error("t,x\n0,1\n0.1,2,3\n", {"trial.csv:3", "ragged"});
  expect_error("", {"empty file"});
}

BOOST_AUTO_TEST_CASE(time_must_increase_uniformly) {
  expect_error("t,x\n0,1\n0.1,2\n0.1,3\n", {"trial.csv:4:1", "increase"});
  expect_error("t,x\n0,1\n0.1,2\n0.25,3\n0.3,4\n", {"trial.csv:4:1", "non-uniform"});
  // Jitter of 1e-4 step is within the default tolerance of 1e-3 step.
  const auto trial = d::parse_trial_csv("t,x\n0,1\n0.10001,2\n0.2,3\n", "ok.csv");
  BOOST_CHECK_CLOSE(trial.sample_rate_hz, 10.0, 1e-9);
}

// Rows missing from a long record: the error names the interval where they are missing (line 53,
// t 0.5 -> 0.56 s, 6 steps), not the first row that the stretched mean step puts off its grid.
// A clock that runs 4e-4 fast, then as slow: every interval is within the tolerance of the others,
// but the middle rows are 0.02 steps off the grid; the first row off it (line 5) is named.
BOOST_AUTO_TEST_CASE(missing_rows_are_named_where_they_are_missing) {
  std::string gap = "t,x\n";
  for (int i = 0; i < 100; ++i)
    if (i <= 50 || i >= 56) gap += std::to_string(i / 100.0) + ",1\n";
  expect_error(gap, {"trial.csv:53:1", "from 0.5 to 0.56 s", "6 times the typical step of 0.01 s",
                     "missing or repeated rows"});
  std::string drift = "t,x\n";
  double t = 0.0;
  for (int i = 0; i < 100; ++i, t += 0.01 * (i <= 50 ? 1.0004 : 0.9996)) {
    std::ostringstream row;
    row << std::setprecision(17) << t << ",1\n";
    drift += row.str();
  }
  expect_error(drift, {"trial.csv:5:1", "steps off the uniform grid"});
}

// A byte-order mark (spreadsheets write one before the header) is not part of the first name;
// a file separated by ';' or tabs is named as such.
BOOST_AUTO_TEST_CASE(byte_order_mark_is_skipped_and_other_separators_are_named) {
  const auto trial = d::parse_trial_csv("\xEF\xBB\xBFt,x\n0,1\n0.5,2\n", "bom.csv");
  BOOST_CHECK_CLOSE(trial.sample_rate_hz, 2.0, 1e-12);
  BOOST_CHECK_EQUAL(trial.names.at(0), "x");
  const d::CsvTable table = d::parse_csv("\xEF\xBB\xBFid,err\n1,2\n", "bom.csv");
  BOOST_CHECK_EQUAL(table.header.at(0), "id");
  expect_error("t;x\n0;1\n0.5;2\n", {"trial.csv:1", "'t;x'", "separated by ','", "';'"});
  expect_error("t\tx\n0\t1\n0.5\t2\n", {"trial.csv:1", "separated by ','", "tabs"});
}

BOOST_AUTO_TEST_CASE(missing_channel_and_file_are_named) {
  const auto trial = d::parse_trial_csv("t,x\n0,1\n0.1,2\n", "c.csv");
  BOOST_CHECK_EXCEPTION(trial.index("fy"), stiffid::InputError, [](const auto& e) {
    return std::string(e.what()).find("c.csv: no channel 'fy'") != std::string::npos;
  });
  BOOST_CHECK_EXCEPTION(
      d::read_csv("/nonexistent/trial.csv"), stiffid::InputError,
      [](const auto& e) { return std::string(e.what()).find("/nonexistent/trial.csv") == 0; });
  BOOST_CHECK_THROW(d::require_samples(trial, 256, "one Welch segment"), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(written_trial_reads_back_bit_exact) {
  d::Trial trial;
  trial.sample_rate_hz = 4000.0;
  trial.add_channel("th1", "rad", Eigen::VectorXd::LinSpaced(9, 0.1, 0.9).array().sin());
  trial.add_channel("fx", "N", Eigen::VectorXd::Random(9));
  const stiffid::test::TempFolder folder("csv_roundtrip");
  const std::string path = folder.file("roundtrip.csv");
  d::write_trial_csv(path, trial, true);
  const auto back = d::read_trial_csv(path);
  BOOST_CHECK_CLOSE(back.sample_rate_hz, 4000.0, 1e-9);
  BOOST_CHECK(back.samples == trial.samples);
  BOOST_CHECK_EQUAL(back.units[0], "rad");
}

BOOST_AUTO_TEST_CASE(json_text_is_nlohmanns_indented_dump_byte_for_byte) {
  // dump_json formats an object's members in parallel; its text must be exactly dump(2)'s:
  // nested objects and arrays, empty ones, escaped keys and strings, numbers of every kind.
  const nlohmann::json value = nlohmann::json::parse(R"({
    "t_s": [2.5, 2.5025, 1e-300, -0.0, 12345678901234567890, 3],
    "K_nm_per_rad": [[[35.0, 35.1], []], [[5.5], [20.25, {"a": [1, {"b": {}}]}]]],
    "options": {"window": "kaiser:3", "angles": ["th1", "th2"], "flag": true, "none": null},
    "quote\"key\n": "line\nbreak \u00e9 \t tab",
    "empty_object": {}, "empty_array": [], "number": -1.5e-7})");
  BOOST_CHECK_EQUAL(d::dump_json(value), value.dump(2));
  for (const char* text : {"{}", "[]", "[1, 2]", "{\"one\": [1]}", "3.5", "\"s\""}) {
    const nlohmann::json v = nlohmann::json::parse(text);
    BOOST_CHECK_EQUAL(d::dump_json(v), v.dump(2));
  }
}

BOOST_AUTO_TEST_CASE(atomic_write_leaves_no_temporary_and_fails_cleanly) {
  const stiffid::test::TempFolder folder("atomic");
  const std::filesystem::path& dir = folder.path;
  d::write_file_atomically((dir / "out.json").string(), "{}\n");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++files;
  BOOST_CHECK_EQUAL(files, 1);
  BOOST_CHECK_THROW(d::write_file_atomically("/nonexistent/dir/out.json", "{}"),
                    stiffid::InputError);
  // A folder given for the file: named as such, nothing written beside it or in its parent.
  for (const std::string& target : {dir.string(), dir.string() + "/"}) {
    BOOST_CHECK_EXCEPTION(d::write_file_atomically(target, "{}"), stiffid::InputError,
                          [&](const stiffid::InputError& e) {
                            return std::string(e.what()) ==
                                   target + ": is a folder; give a file name to write";
                          });
  }
  files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++files;
  BOOST_CHECK_EQUAL(files, 1);
  for (const auto& entry : std::filesystem::directory_iterator(dir.parent_path()))
    BOOST_CHECK(entry.path().filename().string().rfind("." + dir.filename().string(), 0) != 0);
}

namespace {
// A uniformly sampled trial large enough to be parsed in several chunks (> 1 MiB of rows), as
// text: t at 1 kHz, then `a` = row index and `b` = a value with a long decimal expansion.
std::string large_trial_text(int rows) {
  std::string text = "t,a,b\n";
  char line[96];
  for (int r = 0; r < rows; ++r) {
    std::snprintf(line, sizeof line, "%.17g,%d,%.17g\n", r * 1e-3, r, std::sin(0.001 * r) / 3.0);
    text += line;
  }
  return text;
}
}  // namespace

BOOST_AUTO_TEST_CASE(large_trials_parse_in_chunks_to_the_same_values_as_a_row_by_row_read) {
  const int rows = 60000;  // ~2.5 MB: several chunks on any machine with more than one core
  const std::string text = large_trial_text(rows);
  const auto trial = d::parse_trial_csv(text, "big.csv");
  BOOST_REQUIRE_EQUAL(trial.sample_count(), rows);
  BOOST_CHECK_CLOSE(trial.sample_rate_hz, 1000.0, 1e-9);
  bool exact = true;
  for (int r = 0; r < rows; ++r) {
    // strtod is the independent reference for the text the writer printed.
    char cell[40];
    std::snprintf(cell, sizeof cell, "%.17g", std::sin(0.001 * r) / 3.0);
    exact = exact && trial.samples(r, 0) == r && trial.samples(r, 1) == std::strtod(cell, nullptr);
  }
  BOOST_CHECK(exact);
}

BOOST_AUTO_TEST_CASE(in_a_large_trial_the_first_bad_cell_in_the_file_is_reported) {
  // Two bad cells, one near the end and one near the start: whatever the chunking, the message
  // names the earlier one, with its true line number (the header is line 2 after a comment).
  std::string text = "# comment\n" + large_trial_text(60000);
  const auto replace_row = [&](int row, const std::string& with) {
    std::size_t pos = 0;
    for (int l = 0; l < row + 2; ++l) pos = text.find('\n', pos) + 1;  // start of data row `row`
    text.replace(pos, text.find('\n', pos) - pos, with);
  };
  replace_row(55000, "55,55,oops");
  replace_row(1234, "1.234,1234,x");
  expect_error(text, {"trial.csv:1237:3", "'x'"});
  std::string ragged = "# comment\n" + large_trial_text(60000);
  std::size_t pos = 0;
  for (int l = 0; l < 40000 + 2; ++l) pos = ragged.find('\n', pos) + 1;
  ragged.insert(ragged.find('\n', pos), ",9");
  expect_error(ragged, {"trial.csv:40003", "ragged", "4 cells, expected 3"});
}

BOOST_AUTO_TEST_CASE(blanks_around_cells_and_a_leading_plus_are_accepted) {
  const auto trial = d::parse_trial_csv("t , x\n 0 ,\t+1.5 \n0.5, -2e-3\r\n1,+.25\n", "p.csv");
  BOOST_CHECK_EQUAL(trial.samples(0, 0), 1.5);
  BOOST_CHECK_EQUAL(trial.samples(1, 0), -2e-3);
  BOOST_CHECK_EQUAL(trial.samples(2, 0), 0.25);
  expect_error("t,x\n0,1\n0.1,+-2\n", {"trial.csv:3:2", "'+-2'"});
  expect_error("t,x\n0,1\n0.1,+\n", {"trial.csv:3:2"});
  expect_error("t,x\n0,1\n0.1,1 2\n", {"trial.csv:3:2", "'1 2'"});
}

BOOST_AUTO_TEST_CASE(column_views_share_consecutive_channels_and_copy_the_others) {
  const auto trial = d::parse_trial_csv("t,a,b,c\n0,1,2,3\n1,4,5,6\n", "v.csv");
  const auto shared = trial.column_view({"b", "c"});
  BOOST_CHECK(shared.matrix().data() == trial.samples.col(1).data());  // no copy
  BOOST_CHECK(shared.matrix() == trial.columns({"b", "c"}));
  const auto reordered = trial.column_view({"c", "a"});
  BOOST_CHECK(reordered.matrix().data() != trial.samples.data());
  BOOST_CHECK(reordered.matrix() == trial.columns({"c", "a"}));
  BOOST_CHECK_THROW(trial.column_view({"a", "z"}), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(blank_and_comment_lines_inside_a_large_trial_are_skipped_in_every_chunk) {
  // Lines that are not rows, spread over the whole file (so over every parsing chunk): the rows
  // close up around them and the line numbers of later rows stay those of the file.
  const std::string plain = large_trial_text(60000);
  std::string text;
  std::size_t pos = 0;
  int data_line = 0;
  while (pos < plain.size()) {
    const std::size_t eol = plain.find('\n', pos) + 1;
    text.append(plain, pos, eol - pos);
    pos = eol;
    if (++data_line % 9000 == 0) text += (data_line % 2 == 0 ? "\n" : "# note\n");
  }
  const auto trial = d::parse_trial_csv(text, "gaps.csv");
  BOOST_REQUIRE_EQUAL(trial.sample_count(), 60000);
  bool rows_in_order = true;
  for (int r = 0; r < trial.sample_count(); ++r)
    rows_in_order = rows_in_order && trial.samples(r, 0) == r;
  BOOST_CHECK(rows_in_order);
  // Row 59990 is on line 59992 of the plain text, and 6 inserted lines come before it.
  std::string bad = text;
  const std::size_t at = bad.find("\n59.990000000000002,59990,") + 1;
  bad.replace(at, bad.find('\n', at) - at, "59.99,59990,?");
  expect_error(bad, {"trial.csv:59998:3"});
}
