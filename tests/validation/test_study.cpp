#include <unistd.h>

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "data/error.hpp"
#include "tests/support/support.hpp"
#include "validation/progress.hpp"
#include "validation/study.hpp"

namespace v = stiffid::validation;
namespace fs = std::filesystem;
using stiffid::test::read_text;
using stiffid::test::TempFolder;

namespace {

// Two designs, factors of three JSON types, 3 replicates: 2*3*3 + 2*3 = 24 cells.
const char* kSpec = R"({
  "name": "unit",
  "seed": 7,
  "replicates": 3,
  "designs": [
    {"name": "a", "evaluator": "synthetic",
     "factors": {"mean": [0, 10], "label": ["x", "y", "z"]},
     "template": {"mean": "${mean}", "sd": 2, "samples": 50}},
    {"name": "b", "evaluator": "synthetic",
     "factors": {"sd": [0.5, 1.5]},
     "template": {"sd": "${sd}", "samples": 20},
     "metrics": ["sample_sd"]}
  ]
})";

v::StudyResult run(const v::StudySpec& spec, const std::string& store, int threads,
                   bool resume = false) {
  v::StudyOptions options;
  options.store_path = store;
  options.threads = threads;
  options.resume = resume;
  return v::run_study(spec, options, v::builtin_evaluators());
}

std::string error_of(const std::string& text) {
  try {
    v::parse_study_spec(text, "s.json");
  } catch (const stiffid::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

BOOST_AUTO_TEST_CASE(cell_seeds_match_an_independent_implementation_of_the_documented_hash) {
  // tests/data/study/make_seeds.py computes FNV-1a + SplitMix64 in Python from the rule in
  // study_spec.hpp; equality is exact (integers).
  const auto cases = nlohmann::json::parse(read_text(STIFFID_TEST_DATA_DIR "/study/seeds.json"));
  BOOST_REQUIRE_EQUAL(cases.size(), 4u);
  for (const auto& c : cases) {
    const std::uint64_t seed =
        v::cell_seed(std::stoull(c.at("study_seed").get<std::string>()),
                     c.at("design").get<std::string>(), c.at("levels"), c.at("replicate"));
    BOOST_CHECK_EQUAL(std::to_string(seed), c.at("seed").get<std::string>());
  }
}

BOOST_AUTO_TEST_CASE(cells_enumerate_first_factor_slowest_then_replicates) {
  const v::StudySpec spec = v::parse_study_spec(kSpec, "unit.json");
  const auto cells = v::enumerate_cells(spec);
  BOOST_REQUIRE_EQUAL(cells.size(), 24u);
  BOOST_CHECK_EQUAL(cells[0].levels.dump(), R"({"label":"x","mean":0})");
  BOOST_CHECK_EQUAL(cells[2].replicate, 2);
  BOOST_CHECK_EQUAL(cells[3].levels.dump(), R"({"label":"y","mean":0})");
  BOOST_CHECK_EQUAL(cells[9].levels.dump(), R"({"label":"x","mean":10})");
  BOOST_CHECK_EQUAL(cells[18].design, 1);
  BOOST_CHECK_EQUAL(cells[23].index, 23);
  std::set<std::uint64_t> seeds;
  for (const auto& c : cells) seeds.insert(c.seed);
  BOOST_CHECK_EQUAL(seeds.size(), cells.size());  // distinct cells, distinct seeds
  BOOST_CHECK_EQUAL(spec.factor_names().size(), 3u);
}

BOOST_AUTO_TEST_CASE(templates_are_filled_with_typed_levels_and_text) {
  const auto spec = v::parse_study_spec(R"({"name": "t", "designs": [{"name": "d",
      "evaluator": "synthetic", "factors": {"k": [{"a": 1}], "s": ["hi"]},
      "template": {"whole": "${k}", "text": "k=${k} s=${s} r=${replicate}", "n": [1, "${s}"]}}]})",
                                        "t.json");
  const auto cells = v::enumerate_cells(spec);
  const nlohmann::json filled = v::fill_template(spec.designs[0], cells[0]);
  BOOST_CHECK_EQUAL(filled.at("whole").dump(), R"({"a":1})");
  BOOST_CHECK_EQUAL(filled.at("text").get<std::string>(), R"(k={"a":1} s=hi r=0)");
  BOOST_CHECK_EQUAL(filled.at("n").dump(), R"([1,"hi"])");
}

BOOST_AUTO_TEST_CASE(spec_errors_name_the_place) {
  BOOST_CHECK(error_of("{\"name\": \"x\",\n  \"seed\": }").find("s.json:2:") == 0);
  BOOST_CHECK(error_of(R"({"name": "x", "designz": []})").find("'designz'") != std::string::npos);
  BOOST_CHECK(error_of(R"({"name": "x", "seed": -1, "designs": [{"name": "d",
      "evaluator": "e"}]})")
                  .find("'seed'") != std::string::npos);
  BOOST_CHECK(error_of(R"({"name": "x", "designs": [{"name": "d", "evaluator": "e",
      "template": {"a": {"b": "${nope}"}}}]})")
                  .find("designs/0/template/a/b") != std::string::npos);
  BOOST_CHECK(error_of(R"({"name": "x", "designs": [{"name": "d", "evaluator": "e",
      "factors": {"f": []}}]})")
                  .find("designs/0/factors/f") != std::string::npos);
  BOOST_CHECK(error_of(R"({"name": "x", "designs": [{"name": "d", "evaluator": "e",
      "factors": {"f": [1, 1]}}]})")
                  .find("twice") != std::string::npos);
}

BOOST_AUTO_TEST_CASE(results_are_bit_identical_at_one_and_two_threads) {
  TempFolder folder("study");
  const v::StudySpec spec = v::parse_study_spec(kSpec, "unit.json");
  const auto one = run(spec, folder.file("one.sqlite"), 1);
  const auto two = run(spec, folder.file("two.sqlite"), 2);
  BOOST_CHECK(one.status.ok);
  BOOST_CHECK_EQUAL(one.cells_computed, 24);
  BOOST_CHECK_EQUAL(two.cells_computed, 24);
  v::export_tidy_csv(spec, folder.file("one.sqlite"), folder.file("one.csv"));
  v::export_tidy_csv(spec, folder.file("two.sqlite"), folder.file("two.csv"));
  const std::string csv = read_text(folder.file("one.csv"));
  BOOST_CHECK_EQUAL(csv, read_text(folder.file("two.csv")));
  // 18 cells x 3 metrics + 6 cells x 1 kept metric, plus the header.
  BOOST_CHECK_EQUAL(std::count(csv.begin(), csv.end(), '\n'), 18 * 3 + 6 + 1);
  BOOST_CHECK(csv.find("study,design,cell,replicate,seed,mean,label,sd,metric,value\n") == 0);
}

BOOST_AUTO_TEST_CASE(resume_computes_only_missing_cells_and_changes_nothing_stored) {
  TempFolder folder("study");
  const v::StudySpec spec = v::parse_study_spec(kSpec, "unit.json");
  run(spec, folder.file("full.sqlite"), 2);
  // A partial store: the same study with only design "a" run (its cells 0..17 have the same
  // identity and seeds), then resumed with the whole spec. Seeds do not depend on the spec hash, so
  // the partial store is written under the full spec's header by hand.
  const auto cells = v::enumerate_cells(spec);
  {
    v::ResultStore partial(folder.file("part.sqlite"), v::ResultStore::Mode::create,
                           {spec.name, spec.hash(), spec.to_json().dump(), "test"});
    for (int i : {0, 5, 17, 20}) {
      v::CellRecord r;
      r.cell = i;
      r.design = spec.designs[cells[i].design].name;
      r.levels_json = cells[i].levels.dump();
      r.replicate = cells[i].replicate;
      r.seed = cells[i].seed;
      r.started_utc = r.finished_utc = "then";
      const auto outcome = v::synthetic_evaluator(
          v::fill_template(spec.designs[cells[i].design], cells[i]), cells[i].seed);
      r.metrics = outcome.metrics;
      if (i == 20) r.metrics = {{"sample_sd", outcome.metrics.at("sample_sd")}};
      partial.write_cell(r);
    }
  }
  const auto resumed = run(spec, folder.file("part.sqlite"), 2, true);
  BOOST_CHECK_EQUAL(resumed.cells_resumed, 4);
  BOOST_CHECK_EQUAL(resumed.cells_computed, 20);
  v::export_tidy_csv(spec, folder.file("full.sqlite"), folder.file("full.csv"));
  v::export_tidy_csv(spec, folder.file("part.sqlite"), folder.file("part.csv"));
  BOOST_CHECK_EQUAL(read_text(folder.file("full.csv")), read_text(folder.file("part.csv")));
  // A changed spec does not resume into this store.
  v::StudySpec other = spec;
  other.replicates = 4;
  BOOST_CHECK_THROW(run(other, folder.file("part.sqlite"), 1, true), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(synthetic_replicates_estimate_the_known_mean_and_sd) {
  // 200 replicates of the mean of 50 draws N(10, 2^2): the mean of the sample means has SE
  // 2/sqrt(50*200) = 0.02, so |error| < 0.1 is a 5-sigma bound; the mean sample SD is within
  // a few percent of 2 (SE of one sample SD ~ 2/sqrt(98) = 0.2, over 200 replicates ~0.014; the
  // bias of the SD estimator at n = 50 is ~0.5 %), so |error| < 0.1 is again about 5 sigma.
  TempFolder folder("study");
  const auto spec = v::parse_study_spec(R"({"name": "stat", "seed": 3, "replicates": 200,
      "designs": [{"name": "d", "evaluator": "synthetic",
                   "template": {"mean": 10, "sd": 2, "samples": 50}}]})",
                                        "stat.json");
  run(spec, folder.file("s.sqlite"), 2);
  const v::ResultStore store(folder.file("s.sqlite"), v::ResultStore::Mode::read_only);
  const auto summary = v::summarize(store.rows());
  BOOST_REQUIRE_EQUAL(summary.size(), 3u);
  for (const auto& s : summary) {
    BOOST_CHECK_EQUAL(s.n, 200);
    if (s.metric == "sample_mean") BOOST_CHECK_SMALL(s.mean - 10.0, 0.1);
    if (s.metric == "sample_sd") BOOST_CHECK_SMALL(s.mean - 2.0, 0.1);
  }
}

BOOST_AUTO_TEST_CASE(summary_mean_and_sd_match_hand_values) {
  // Values 1, 2, 4 -> mean 7/3, sample SD sqrt(((4/3)^2 + (1/3)^2 + (5/3)^2) / 2) = sqrt(7/3).
  std::vector<v::ResultRow> rows;
  for (double x : {1.0, 2.0, 4.0}) rows.push_back({0, "d", "{\"f\":1}", 0, 0, "m", x});
  rows.push_back({9, "d", "{\"f\":2}", 0, 0, "m", std::nan("")});
  const auto summary = v::summarize(rows);
  BOOST_REQUIRE_EQUAL(summary.size(), 2u);
  BOOST_CHECK_CLOSE(summary[0].mean, 7.0 / 3.0, 1e-12);
  BOOST_CHECK_CLOSE(summary[0].sd, std::sqrt(7.0 / 3.0), 1e-12);
  BOOST_CHECK_EQUAL(summary[1].n, 0);
}

BOOST_AUTO_TEST_CASE(failed_cells_are_reported_and_bad_specs_stop_the_run) {
  TempFolder folder("study");
  const auto failing = v::parse_study_spec(R"({"name": "f", "designs": [{"name": "d",
      "evaluator": "synthetic", "factors": {"fail": [false, true]},
      "template": {"fail": "${fail}"}}]})",
                                           "f.json");
  const auto result = run(failing, folder.file("f.sqlite"), 2);
  BOOST_CHECK(!result.status.ok);
  BOOST_CHECK_EQUAL(result.cells_failed, 1);
  BOOST_CHECK(result.status.message.find("cell 1") != std::string::npos);

  const auto unknown_key = v::parse_study_spec(R"({"name": "u", "designs": [{"name": "d",
      "evaluator": "synthetic", "template": {"meen": 1}}]})",
                                               "u.json");
  BOOST_CHECK_THROW(run(unknown_key, folder.file("u.sqlite"), 1), stiffid::InputError);
  const auto unknown_metric = v::parse_study_spec(R"({"name": "m", "designs": [{"name": "d",
      "evaluator": "synthetic", "metrics": ["vaf"]}]})",
                                                  "m.json");
  BOOST_CHECK_THROW(run(unknown_metric, folder.file("m.sqlite"), 1), stiffid::InputError);
  const auto unknown_evaluator = v::parse_study_spec(R"({"name": "e", "designs": [{"name": "d",
      "evaluator": "nope"}]})",
                                                     "e.json");
  BOOST_CHECK_THROW(run(unknown_evaluator, folder.file("e.sqlite"), 1), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(progress_bar_text_shows_count_rate_and_eta) {
  // 10 of 40 done, 8 computed in 4 s: 2 cells/s, 30 left -> 15 s.
  BOOST_CHECK_EQUAL(v::ProgressBar::render("s", 10, 40, 8, 4.0, 8),
                    "s [==      ] 10/40 cells  2.0 cells/s  ETA 0:15");
  BOOST_CHECK_EQUAL(v::ProgressBar::render("s", 0, 40, 0, 0.0, 4),
                    "s [    ] 0/40 cells  - cells/s  ETA -");
}
