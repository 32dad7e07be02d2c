// Lumped-model fits (fitting/lumped_fit.hpp) against trials simulated independently with scipy
// solve_ivp (tests/data/fitting/make_fixtures.py, DOP853 at rtol 1e-12, FOH or ZOH forces).

#include <Eigen/Cholesky>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "fitting/lumped_fit.hpp"

namespace sf = stiffid::fitting;

namespace {

const std::string kDir = std::string(STIFFID_TEST_DATA_DIR) + "/fitting/";

nlohmann::json truth(const std::string& name) {
  std::ifstream in(kDir + "lumped_truth.json");
  return nlohmann::json::parse(in).at(name);
}

Eigen::MatrixXd to_matrix(const nlohmann::json& j) {
  Eigen::MatrixXd m(j.size(), j[0].size());
  for (std::size_t r = 0; r < j.size(); ++r) {
    for (std::size_t c = 0; c < j[r].size(); ++c) m(r, c) = j[r][c].get<double>();
  }
  return m;
}

struct Case {
  stiffid::data::Trial trial;
  nlohmann::json truth;
  std::vector<std::string> inputs, outputs;
  sf::LumpedModel model;
  sf::InputHold hold;
};

Case load(const std::string& name) {
  Case c{stiffid::data::read_trial_csv(kDir + name + ".csv"),
         truth(name),
         {},
         {},
         sf::parse_lumped_model(truth(name).at("model")),
         sf::parse_input_hold(truth(name).at("hold"))};
  const int dof = c.truth.at("dof");
  for (int j = 1; j <= dof; ++j) {
    c.inputs.push_back("f" + std::to_string(j));
    c.outputs.push_back("x" + std::to_string(j));
  }
  return c;
}

std::vector<Eigen::MatrixXd> true_matrices(const Case& c) {
  std::vector<Eigen::MatrixXd> out;
  for (const sf::MatrixParameter& m : sf::model_matrices(c.model)) {
    out.push_back(to_matrix(c.truth.at("parameters").at(m.name)));
  }
  return out;
}

// Largest entry error of every matrix relative to that matrix's largest entry.
double worst_relative_error(const sf::LumpedFitResult& r, const std::vector<Eigen::MatrixXd>& t) {
  double worst = 0.0;
  for (std::size_t m = 0; m < t.size(); ++m) {
    const double scale = t[m].cwiseAbs().maxCoeff();
    worst = std::max(worst, (r.parameters[m].value - t[m]).cwiseAbs().maxCoeff() / scale);
  }
  return worst;
}

void check_recovery(const std::string& name) {
  const Case c = load(name);
  sf::LumpedFitOptions o;
  o.model = c.model;
  o.hold = c.hold;
  o.starts = 2;
  o.seed = 7;
  const sf::LumpedFitResult r = sf::fit_lumped(c.trial, c.inputs, c.outputs, o);
  BOOST_TEST_INFO(name << ": " << r.termination);
  BOOST_TEST(r.status.ok);
  // Target of issue 8: 1e-4 relative from noise-free trials. What remains is the RK4 error at
  // h * rate <= 0.05 (checked below to be < 1e-6 of the signal) and the solver's tolerances.
  const double err = worst_relative_error(r, true_matrices(c));
  BOOST_TEST_MESSAGE(name << ": worst relative parameter error " << err << ", substeps "
                          << r.substeps << ", iterations " << r.iterations);
  BOOST_TEST(err < 1e-4);
  for (int j = 0; j < r.dof; ++j) BOOST_TEST(r.vaf_percent(j) > 99.9999);
}

}  // namespace

BOOST_AUTO_TEST_CASE(rk4_simulation_matches_scipy_to_well_below_the_recovery_target) {
  for (const std::string name : {"kv2", "pt2", "duffing2", "kv2_zoh"}) {
    const Case c = load(name);
    const Eigen::VectorXd theta = sf::matrices_to_theta(c.model, true_matrices(c));
    std::vector<double> z;
    for (const char* key : {"x0", "v0", "q0"}) {
      for (const auto& v : c.truth.at(key)) z.push_back(v.get<double>());
    }
    const Eigen::VectorXd z0 = Eigen::Map<Eigen::VectorXd>(z.data(), z.size());
    const Eigen::MatrixXd y = c.trial.columns(c.outputs);
    // 2 s at 200 Hz, fastest rate about 25 1/s: 4 substeps give h * rate ~ 0.03
    const Eigen::MatrixXd sim = sf::simulate_lumped(c.model, theta, z0, c.trial.columns(c.inputs),
                                                    c.trial.sample_rate_hz, c.hold, 4);
    const double rel = (sim - y).cwiseAbs().maxCoeff() / y.cwiseAbs().maxCoeff();
    BOOST_TEST_MESSAGE(name << ": RK4 (4 substeps) vs solve_ivp, max error / max |x| = " << rel);
    // RK4 global error ~ (h r)^4 r T / 120 ~ 1e-7 here; 1e-6 keeps it 100x below the 1e-4 target
    BOOST_TEST(rel < 1e-6);
  }
}

BOOST_AUTO_TEST_CASE(cholesky_parameterization_round_trips_spd_matrices) {
  Eigen::MatrixXd a(3, 3);
  a << 4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0;
  const Eigen::VectorXd theta = sf::spd_to_theta(a);
  const sf::SmallMatrix<double> back = sf::theta_to_matrix(theta.data(), {"K", "N/m", false}, 3);
  BOOST_TEST((Eigen::MatrixXd(back) - a).cwiseAbs().maxCoeff() < 1e-14);  // round-off of 3x3 LLT
  // any theta gives a symmetric positive definite matrix
  const Eigen::VectorXd any = (Eigen::VectorXd(6) << -3.0, 7.0, 2.0, -5.0, 0.3, -9.0).finished();
  const Eigen::MatrixXd m = sf::theta_to_matrix(any.data(), {"K", "N/m", false}, 3);
  BOOST_TEST((m - m.transpose()).norm() == 0.0);
  BOOST_TEST(m.llt().info() == Eigen::Success);
}

BOOST_AUTO_TEST_CASE(kelvin_voigt_recovered_to_1e_minus_4_for_1_and_2_dof) {
  check_recovery("kv1");
  check_recovery("kv2");
}

BOOST_AUTO_TEST_CASE(kelvin_voigt_with_zero_order_hold_inputs_recovered_to_1e_minus_4) {
  check_recovery("kv2_zoh");
}

BOOST_AUTO_TEST_CASE(poynting_thomson_recovered_to_1e_minus_4_for_1_and_2_dof) {
  check_recovery("pt1");
  check_recovery("pt2");
}

BOOST_AUTO_TEST_CASE(duffing_recovered_to_1e_minus_4_for_1_and_2_dof) {
  check_recovery("duffing1");
  check_recovery("duffing2");
}

BOOST_AUTO_TEST_CASE(multiple_shooting_gives_the_single_shooting_answer) {
  const Case c = load("kv2");
  sf::LumpedFitOptions o;
  o.starts = 1;
  o.segment_s = 0.5;  // 4 segments
  const sf::LumpedFitResult r = sf::fit_lumped(c.trial, c.inputs, c.outputs, o);
  BOOST_TEST(r.segments == 4);
  BOOST_TEST(r.status.ok);
  BOOST_TEST(worst_relative_error(r, true_matrices(c)) < 1e-4);
}

BOOST_AUTO_TEST_CASE(truth_within_3_standard_errors_in_90_percent_of_noisy_replicates) {
  // 1 DOF KV, first 1 s (201 samples), output noise at 20 dB SNR (noise RMS = signal RMS / 10),
  // 100 replicates from a seeded generator. A replicate covers when all of I, C, K are within 3
  // standard errors (per-parameter probability 0.997 if the errors are Gaussian and the standard
  // errors right; 0.99 jointly), so >= 90 of 100 fails only if the standard errors are too small.
  const Case c = load("kv1");
  const Eigen::MatrixXd u = c.trial.columns(c.inputs).topRows(201);
  const Eigen::MatrixXd y0 = c.trial.columns(c.outputs).topRows(201);
  const double sigma = std::sqrt(y0.squaredNorm() / y0.size()) / 10.0;
  const std::vector<Eigen::MatrixXd> t = true_matrices(c);
  std::mt19937_64 gen(20261123);
  std::normal_distribution<double> normal(0.0, sigma);
  int covered = 0;
  sf::LumpedFitOptions o;
  o.starts = 1;  // the box centre: one local solve per replicate keeps the test fast
  for (int rep = 0; rep < 100; ++rep) {
    Eigen::MatrixXd y = y0;
    for (Eigen::Index i = 0; i < y.rows(); ++i) y(i, 0) += normal(gen);
    const sf::LumpedFitResult r = sf::fit_lumped(u, y, c.trial.sample_rate_hz, o);
    bool ok = r.status.ok && r.standard_errors_ok;
    for (std::size_t m = 0; m < t.size(); ++m) {
      ok = ok && std::abs(r.parameters[m].value(0, 0) - t[m](0, 0)) <=
                     3.0 * r.parameters[m].std_error(0, 0);
    }
    covered += ok ? 1 : 0;
  }
  BOOST_TEST_MESSAGE("coverage of 3 standard errors: " << covered << " / 100");
  BOOST_TEST(covered >= 90);
}

BOOST_AUTO_TEST_CASE(same_seed_gives_identical_fits) {
  const Case c = load("pt1");
  sf::LumpedFitOptions o;
  o.model = sf::LumpedModel::poynting_thomson;
  o.starts = 3;
  o.seed = 42;
  const sf::LumpedFitResult a = sf::fit_lumped(c.trial, c.inputs, c.outputs, o);
  const sf::LumpedFitResult b = sf::fit_lumped(c.trial, c.inputs, c.outputs, o);
  BOOST_TEST((a.theta - b.theta).cwiseAbs().maxCoeff() == 0.0);
  BOOST_TEST(a.iterations == b.iterations);
}

BOOST_AUTO_TEST_CASE(non_converged_fit_is_reported_as_failed) {
  const Case c = load("kv2");
  sf::LumpedFitOptions o;
  o.starts = 1;
  o.max_iterations = 1;
  const sf::LumpedFitResult r = sf::fit_lumped(c.trial, c.inputs, c.outputs, o);
  BOOST_TEST(!r.status.ok);
  BOOST_TEST(r.termination.find("NO_CONVERGENCE") != std::string::npos);
  BOOST_TEST(sf::to_json(r).at("status") == false);
}

BOOST_AUTO_TEST_CASE(bad_input_throws_input_error) {
  BOOST_CHECK_THROW(sf::parse_lumped_model("maxwell"), stiffid::InputError);
  BOOST_CHECK_THROW(sf::parse_input_hold("cubic"), stiffid::InputError);
  const Case c = load("kv2");
  sf::LumpedFitOptions o;
  o.starts = 1;
  BOOST_CHECK_THROW(sf::fit_lumped(c.trial, {"f1", "f2"}, {"x1"}, o), stiffid::InputError);
  BOOST_CHECK_THROW(sf::fit_lumped(c.trial, {"f1"}, {"nope"}, o), stiffid::InputError);
  Eigen::MatrixXd u = c.trial.columns(c.inputs), y = c.trial.columns(c.outputs);
  y(10, 1) = std::nan("");
  BOOST_CHECK_THROW(sf::fit_lumped(u, y, 200.0, o), stiffid::InputError);
  y = c.trial.columns(c.outputs);
  u.col(0).setZero();
  BOOST_CHECK_THROW(sf::fit_lumped(u, y, 200.0, o), stiffid::InputError);
  sf::LumpedFitOptions bad = o;
  bad.ranges["KS"] = {1.0, 2.0};  // not a KV parameter
  BOOST_CHECK_THROW(sf::fit_lumped(c.trial, c.inputs, c.outputs, bad), stiffid::InputError);
  bad.ranges.clear();
  bad.ranges["K"] = {-1.0, 2.0};  // SPD box must be positive
  BOOST_CHECK_THROW(sf::fit_lumped(c.trial, c.inputs, c.outputs, bad), stiffid::InputError);
}
