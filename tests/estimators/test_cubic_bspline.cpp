#include <Eigen/QR>
#include <boost/test/unit_test.hpp>
#include <cmath>

#include "data/error.hpp"
#include "estimators/cubic_bspline.hpp"

using stiffid::estimators::UniformCubicBspline;

BOOST_AUTO_TEST_CASE(basis_is_a_partition_of_unity_and_reproduces_linear_functions) {
  const UniformCubicBspline spline(2.37, 0.1);
  BOOST_CHECK_EQUAL(spline.spans(), 24);
  BOOST_CHECK_CLOSE(spline.spacing_s(), 2.37 / 24, 1e-12);
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(301, 0.0, 2.37);
  const Eigen::MatrixXd b = spline.values(t);
  // Sum of the basis is 1 and the Greville abscissae (m - 1) h reproduce t: exact up to round-off.
  Eigen::VectorXd greville(spline.size());
  for (int m = 0; m < spline.size(); ++m) greville(m) = (m - 1) * spline.spacing_s();
  BOOST_CHECK_SMALL((b.rowwise().sum().array() - 1.0).abs().maxCoeff(), 1e-14);
  BOOST_CHECK_SMALL((b * greville - t).cwiseAbs().maxCoeff(), 1e-13);
  // Its derivative is then 1 everywhere.
  BOOST_CHECK_SMALL(((spline.first_derivatives(t) * greville).array() - 1.0).abs().maxCoeff(),
                    1e-12);
}

BOOST_AUTO_TEST_CASE(running_integrals_match_quadrature_and_derivatives_match_differences) {
  const UniformCubicBspline spline(1.0, 0.23);  // 4 spans of 0.25 s
  // Composite Simpson on 4000 intervals of each (piecewise cubic) basis function: exact on each
  // span's cubic, knots fall on the grid, so the difference is round-off.
  const int steps = 4000;
  const Eigen::VectorXd grid = Eigen::VectorXd::LinSpaced(steps + 1, 0.0, 1.0);
  const Eigen::MatrixXd values = spline.values(grid);
  const Eigen::MatrixXd integrals = spline.integrals(grid);
  Eigen::RowVectorXd running = Eigen::RowVectorXd::Zero(spline.size());
  const double h = 1.0 / steps;
  for (int i = 0; i + 2 <= steps; i += 2) {
    running += h / 3.0 * (values.row(i) + 4.0 * values.row(i + 1) + values.row(i + 2));
    BOOST_CHECK_SMALL((integrals.row(i + 2) - running).cwiseAbs().maxCoeff(), 1e-12);
  }
  // Central differences of the values: error h^2/6 f''' <= (1e-4)^2 / 6 * 1/h_knot^3 ~ 1e-8.
  const double e = 1e-4;
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(37, 0.01, 0.99);
  const Eigen::MatrixXd numeric =
      (spline.values(t.array() + e) - spline.values(t.array() - e)) / (2.0 * e);
  BOOST_CHECK_SMALL((spline.first_derivatives(t) - numeric).cwiseAbs().maxCoeff(), 1e-6);
  // Second derivatives: central differences of the first derivatives (exact on each span's
  // quadratic pieces away from the knots; this grid keeps 2e-3 s from them).
  const Eigen::VectorXd off = (Eigen::VectorXd::LinSpaced(10, 0.0, 0.9).array() + 0.052).matrix();
  const Eigen::MatrixXd numeric2 =
      (spline.first_derivatives(off.array() + e) - spline.first_derivatives(off.array() - e)) /
      (2.0 * e);
  BOOST_CHECK_SMALL((spline.second_derivatives(off) - numeric2).cwiseAbs().maxCoeff(), 1e-6);
}

BOOST_AUTO_TEST_CASE(second_derivatives_of_a_represented_cubic_are_exact) {
  // The cubic p(t) = 2 - t + 3 t^2 - 4 t^3 lies in the span of the basis: coefficients from least
  // squares on its values, then p''(t) = 6 - 24 t exactly (to round-off), at knots too.
  const UniformCubicBspline spline(2.0, 0.25);
  const Eigen::VectorXd grid = Eigen::VectorXd::LinSpaced(81, 0.0, 2.0);
  const Eigen::VectorXd p =
      (2.0 - grid.array() + 3.0 * grid.array().square() - 4.0 * grid.array().cube()).matrix();
  const Eigen::VectorXd coef = spline.values(grid).colPivHouseholderQr().solve(p);
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(9, 0.0, 2.0);  // the knots
  const Eigen::VectorXd exact = (6.0 - 24.0 * t.array()).matrix();
  BOOST_CHECK_SMALL((spline.second_derivatives(t) * coef - exact).cwiseAbs().maxCoeff(), 1e-9);
}

BOOST_AUTO_TEST_CASE(difference_operators_vanish_on_constant_and_linear_coefficients) {
  const UniformCubicBspline spline(1.0, 0.1);
  const Eigen::VectorXd constant = Eigen::VectorXd::Constant(spline.size(), 3.0);
  const Eigen::VectorXd linear = Eigen::VectorXd::LinSpaced(spline.size(), -1.0, 2.0);
  BOOST_CHECK_SMALL((spline.first_differences() * constant).cwiseAbs().maxCoeff(), 1e-15);
  BOOST_CHECK_SMALL((spline.second_differences() * linear).cwiseAbs().maxCoeff(), 1e-14);
  BOOST_CHECK_THROW(UniformCubicBspline(0.0, 0.1), stiffid::InputError);
  BOOST_CHECK_THROW(UniformCubicBspline(1.0, -0.1), stiffid::InputError);
}
