#include <Eigen/Core>
#include <boost/test/unit_test.hpp>

#include "estimators/differences.hpp"

using stiffid::estimators::central_differences;

BOOST_AUTO_TEST_CASE(central_inside_one_sided_at_the_ends) {
  // x = t^2 (column 0) and 3 t + 1 (column 1) at t = 0, 0.5, ..., 2 s: central differences are
  // exact for a quadratic inside (2 t); the ends take the one-sided slopes (0.5 at t = 0, 3.5 at
  // t = 2); a line is exact everywhere.
  const double dt = 0.5;
  Eigen::MatrixXd x(5, 2);
  for (int i = 0; i < 5; ++i) {
    const double t = i * dt;
    x(i, 0) = t * t;
    x(i, 1) = 3.0 * t + 1.0;
  }
  const Eigen::MatrixXd d = central_differences(x, dt);
  const double expected[5] = {0.5, 1.0, 2.0, 3.0, 3.5};
  for (int i = 0; i < 5; ++i) {
    BOOST_CHECK_CLOSE(d(i, 0), expected[i], 1e-12);
    BOOST_CHECK_CLOSE(d(i, 1), 3.0, 1e-12);
  }
  // One sample: no slope to take.
  BOOST_CHECK_EQUAL(central_differences(Eigen::MatrixXd::Ones(1, 3), dt).norm(), 0.0);
}
