// Classical mixed-model ANOVA with random factors against base-R aov() sums of squares with F
// denominators written out by hand from textbook EMS tables (tests/data/anova/make_fixtures.R).

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <functional>
#include <iomanip>
#include <map>
#include <set>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "tests/support/support.hpp"
#include "validation/anova.hpp"
#include "validation/anova_report.hpp"

namespace v = stiffid::validation;
namespace d = stiffid::data;

namespace {

const std::string kDir = std::string(STIFFID_TEST_DATA_DIR) + "/anova/";

// Same data in double precision on both sides; balanced sums of squares and Satterthwaite df
// agree to ~1e-13 relative, 1e-8 leaves a wide margin yet catches any wrong denominator.
constexpr double kRel = 1e-8;

bool close(double a, double b) {
  return std::fabs(a - b) <= kRel * std::max({std::fabs(a), std::fabs(b), 1e-300});
}

#define CHECK_REL(a, b, what)          \
  BOOST_CHECK_MESSAGE(close((a), (b)), \
                      what << ": got " << std::setprecision(17) << (a) << ", expected " << (b))

v::AnovaResult run(const std::string& name, const std::vector<std::string>& fixed,
                   const std::vector<std::string>& random, v::MixedModel model) {
  std::vector<std::string> factors = fixed;
  factors.insert(factors.end(), random.begin(), random.end());
  const auto t = v::long_table_from_csv(d::read_csv(kDir + name + ".csv"), "err", factors);
  v::MixedAnovaOptions o;
  o.fixed = fixed;
  o.random = random;
  o.model = model;
  return v::mixed_model_anova(t, o);
}

// The effect with the factors of `name` ("a:b:c"), in any order.
const v::AnovaEffect* find(const v::AnovaResult& r, const std::string& name) {
  std::multiset<std::string> want;
  for (size_t start = 0, colon = 0; colon != std::string::npos; start = colon + 1) {
    colon = name.find(':', start);
    want.insert(name.substr(start, colon == std::string::npos ? colon : colon - start));
  }
  for (const auto& e : r.effects) {
    if (std::multiset<std::string>(e.factors.begin(), e.factors.end()) == want) return &e;
  }
  return nullptr;
}

// Every fixture row of (dataset, model) whose R quasi-F denominator is positive must match.
// Returns the effects R found with a non-positive denominator (F <= 0 there).
std::vector<std::string> check(const std::string& dataset, const std::string& model,
                               const v::AnovaResult& r) {
  const d::CsvTable t = d::read_csv(kDir + "mixed_effects.csv");
  std::vector<std::string> negative;
  int rows = 0;
  for (int i = 0; i < t.row_count(); ++i) {
    if (t.cells[i][0] != dataset || t.cells[i][1] != model) continue;
    ++rows;
    std::map<std::string, std::string> row;
    for (int c = 0; c < t.column_count(); ++c) row[t.header[c]] = t.cells[i][c];
    const std::string at = dataset + " " + model + " " + row["effect"];
    const v::AnovaEffect* e = find(r, row["effect"]);
    BOOST_REQUIRE_MESSAGE(e, "missing " << at);
    BOOST_CHECK_EQUAL(v::to_string(e->type), row["type"]);
    CHECK_REL(e->ss, std::stod(row["ss"]), at << " SS");
    CHECK_REL(e->df1, std::stod(row["df1"]), at << " df1");
    if (std::stod(row["F"]) <= 0.0) {
      negative.push_back(row["effect"]);
      BOOST_CHECK_MESSAGE(!e->testable, at << " should be untestable");
      continue;
    }
    BOOST_CHECK_EQUAL(e->quasi, row["quasi"] == "true");
    CHECK_REL(e->df2, std::stod(row["df2"]), at << " df2");
    CHECK_REL(e->f, std::stod(row["F"]), at << " F");
    CHECK_REL(e->p, std::stod(row["p"]), at << " p");
  }
  BOOST_CHECK_EQUAL(static_cast<int>(r.effects.size()), rows);
  return negative;
}

using stiffid::test::expect_input_error;

v::LongTable table_from(const std::string& csv) {
  return v::long_table_from_csv(d::parse_csv(csv, "r.csv"), "err", {"a", "b"});
}

}  // namespace

BOOST_AUTO_TEST_CASE(restricted_model_matches_textbook_ems_denominators) {
  const auto r = run("random3", {"method"}, {"kprofile", "cprofile"}, v::MixedModel::restricted);
  BOOST_CHECK(r.status.ok);
  BOOST_CHECK(check("random3", "restricted", r).empty());
  const auto* method = find(r, "method");
  BOOST_CHECK_EQUAL(method->denominator,
                    "method:kprofile + method:cprofile - method:kprofile:cprofile");
  BOOST_CHECK_EQUAL(find(r, "kprofile")->denominator, "kprofile:cprofile");
  BOOST_CHECK_EQUAL(find(r, "kprofile:cprofile")->denominator, "residual");
  BOOST_CHECK_EQUAL(r.replicates, 2);
}

BOOST_AUTO_TEST_CASE(unrestricted_model_matches_and_flags_a_negative_quasi_denominator) {
  const auto r = run("random3", {"method"}, {"kprofile", "cprofile"}, v::MixedModel::unrestricted);
  const auto negative = check("random3", "unrestricted", r);
  // make_fixtures.R: MS_AC + MS_BC - MS_ABC < 0 for cprofile in this data set.
  BOOST_REQUIRE_EQUAL(negative.size(), 1u);
  BOOST_CHECK_EQUAL(negative[0], "cprofile");
  BOOST_CHECK(!r.status.ok);
  BOOST_CHECK(r.status.message.find("cprofile") != std::string::npos);
  BOOST_CHECK(r.status.message.find("not positive") != std::string::npos);
  BOOST_CHECK_EQUAL(find(r, "kprofile")->denominator,
                    "method:kprofile + kprofile:cprofile - method:kprofile:cprofile");
  const auto j = v::anova_to_json(r);
  BOOST_CHECK(j.dump().find("NaN") == std::string::npos);
  BOOST_CHECK(j.dump().find("null") == std::string::npos);
}

BOOST_AUTO_TEST_CASE(one_observation_per_cell_uses_highest_interaction_as_residual) {
  // Effect names follow the flag order (fixed, then random): "noise:kprofile" is R's
  // "kprofile:noise"; find() matches factor sets.
  const auto r = run("random_n1", {"method", "noise"}, {"kprofile"}, v::MixedModel::unrestricted);
  BOOST_CHECK(r.status.ok);
  BOOST_CHECK(check("random_n1", "unrestricted", r).empty());
  BOOST_CHECK(find(r, "method:kprofile:noise") == nullptr);
  BOOST_CHECK_EQUAL(find(r, "kprofile")->denominator,
                    "method:kprofile + noise:kprofile - residual");
  BOOST_CHECK_EQUAL(find(r, "noise")->denominator, "noise:kprofile");
  BOOST_REQUIRE(!r.notes.empty());
  BOOST_CHECK(r.notes[0].find("residual") != std::string::npos);
}

BOOST_AUTO_TEST_CASE(two_factor_mixed_model_gives_textbook_exact_tests) {
  // A fixed (2 levels), B random (3 levels), n = 2. Restricted: A / AB, B / residual;
  // unrestricted: A / AB, B / AB (Montgomery, Table 13.9 and eqs 13.20-13.21).
  std::string csv = "a,b,err\n";
  const double y[2][3][2] = {{{5, 6}, {7, 9}, {4, 4.5}}, {{8, 7}, {9.5, 12}, {6, 8}}};
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 2; ++k)
        csv += "a" + std::to_string(i) + ",b" + std::to_string(j) + "," +
               std::to_string(y[i][j][k]) + "\n";
  // Hand-computed sums of squares (cell, marginal and grand means of the 12 numbers above).
  double grand = 0, ma[2] = {0, 0}, mb[3] = {0, 0, 0}, cell[2][3] = {};
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 2; ++k) {
        grand += y[i][j][k] / 12;
        ma[i] += y[i][j][k] / 6;
        mb[j] += y[i][j][k] / 4;
        cell[i][j] += y[i][j][k] / 2;
      }
  double ss_a = 0, ss_b = 0, ss_ab = 0, ss_e = 0;
  for (int i = 0; i < 2; ++i) ss_a += 6 * std::pow(ma[i] - grand, 2);
  for (int j = 0; j < 3; ++j) ss_b += 4 * std::pow(mb[j] - grand, 2);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) {
      ss_ab += 2 * std::pow(cell[i][j] - ma[i] - mb[j] + grand, 2);
      for (int k = 0; k < 2; ++k) ss_e += std::pow(y[i][j][k] - cell[i][j], 2);
    }
  const double ms_a = ss_a, ms_b = ss_b / 2, ms_ab = ss_ab / 2, ms_e = ss_e / 6;
  v::MixedAnovaOptions o;
  o.fixed = {"a"};
  o.random = {"b"};
  for (const auto model : {v::MixedModel::restricted, v::MixedModel::unrestricted}) {
    o.model = model;
    const auto r = v::mixed_model_anova(table_from(csv), o);
    BOOST_REQUIRE(r.status.ok);
    CHECK_REL(find(r, "a")->f, ms_a / ms_ab, "F_A");
    BOOST_CHECK_EQUAL(find(r, "a")->df2, 2.0);
    CHECK_REL(find(r, "a:b")->f, ms_ab / ms_e, "F_AB");
    const bool restricted = model == v::MixedModel::restricted;
    CHECK_REL(find(r, "b")->f, restricted ? ms_b / ms_e : ms_b / ms_ab, "F_B");
    BOOST_CHECK_EQUAL(find(r, "b")->denominator, restricted ? "residual" : "a:b");
    BOOST_CHECK(!find(r, "b")->quasi);
  }
}

BOOST_AUTO_TEST_CASE(missing_cell_in_random_design_names_the_cell) {
  v::MixedAnovaOptions o;
  o.fixed = {"a"};
  o.random = {"b"};
  expect_input_error([&] { v::mixed_model_anova(table_from("a,b,err\nx,p,1\nx,q,2\ny,p,3\n"), o); },
                     {"r.csv", "a=y, b=q"});
}

BOOST_AUTO_TEST_CASE(unbalanced_random_design_is_an_input_error) {
  v::MixedAnovaOptions o;
  o.fixed = {"a"};
  o.random = {"b"};
  expect_input_error(
      [&] { v::mixed_model_anova(table_from("a,b,err\nx,p,1\nx,q,2\ny,p,3\ny,q,4\ny,q,5\n"), o); },
      {"unbalanced", "a=y, b=q", "r.csv:5"});
}

BOOST_AUTO_TEST_CASE(single_level_random_factor_is_an_input_error) {
  v::MixedAnovaOptions o;
  o.fixed = {"a"};
  o.random = {"b"};
  expect_input_error([&] { v::mixed_model_anova(table_from("a,b,err\nx,p,1\ny,p,2\n"), o); },
                     {"--random", "'b'", "1 level"});
}

BOOST_AUTO_TEST_CASE(zero_residual_variance_is_a_reported_failure) {
  v::MixedAnovaOptions o;
  o.fixed = {"a"};
  o.random = {"b"};
  // Replicates identical: the residual mean square is exactly zero.
  const auto r = v::mixed_model_anova(
      table_from("a,b,err\nx,p,1\nx,p,1\nx,q,2\nx,q,2\ny,p,3\ny,p,3\ny,q,5\ny,q,5\n"), o);
  BOOST_CHECK(!r.status.ok);
  BOOST_CHECK(r.status.message.find("a:b") != std::string::npos);
  BOOST_CHECK(v::anova_to_json(r).dump().find("NaN") == std::string::npos);
}
