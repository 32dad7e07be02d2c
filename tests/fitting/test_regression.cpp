// Classical regressions (fitting/regression.hpp) on a linear endpoint model with known M, B, K
// (tests/data/fitting/make_fixtures.py: exact force-pulse responses from solve_ivp and exact servo
// forces for minimum-jerk ramp-and-hold displacements; K and B scaled by 1.5 at the 3.0 s onset).

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "fitting/regression.hpp"

namespace sf = stiffid::fitting;

namespace {

const std::string kDir = std::string(STIFFID_TEST_DATA_DIR) + "/fitting/";

nlohmann::json truth() {
  std::ifstream in(kDir + "regress_truth.json");
  return nlohmann::json::parse(in);
}

Eigen::Matrix2d mat(const nlohmann::json& j) {
  Eigen::Matrix2d m;
  m << j[0][0].get<double>(), j[0][1].get<double>(), j[1][0].get<double>(), j[1][1].get<double>();
  return m;
}

std::vector<stiffid::data::Trial> trials(const std::string& kind, int directions = 8) {
  std::vector<stiffid::data::Trial> out;
  for (const char* onset : {"2.5", "3.0"}) {
    for (int d = 0; d < directions; ++d) {
      out.push_back(stiffid::data::read_trial_csv(kDir + kind + "_" + onset + "_d" +
                                                  std::to_string(d) + ".csv"));
    }
  }
  return out;
}

double relative(const Eigen::Matrix2d& got, const Eigen::Matrix2d& want) {
  return (got - want).cwiseAbs().maxCoeff() / want.cwiseAbs().maxCoeff();
}

// Independent Jacobian of the Table 1 arm (l1 = 0.29 m, l2 = 0.4 m), m/rad.
Eigen::Matrix2d jacobian(const Eigen::Vector2d& th) {
  const double l1 = 0.29, l2 = 0.4;
  Eigen::Matrix2d j;
  j << -l1 * std::sin(th(0)) - l2 * std::sin(th(0) + th(1)), -l2 * std::sin(th(0) + th(1)),
      l1 * std::cos(th(0)) + l2 * std::cos(th(0) + th(1)), l2 * std::cos(th(0) + th(1));
  return j;
}

void check(sf::RegressionMethod method, const std::string& kind) {
  const nlohmann::json t = truth();
  sf::RegressionOptions o;
  o.method = method;
  const sf::RegressionResult r = sf::regress(trials(kind), nullptr, o);
  BOOST_TEST_REQUIRE(r.estimates.size() == 2u);
  for (int g = 0; g < 2; ++g) {
    const sf::RegressionEstimate& e = r.estimates[g];
    const nlohmann::json& tg = t.at("groups")[g];
    // the pulse starts exactly at a sample; the minimum-jerk force starts at zero and is first
    // non-zero one sample (1 ms) later
    BOOST_TEST(std::abs(e.onset_s - tg.at("onset_s").get<double>()) <= 0.0011);
    BOOST_TEST(e.trials.size() == 8u);
    const double ek = relative(e.k_endpoint_n_per_m, mat(tg.at("K_n_per_m")));
    BOOST_TEST_MESSAGE(sf::regression_method_name(method) << " group " << g << ": K error " << ek);
    // issue 8: constant K (and M, B) of a linear endpoint model to 1 % without noise
    BOOST_TEST(ek < 0.01);
    if (method != sf::RegressionMethod::displacement_steady_state) {
      const double eb = relative(e.b_endpoint_ns_per_m, mat(tg.at("B_ns_per_m")));
      const double em = relative(e.m_endpoint_kg, mat(t.at("M_kg")));
      BOOST_TEST_MESSAGE("  B error " << eb << ", M error " << em);
      BOOST_TEST(eb < 0.01);
      BOOST_TEST(em < 0.01);
    }
    // joint stiffness at zero baseline force: J^T K_x J
    const Eigen::Matrix2d j = jacobian(e.theta_rad);
    BOOST_TEST(relative(e.k_joint_nm_per_rad, j.transpose() * e.k_endpoint_n_per_m * j) < 1e-12);
  }
  // the PCHIP profile starts and ends at the estimates, every 1/400 s
  const sf::RegressionProfile& p = r.profile;
  BOOST_TEST(std::abs(p.t_s(1) - p.t_s(0) - 1.0 / 400.0) < 1e-12);
  BOOST_TEST(std::abs(p.t_s(0) - r.estimates[0].time_s) < 1e-12);
  BOOST_TEST(relative(p.k_joint_nm_per_rad.front(), r.estimates[0].k_joint_nm_per_rad) < 1e-12);
  BOOST_TEST(relative(p.k_joint_nm_per_rad.back(), r.estimates[1].k_joint_nm_per_rad) < 1e-9);
}

}  // namespace

BOOST_AUTO_TEST_CASE(force_pulse_full_regression_recovers_m_b_k_to_1_percent) {
  check(sf::RegressionMethod::force_pulse, "pulse");
}

BOOST_AUTO_TEST_CASE(displacement_full_regression_recovers_m_b_k_to_1_percent) {
  check(sf::RegressionMethod::displacement_full, "ramp");
}

BOOST_AUTO_TEST_CASE(displacement_steady_state_regression_recovers_k_to_1_percent) {
  check(sf::RegressionMethod::displacement_steady_state, "ramp");
}

BOOST_AUTO_TEST_CASE(given_onset_and_baseline_trial_give_the_same_estimate) {
  std::vector<stiffid::data::Trial> all = trials("pulse");
  std::vector<stiffid::data::Trial> first(all.begin(), all.begin() + 8);
  sf::RegressionOptions o;
  o.onset_s = 2.5;
  // an unperturbed trial: the first trial before its onset, held
  stiffid::data::Trial base = first[0];
  for (Eigen::Index i = 0; i < base.samples.rows(); ++i)
    base.samples.row(i) = first[0].samples.row(0);
  const sf::RegressionResult a = sf::regress(first, nullptr, o);
  const sf::RegressionResult b = sf::regress(first, &base, o);
  BOOST_TEST(relative(a.estimates[0].k_endpoint_n_per_m, b.estimates[0].k_endpoint_n_per_m) <
             1e-12);
}

BOOST_AUTO_TEST_CASE(bad_input_gets_clear_errors) {
  BOOST_CHECK_THROW(sf::parse_regression_method("force"), stiffid::InputError);
  sf::RegressionOptions o;
  // fewer directions than unknowns: 4 directions for 6 unknowns per force component
  BOOST_CHECK_THROW(sf::regress(trials("pulse", 4), nullptr, o), stiffid::InputError);
  // singular regressors: on the plateau, 8 copies of one servo direction span a line, not the plane
  std::vector<stiffid::data::Trial> same(8, trials("ramp", 1)[0]);
  sf::RegressionOptions ss;
  ss.method = sf::RegressionMethod::displacement_steady_state;
  try {
    sf::regress(same, nullptr, ss);
    BOOST_FAIL("expected InputError");
  } catch (const stiffid::InputError& e) {
    BOOST_TEST(std::string(e.what()).find("singular") != std::string::npos);
  }
  // non-finite data
  std::vector<stiffid::data::Trial> bad = trials("pulse");
  bad[3].samples(300, 3) = std::nan("");
  BOOST_CHECK_THROW(sf::regress(bad, nullptr, o), stiffid::InputError);
  // no perturbation in the force
  std::vector<stiffid::data::Trial> flat = trials("pulse");
  flat[0].samples.col(flat[0].index("fx")).setZero();
  flat[0].samples.col(flat[0].index("fy")).setZero();
  BOOST_CHECK_THROW(sf::regress(flat, nullptr, o), stiffid::InputError);
}
