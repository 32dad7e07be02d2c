// PCHIP and the fitting-local Savitzky-Golay differentiator against scipy
// (tests/data/fitting/interpolation_ref.json, made by make_fixtures.py).

#include <boost/test/unit_test.hpp>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/error.hpp"
#include "estimators/savitzky_golay.hpp"
#include "fitting/pchip.hpp"

namespace sf = stiffid::fitting;

namespace {

nlohmann::json reference() {
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/fitting/interpolation_ref.json");
  return nlohmann::json::parse(in);
}

Eigen::VectorXd vec(const nlohmann::json& j) {
  Eigen::VectorXd v(j.size());
  for (std::size_t i = 0; i < j.size(); ++i) v(i) = j[i].get<double>();
  return v;
}

Eigen::MatrixXd mat(const nlohmann::json& j) {
  Eigen::MatrixXd m(j.size(), j[0].size());
  for (std::size_t i = 0; i < j.size(); ++i) m.row(i) = vec(j[i]).transpose();
  return m;
}

}  // namespace

BOOST_AUTO_TEST_CASE(pchip_matches_scipy_including_extrapolation) {
  const nlohmann::json ref = reference().at("pchip");
  const sf::Pchip p(vec(ref.at("x")), mat(ref.at("y")));
  const Eigen::MatrixXd got = p(vec(ref.at("t")));
  const Eigen::MatrixXd want = mat(ref.at("values"));
  // same formulas in double precision: differences are round-off on values of order 100
  BOOST_TEST((got - want).cwiseAbs().maxCoeff() < 1e-11);
}

BOOST_AUTO_TEST_CASE(pchip_is_monotone_on_monotone_data_and_exact_at_knots) {
  Eigen::VectorXd x(5), y(5);
  x << 0.0, 1.0, 1.5, 3.0, 4.0;
  y << 0.0, 0.1, 5.0, 5.1, 9.0;
  const sf::Pchip p(x, y);
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(401, 0.0, 4.0);
  const Eigen::VectorXd v = p(t);
  for (Eigen::Index i = 1; i < v.size(); ++i) BOOST_TEST(v(i) >= v(i - 1));
  BOOST_TEST((p(x) - y).cwiseAbs().maxCoeff() < 1e-15);
  // one knot: constant; two knots: straight line
  BOOST_TEST(sf::Pchip(x.head(1), y.head(1))(t)(7) == 0.0);
  BOOST_TEST(std::abs(sf::Pchip(x.head(2), y.head(2))(Eigen::VectorXd::Constant(1, 0.5))(0) -
                      0.05) < 1e-15);
}

BOOST_AUTO_TEST_CASE(pchip_rejects_unsorted_knots) {
  Eigen::VectorXd x(3), y(3);
  x << 0.0, 2.0, 1.0;
  y << 0.0, 1.0, 2.0;
  BOOST_CHECK_THROW(sf::Pchip(x, y), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(savitzky_golay_matches_scipy_interp_mode) {
  const nlohmann::json ref = reference().at("savgol");
  const Eigen::VectorXd x = vec(ref.at("x"));
  // The regressions differentiate with the estimators' Savitzky-Golay filter: check it on their
  // window and spacing.
  const double dt = ref.at("dt");
  const int window = ref.at("window");
  const auto r =
      stiffid::estimators::savitzky_golay(x, 1.0 / dt, {(window - 1) * dt, ref.at("order")});
  // least squares of an 11 x 5 Vandermonde: round-off ~1e-13 relative, scaled by 1/dt^k
  BOOST_TEST((r.value.col(0) - vec(ref.at("value"))).cwiseAbs().maxCoeff() < 1e-10);
  BOOST_TEST((r.first_derivative.col(0) - vec(ref.at("first"))).cwiseAbs().maxCoeff() < 1e-7);
  BOOST_TEST((r.second_derivative.col(0) - vec(ref.at("second"))).cwiseAbs().maxCoeff() < 1e-4);
  // order 6 on a 5-sample window has no least-squares polynomial
  BOOST_CHECK_THROW(stiffid::estimators::savitzky_golay(x, 1.0 / dt, {4 * dt, 6}),
                    stiffid::InputError);
}
