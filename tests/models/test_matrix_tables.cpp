// Time tables of full stiffness and damping matrices (models/viscoelastic.hpp MatrixTable, spec
// keys stiffness_table / damping_table): the constant element as a table, the sigmoid profile as a
// table, the interpolated truth, a scipy fixture (tests/data/models/make_fixtures.py), the spec
// round trip and the errors that name the key.

#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "models/presets.hpp"
#include "models/simulate.hpp"
#include "models/spec.hpp"
#include "tests/support/support.hpp"

namespace m = stiffid::models;
using nlohmann::json;

namespace {

const std::string kData = std::string(STIFFID_TEST_DATA_DIR) + "/models/";

double max_abs(const Eigen::MatrixXd& a) { return a.cwiseAbs().maxCoeff(); }

m::SimulationResult run(const m::TrialSpec& spec) {
  std::mt19937_64 rng(1);
  m::SimulationResult r = m::simulate(spec, rng);
  BOOST_REQUIRE(r.status.ok);
  return r;
}

// Piovesan's posture with a 45 deg impulse at `onset_s`, 1 kHz, constant K0, C0.
m::TrialSpec posture(double duration_s, double onset_s) {
  m::TrialSpec spec;
  spec.duration_s = duration_s;
  spec.sample_rate_hz = 1000.0;
  spec.perturbations.pulses = {m::force_impulse(onset_s, M_PI / 4)};
  return spec;
}

m::MatrixTable constant_table(const std::vector<double>& times, const Eigen::MatrixXd& value) {
  return {times, std::vector<Eigen::MatrixXd>(times.size(), value)};
}

// K0 u2(t) (eq 54, start_s, horizon_s) sampled every h_s from start_s to horizon_s, with a knot
// one sample before start_s holding K0 (u = 1 before the start; the arm rests until the impulse at
// start_s, so the table's ramp between those two knots moves nothing).
m::MatrixTable sigmoid_table(const Eigen::MatrixXd& k0, double start_s, double horizon_s,
                             double h_s, double sample_s) {
  m::TimeProfile u{m::ProfileKind::sigmoid, start_s, horizon_s, {}, {}};
  m::MatrixTable table;
  table.time_s.push_back(start_s - sample_s);
  table.value.push_back(k0);
  const int knots = static_cast<int>(std::lround((horizon_s - start_s) / h_s));
  for (int k = 0; k <= knots; ++k) {
    const double t = start_s + k * h_s;
    table.time_s.push_back(t);
    table.value.push_back(k0 * u.value(t));
  }
  return table;
}

json posture_json() {
  return json::parse(R"({"model": "arm", "duration_s": 1, "sample_rate_hz": 100,
    "task": {"kind": "posture", "hand_m": [0.4, 0.0]},
    "viscoelasticity": {"kind": "kelvin_voigt",
      "stiffness_table": {"time_s": [0, 0.5, 1],
        "stiffness_nm_per_rad": [[[35, 5], [5, 20]], [[35, 5], [5, 60]], [[35, 5], [5, 100]]]},
      "damping_nms_per_rad": [[0.35, 0.05], [0.05, 0.2]]},
    "perturbations": [{"kind": "impulse", "onset_s": 0.5, "direction_deg": 90}]})");
}

using stiffid::test::mentions;

// The error message of parsing `spec`, or "" when it parses.
std::string error_of(const json& spec) {
  return stiffid::test::input_error_message([&] { m::parse_trial_spec(spec, "spec.json"); });
}

}  // namespace

BOOST_AUTO_TEST_CASE(one_knot_table_gives_the_constant_element_bit_for_bit) {
  const m::TrialSpec constant = posture(1.0, 0.2);
  m::TrialSpec table = constant;
  table.joint.stiffness_table = constant_table({0.4}, constant.joint.stiffness);
  table.joint.damping_table = constant_table({0.4}, constant.joint.damping);
  table.joint.stiffness.resize(0, 0);
  table.joint.damping.resize(0, 0);
  const m::SimulationResult a = run(constant), b = run(table);
  // One knot: no breakpoint, the same segments, and K d, C d' in place of 1.0 * (K0 d): the same
  // floating-point operations, so the same bits.
  BOOST_CHECK(a.trial.samples.cwiseEqual(b.trial.samples).all());
  BOOST_CHECK(a.truth.stiffness.cwiseEqual(b.truth.stiffness).all());
  BOOST_CHECK(a.truth.damping.cwiseEqual(b.truth.damping).all());
  BOOST_CHECK_EQUAL(a.steps, b.steps);

  // Several knots of the same matrix: the integrator restarts at each knot (8 more segments), so
  // the trials differ by the integration error only: local error per step <= 1e-10 rad absolute
  // (the default), over ~500 steps of a decaying response; 1e-9 rad bounds it.
  m::TrialSpec knots = table;
  knots.joint.stiffness_table =
      constant_table({0.1, 0.25, 0.3, 0.45, 0.6}, constant.joint.stiffness);
  knots.joint.damping_table = constant_table({0.15, 0.5, 0.77, 0.9}, constant.joint.damping);
  const m::SimulationResult c = run(knots);
  const Eigen::MatrixXd angles = a.trial.columns({"th1", "th2"});
  BOOST_TEST_MESSAGE("constant matrix table with knots: max |dtheta| = "
                     << max_abs(angles - c.trial.columns({"th1", "th2"})) << " rad");
  BOOST_CHECK_LT(max_abs(angles - c.trial.columns({"th1", "th2"})), 1e-9);
  BOOST_CHECK_LT(max_abs(a.truth.stiffness - c.truth.stiffness), 1e-13);
}

BOOST_AUTO_TEST_CASE(table_sampling_the_sigmoid_matches_the_sigmoid_profile_to_its_grid_error) {
  // Piovesan's 5 s posture trial, K = K0 u2(t) from 2.5 s, impulse at 2.5 s, 4 kHz.
  m::TrialSpec profile = m::piovesan_impulse_trial(m::TaskKind::posture, m::ProfileKind::sigmoid,
                                                   m::ProfileKind::constant, M_PI / 4);
  const double sample_s = 1.0 / profile.sample_rate_hz;
  const m::SimulationResult reference = run(profile);
  const Eigen::MatrixXd deviation = reference.trial.columns({"dth1", "dth2"});
  double error[2];
  const double grid_s[2] = {0.01, 0.005};
  for (int g = 0; g < 2; ++g) {
    m::TrialSpec table = profile;
    table.joint.stiffness_profile = m::TimeProfile{};
    table.joint.stiffness_table =
        sigmoid_table(profile.joint.stiffness, 2.5, 5.0, grid_s[g], sample_s);
    table.joint.stiffness.resize(0, 0);
    const m::SimulationResult r = run(table);
    error[g] = max_abs(r.trial.columns({"dth1", "dth2"}) - deviation) / max_abs(deviation);
    BOOST_TEST_MESSAGE("sigmoid as a " << 1e3 * grid_s[g] << " ms table: max |dtheta error| / "
                                       << "max |dtheta| = " << error[g]);
  }
  // Linear interpolation of u2 = 4 / (1 + exp(-4 (t - 3.75))) + 1 on a grid h errs by at most
  // h^2 / 8 max |u2''| = h^2 / 8 * 16 * 4 * 0.0962 = 7.7e-5 at h = 10 ms, i.e. 7.7e-5 relative
  // to u2 >= 1: K is at most 7.7e-5 K off. The error of the response solves M e'' + C e' + K e =
  // -dK d, a forcing at the response's own (resonant) frequency, so it grows until the damping
  // stops it: |e| / |d| <~ (|dK| / |K|) / (2 zeta), with zeta = C w / (2 K) ~ 0.07 here (C =
  // 0.01 K, w ~ 14 rad/s), i.e. <~ 7.7e-5 * 7 = 5.4e-4; 5e-4 is that bound (measured: 4.6e-5, as
  // |dK| / |K| is far below its worst over most of the trial). The integrator's error (1e-10 rad
  // on ~1e-2 rad responses, 1e-8 relative) is far below both grid errors, so halving the grid
  // must divide the error by ~4 (second-order convergence): between 3 and 5.
  BOOST_CHECK_LT(error[0], 5e-4);
  BOOST_CHECK_GT(error[0] / error[1], 3.0);
  BOOST_CHECK_LT(error[0] / error[1], 5.0);
}

BOOST_AUTO_TEST_CASE(truth_carries_the_interpolated_matrices_at_and_between_knots) {
  m::TrialSpec spec = posture(1.0, 0.3);
  const Eigen::Matrix2d k_a{{35.0, 5.0}, {5.0, 20.0}}, k_b{{30.0, -4.0}, {-4.0, 90.0}};
  const Eigen::Matrix2d c_a{{0.35, 0.05}, {0.05, 0.2}}, c_b{{0.5, 0.1}, {0.1, 0.9}};
  spec.joint.stiffness_table = {{0.25, 0.6}, {k_a, k_b}};
  spec.joint.damping_table = {{0.1, 0.3337}, {c_a, c_b}};  // the second knot between samples
  spec.joint.stiffness.resize(0, 0);
  spec.joint.damping.resize(0, 0);
  const m::SimulationResult r = run(spec);
  const json truth = m::truth_to_json(r);
  // Expected values computed here from the definition (linear in t, held outside the knots).
  auto expected = [](double t, double t0, double t1, const Eigen::Matrix2d& a,
                     const Eigen::Matrix2d& b) -> Eigen::Matrix2d {
    if (t <= t0) return a;
    if (t >= t1) return b;
    const double w = (t - t0) / (t1 - t0);
    return (1.0 - w) * a + w * b;
  };
  double worst_k = 0.0, worst_c = 0.0;
  for (int s = 0; s < r.trial.sample_count(); ++s) {
    const double t = r.truth.time_s(s);
    const Eigen::Matrix2d k = expected(t, 0.25, 0.6, k_a, k_b);
    const Eigen::Matrix2d c = expected(t, 0.1, 0.3337, c_a, c_b);
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        worst_k = std::max(
            worst_k, std::abs(truth["stiffness_nm_per_rad"][s][i][j].get<double>() - k(i, j)));
        worst_c = std::max(worst_c,
                           std::abs(truth["damping_nms_per_rad"][s][i][j].get<double>() - c(i, j)));
      }
    }
  }
  // Round-off of (1 - w) a + w b on entries <= 90: a few ulp.
  BOOST_CHECK_LT(worst_k, 1e-13);
  BOOST_CHECK_LT(worst_c, 1e-15);
  // At the knots (samples 250 and 600) and held outside: exactly the knot matrices.
  BOOST_CHECK(m::matrix_at(r.truth.stiffness, 250, 2) == Eigen::MatrixXd(k_a));
  BOOST_CHECK(m::matrix_at(r.truth.stiffness, 600, 2) == Eigen::MatrixXd(k_b));
  BOOST_CHECK(m::matrix_at(r.truth.stiffness, 0, 2) == Eigen::MatrixXd(k_a));
  BOOST_CHECK(m::matrix_at(r.truth.stiffness, 999, 2) == Eigen::MatrixXd(k_b));
  BOOST_CHECK(m::matrix_at(r.truth.damping, 100, 2) == Eigen::MatrixXd(c_a));
  // Halfway between the stiffness knots (sample 425): the mean of the two.
  BOOST_CHECK_LT(max_abs(m::matrix_at(r.truth.stiffness, 425, 2) - 0.5 * (k_a + k_b)), 1e-13);
  // A table has no profile: u = 1.
  BOOST_CHECK_EQUAL(r.truth.stiffness_profile.minCoeff(), 1.0);
  BOOST_CHECK_EQUAL(r.truth.stiffness_profile.maxCoeff(), 1.0);
}

BOOST_AUTO_TEST_CASE(rotating_stiffness_table_matches_scipy) {
  // The spec and the trial were both written by make_fixtures.py: K(t) = R(phi) K0 R(phi)^T with
  // phi 0 -> 30 deg (knots every 50 ms), C(t) with c22 rising 3 x (knots every 73.5 ms, off the
  // samples), solve_ivp DOP853 at rtol 1e-11 split at every knot.
  const m::TrialSpec spec = m::read_trial_spec(kData + "arm_posture_rotating_table.json");
  const stiffid::data::Trial ref =
      stiffid::data::read_trial_csv(kData + "arm_posture_rotating_table.csv");
  const m::SimulationResult r = run(spec);
  BOOST_REQUIRE_EQUAL(r.trial.sample_count(), ref.sample_count());
  const double diff = max_abs(r.trial.columns({"th1", "th2"}) - ref.columns({"th1", "th2"}));
  BOOST_TEST_MESSAGE("rotating table vs scipy: max |dtheta| = " << diff << " rad");
  // As the other scipy fixtures (test_simulate): both integrators at ~1e-11 relative tolerance
  // agree to ~1e-9 rad; 1e-6 rad (issue 4) fails only on a modelling difference (a mis-indexed
  // entry, the wrong piece at a knot: k22 10 % high at every knot gives 5e-3 rad here).
  BOOST_CHECK_LT(diff, 1e-6);
  BOOST_CHECK_LT(max_abs(r.trial.columns({"fx", "fy"}) - ref.columns({"fx", "fy"})), 1e-12);
}

BOOST_AUTO_TEST_CASE(tables_survive_the_spec_round_trip) {
  const m::TrialSpec spec = m::parse_trial_spec(posture_json(), "spec.json");
  BOOST_REQUIRE_EQUAL(spec.joint.stiffness_table.time_s.size(), 3u);
  BOOST_CHECK_EQUAL(spec.joint.stiffness.size(), 0);
  BOOST_CHECK_EQUAL(spec.joint.stiffness_table.value[2](1, 1), 100.0);
  const json once = m::trial_spec_to_json(spec);
  BOOST_CHECK(once["viscoelasticity"].contains("stiffness_table"));
  BOOST_CHECK(!once["viscoelasticity"].contains("stiffness_nm_per_rad"));
  BOOST_CHECK(!once["viscoelasticity"].contains("stiffness_profile"));
  const m::TrialSpec again = m::parse_trial_spec(once, "round trip");
  BOOST_CHECK(again.joint.stiffness_table.time_s == spec.joint.stiffness_table.time_s);
  for (std::size_t k = 0; k < 3; ++k) {
    BOOST_CHECK(again.joint.stiffness_table.value[k] == spec.joint.stiffness_table.value[k]);
  }
  BOOST_CHECK(again.joint.damping == spec.joint.damping);
  BOOST_CHECK_EQUAL(m::trial_spec_to_json(again).dump(), once.dump());
  // A damping table and an endpoint model (N/m, N s/m keys) too.
  json endpoint = json::parse(R"({"model": "endpoint", "duration_s": 1, "sample_rate_hz": 50,
    "endpoint": {"inertia_kg": [[1.2, 0.1], [0.1, 0.9]], "stiffness_n_per_m": [[250, 40], [40, 180]],
      "damping_table": {"time_s": [0.2, 0.7], "damping_ns_per_m": [[[10, 1], [1, 7]], [[10, 1], [1, 20]]]}},
    "perturbations": [{"kind": "random_force"}]})");
  const m::TrialSpec e = m::parse_trial_spec(endpoint, "endpoint.json");
  const json e_once = m::trial_spec_to_json(e);
  BOOST_CHECK(e_once["endpoint"]["damping_table"].contains("damping_ns_per_m"));
  BOOST_CHECK_EQUAL(m::trial_spec_to_json(m::parse_trial_spec(e_once, "rt")).dump(), e_once.dump());
  // Time-varying: the automatic method integrates it (no exact discretization).
  std::mt19937_64 rng(2);
  const m::SimulationResult r = m::simulate(e, rng);
  BOOST_CHECK(r.status.ok);
  BOOST_CHECK(r.integrator == m::IntegratorKind::adaptive);
  BOOST_CHECK_EQUAL(m::matrix_at(r.truth.damping, 49, 2)(1, 1), 20.0);
}

BOOST_AUTO_TEST_CASE(malformed_tables_are_errors_naming_the_key) {
  const std::string k = "spec.json: viscoelasticity.stiffness_table";
  json times = posture_json();
  times["viscoelasticity"]["stiffness_table"]["time_s"] = json::array({0.0, 0.5, 0.5});
  BOOST_CHECK(mentions(error_of(times), k + ".time_s[2]: expected strictly increasing"));
  json count = posture_json();
  count["viscoelasticity"]["stiffness_table"]["time_s"] = json::array({0.0, 0.5});
  BOOST_CHECK(mentions(error_of(count), k + ": a table needs as many times as values"));
  json shape = posture_json();
  shape["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"][1] =
      json::array({json::array({35, 5, 1}), json::array({5, 20, 1})});
  BOOST_CHECK(mentions(error_of(shape), k + ".stiffness_nm_per_rad[1][0]: expected 2 numbers"));
  json rows = posture_json();
  rows["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"][0] =
      json::array({json::array({35, 5})});
  BOOST_CHECK(mentions(error_of(rows), k + ".stiffness_nm_per_rad[0]: expected 2 rows"));
  json flat = posture_json();
  flat["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"] = json::array({35, 5});
  BOOST_CHECK(mentions(error_of(flat), k + ".stiffness_nm_per_rad[0]: expected a square matrix"));
  json finite = posture_json();
  finite["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"][1][0][1] =
      std::numeric_limits<double>::infinity();
  BOOST_CHECK(mentions(error_of(finite), k + ".stiffness_nm_per_rad[1][0][1]: expected a finite"));
  json time_finite = posture_json();
  time_finite["viscoelasticity"]["stiffness_table"]["time_s"][1] =
      std::numeric_limits<double>::infinity();
  BOOST_CHECK(mentions(error_of(time_finite), k + ".time_s[1]: expected a finite"));
  json spd = posture_json();
  spd["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"][2] =
      json::array({json::array({1, 5}), json::array({5, 1})});
  BOOST_CHECK(
      mentions(error_of(spd), k + ".stiffness_nm_per_rad[2]: expected a positive definite"));
  json unit = posture_json();
  unit["viscoelasticity"]["stiffness_table"]["stiffness_n_per_m"] =
      unit["viscoelasticity"]["stiffness_table"]["stiffness_nm_per_rad"];
  unit["viscoelasticity"]["stiffness_table"].erase("stiffness_nm_per_rad");
  BOOST_CHECK(mentions(error_of(unit), k + ".stiffness_n_per_m: wrong or unknown unit"));
  json missing = posture_json();
  missing["viscoelasticity"]["stiffness_table"].erase("time_s");
  BOOST_CHECK(mentions(error_of(missing), k + ".time_s: missing"));

  // Exclusive with the constant matrix, its profile, and (damping) the rotation.
  json both = posture_json();
  both["viscoelasticity"]["stiffness_nm_per_rad"] =
      json::array({json::array({35, 5}), json::array({5, 20})});
  BOOST_CHECK(
      mentions(error_of(both), k + ": give either stiffness_table or stiffness_nm_per_rad"));
  json profile = posture_json();
  profile["viscoelasticity"]["stiffness_profile"] = "sigmoid";
  BOOST_CHECK(mentions(error_of(profile), k + ": a table replaces stiffness_profile"));
  json rotation = posture_json();
  rotation["viscoelasticity"]["damping_table"] =
      json::parse(R"({"time_s": [0], "damping_nms_per_rad": [[[0.35, 0.05], [0.05, 0.2]]]})");
  rotation["viscoelasticity"].erase("damping_nms_per_rad");
  rotation["viscoelasticity"]["damping_rotation_deg"] = 30;
  BOOST_CHECK(mentions(error_of(rotation),
                       "viscoelasticity.damping_table: a table replaces damping_rotation_deg"));
  json damping_both = rotation;
  damping_both["viscoelasticity"].erase("damping_rotation_deg");
  damping_both["viscoelasticity"]["damping_nms_per_rad"] =
      json::array({json::array({1, 0}), json::array({0, 1})});
  BOOST_CHECK(
      mentions(error_of(damping_both),
               "viscoelasticity.damping_table: give either damping_table or damping_nms_per_rad"));
  json pt = posture_json();
  pt["viscoelasticity"]["kind"] = "poynting_thomson";
  pt["viscoelasticity"]["series_stiffness_nm_per_rad"] =
      json::array({json::array({350, 50}), json::array({50, 200})});
  BOOST_CHECK(mentions(error_of(pt), k + ": matrix tables are for kelvin_voigt and duffing"));
  json sdn = posture_json();
  sdn["noise"] = {{"signal_dependent", true}};
  BOOST_CHECK(mentions(error_of(sdn), "noise.signal_dependent"));
  // The same checks on a spec built in code (no parser): validate names the key.
  m::TrialSpec code = m::parse_trial_spec(posture_json(), "");
  code.joint.stiffness_table.value[1](0, 0) = std::numeric_limits<double>::quiet_NaN();
  stiffid::test::expect_input_error(
      [&] { code.validate(); },
      {"viscoelasticity.stiffness_table.stiffness_nm_per_rad[1]: expected finite"});
  // The Duffing linear part takes tables too.
  json duffing = posture_json();
  duffing["viscoelasticity"]["kind"] = "duffing";
  duffing["viscoelasticity"]["cubic_stiffness_nm_per_rad3"] =
      json::array({json::array({7e6, 1e6}), json::array({1e6, 4e6})});
  BOOST_CHECK_EQUAL(error_of(duffing), "");
}
