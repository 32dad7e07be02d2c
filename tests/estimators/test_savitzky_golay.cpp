// Savitzky-Golay smoothing and derivatives against scipy.signal.savgol_coeffs / savgol_filter
// (mode="interp"); fixture and script in tests/data/tfa/ (make_savgol.py).
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/error.hpp"
#include "estimators/savitzky_golay.hpp"

namespace est = stiffid::estimators;

namespace {

nlohmann::json fixture() {
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/tfa/savgol.json");
  BOOST_REQUIRE(in);
  return nlohmann::json::parse(in);
}

Eigen::VectorXd vec(const nlohmann::json& a) {
  Eigen::VectorXd v(a.size());
  for (size_t i = 0; i < a.size(); ++i) v(i) = a[i].get<double>();
  return v;
}

}  // namespace

BOOST_AUTO_TEST_CASE(coefficients_match_scipy_savgol_coeffs) {
  const auto f = fixture();
  for (const auto& c : f["cases"]) {
    const int w = c["window"], p = c["order"];
    const double delta = c["delta"];
    for (int d = 0; d < 3; ++d) {
      const Eigen::VectorXd ref = vec(c["coeffs_d" + std::to_string(d)]);
      const Eigen::VectorXd got = est::savitzky_golay_coefficients(w, p, d, delta, w / 2);
      // Least-squares weights of size up to 1/delta^2 = 1.6e5: 1e-9 relative to the largest is
      // round-off of two different QR solutions, far below any modelling effect.
      BOOST_CHECK_SMALL((got - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff(), 1e-9);
    }
    const Eigen::VectorXd ref = vec(c["coeffs_pos2_d1"]);
    const Eigen::VectorXd got = est::savitzky_golay_coefficients(w, p, 1, delta, 2);
    BOOST_CHECK_SMALL((got - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff(), 1e-9);
  }
}

BOOST_AUTO_TEST_CASE(filter_and_derivatives_match_scipy_savgol_filter_interp_edges) {
  const auto f = fixture();
  const Eigen::VectorXd x = vec(f["x"]);
  const double fs = f["fs"];
  for (const auto& c : f["cases"]) {
    const int w = c["window"];
    est::SavitzkyGolayOptions o;
    o.window_s = (w - 1) / fs;
    o.polynomial_order = c["order"];
    const est::SavitzkyGolayResult r = est::savitzky_golay(x, fs, o);
    BOOST_CHECK_EQUAL(r.window_samples, w);
    const Eigen::MatrixXd* got[3] = {&r.value, &r.first_derivative, &r.second_derivative};
    for (int d = 0; d < 3; ++d) {
      const Eigen::VectorXd ref = vec(c["filter_d" + std::to_string(d)]);
      // Same round-off argument as above, relative to the series' largest value.
      BOOST_CHECK_SMALL((got[d]->col(0) - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff(),
                        1e-9);
    }
  }
}

BOOST_AUTO_TEST_CASE(cubic_is_reproduced_exactly_with_its_derivatives) {
  // A cubic lies in the span of an order-3 fit: value and derivatives are exact everywhere,
  // edges included (closed form).
  const double fs = 100.0;
  Eigen::VectorXd x(300);
  for (int i = 0; i < 300; ++i) {
    const double t = i / fs;
    x(i) = 1.0 - 2.0 * t + 0.5 * t * t - 0.1 * t * t * t;
  }
  const est::SavitzkyGolayResult r = est::savitzky_golay(x, fs, {0.25, 3});
  for (int i = 0; i < 300; ++i) {
    const double t = i / fs;
    BOOST_CHECK_SMALL(r.value(i, 0) - x(i), 1e-9);
    BOOST_CHECK_SMALL(r.first_derivative(i, 0) - (-2.0 + t - 0.3 * t * t), 1e-8);
    BOOST_CHECK_SMALL(r.second_derivative(i, 0) - (1.0 - 0.6 * t), 1e-6);
  }
}

BOOST_AUTO_TEST_CASE(too_short_input_or_bad_order_is_an_input_error) {
  const Eigen::VectorXd x = Eigen::VectorXd::Ones(10);
  BOOST_CHECK_THROW(est::savitzky_golay(x, 100.0, {0.25, 3}), stiffid::InputError);
  BOOST_CHECK_THROW(est::savitzky_golay(x, 100.0, {0.05, 7}), stiffid::InputError);
}
