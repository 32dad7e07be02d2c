#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <random>

#include "estimators/effective_parameters.hpp"

namespace est = stiffid::estimators;

namespace {

// Random orthogonal matrix (QR of a Gaussian matrix), seeded.
Eigen::MatrixXd orthogonal(int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Eigen::MatrixXd a(n, n);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) a(i, k) = g(rng);
  return Eigen::HouseholderQR<Eigen::MatrixXd>(a).householderQ();
}

}  // namespace

BOOST_AUTO_TEST_SUITE(effective_parameters)

// Ridge regression: J_d = U diag(s) V^T, Q = lambda I: sum s_i^2 / (s_i^2 + lambda).
BOOST_AUTO_TEST_CASE(a_ridge_penalty_gives_the_closed_form_degrees_of_freedom) {
  const int p = 6;
  const Eigen::VectorXd s = (Eigen::VectorXd(p) << 10.0, 3.0, 1.0, 0.3, 0.1, 0.0).finished();
  const double lambda = 0.5;
  const Eigen::MatrixXd v = orthogonal(p, 11);
  const Eigen::MatrixXd jd = orthogonal(p, 12) * s.asDiagonal() * v.transpose();
  const Eigen::MatrixXd d = jd.transpose() * jd;
  const Eigen::MatrixXd q = lambda * Eigen::MatrixXd::Identity(p, p);
  double expected = 0.0;
  for (int i = 0; i < p; ++i) expected += s(i) * s(i) / (s(i) * s(i) + lambda);
  BOOST_CHECK_CLOSE(est::effective_parameters(d, q), expected, 1e-9);
  // No penalty: every determined parameter counts 1, the undetermined one 0 (rank 5).
  BOOST_CHECK_CLOSE(est::effective_parameters(d, Eigen::MatrixXd::Zero(p, p)), 5.0, 1e-6);
}

// Parameters on scales 1e-8 .. 1e8 (a rate in 1/s beside an amplitude in rad): the count does
// not depend on the units the parameters are in.
BOOST_AUTO_TEST_CASE(the_count_does_not_depend_on_the_parameters_units) {
  const int p = 5;
  const Eigen::VectorXd s = (Eigen::VectorXd(p) << 4.0, 2.0, 1.0, 0.5, 0.25).finished();
  const Eigen::MatrixXd jd = orthogonal(p, 21) * s.asDiagonal() * orthogonal(p, 22).transpose();
  const Eigen::MatrixXd jp = 0.7 * orthogonal(p, 23);  // prior rows, full rank
  const Eigen::VectorXd units = (Eigen::VectorXd(p) << 1e-8, 1e-4, 1.0, 1e4, 1e8).finished();
  const Eigen::MatrixXd d = jd.transpose() * jd, q = jp.transpose() * jp;
  const double plain = est::effective_parameters(d, q);
  const Eigen::MatrixXd scaled_d = units.asDiagonal() * d * units.asDiagonal();
  const Eigen::MatrixXd scaled_q = units.asDiagonal() * q * units.asDiagonal();
  BOOST_CHECK_CLOSE(est::effective_parameters(scaled_d, scaled_q), plain, 1e-8);
  // Q = 0.49 I (0.7 times an orthogonal matrix): the ridge closed form.
  double expected = 0.0;
  for (int i = 0; i < p; ++i) expected += s(i) * s(i) / (s(i) * s(i) + 0.49);
  BOOST_CHECK_CLOSE(plain, expected, 1e-9);
}

// What the LDLT of the whole normal matrix got wrong: directions neither the data nor the prior
// see (N singular) and near-collinear data columns. The count stays in [0, rank N].
BOOST_AUTO_TEST_CASE(directions_nobody_determines_count_zero_and_the_count_stays_bounded) {
  // Parameter 0 seen by the data, 1 by the prior only, 2 and 3 by the data only through their
  // sum (the same column twice), 4 by nobody: 1 + 0 + 1 + 0.
  Eigen::MatrixXd jd = Eigen::MatrixXd::Zero(2, 5);
  jd(0, 0) = 2.0;
  jd(1, 2) = 1.0;
  jd(1, 3) = 1.0;
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(5, 5);
  q(1, 1) = 3.0;
  BOOST_CHECK_CLOSE(est::effective_parameters(jd.transpose() * jd, q), 2.0, 1e-9);
  // A parameter the data see at 1e-9 of the others' scale and no prior does counts 1, as in
  // exact arithmetic (tr(N^-1 D) = 3 here): the scale is a matter of units, not of information.
  Eigen::MatrixXd jw = Eigen::MatrixXd::Zero(3, 4);
  jw(0, 0) = 2.0;
  jw(1, 1) = 1.0;
  jw(2, 2) = 1e-9;
  jw(2, 3) = -1e-9;
  Eigen::MatrixXd qw = Eigen::MatrixXd::Zero(4, 4);
  qw(2, 2) = 1.0;
  BOOST_CHECK_CLOSE(est::effective_parameters(jw.transpose() * jw, qw), 3.0, 1e-6);
  // Near-collinear columns (condition ~1e24): numerically one direction; in [1, 2], never the
  // 6e9 or -2e15 an LDLT gave.
  Eigen::MatrixXd jc(2, 2);
  jc << 1.0, 1.0, 1.0, 1.0 + 1e-12;
  const double collinear =
      est::effective_parameters(jc.transpose() * jc, Eigen::MatrixXd::Zero(2, 2));
  BOOST_CHECK_GE(collinear, 1.0 - 1e-9);
  BOOST_CHECK_LE(collinear, 2.0 + 1e-9);
  BOOST_CHECK_EQUAL(
      est::effective_parameters(Eigen::MatrixXd::Zero(3, 3), Eigen::MatrixXd::Zero(3, 3)), 0.0);
}

BOOST_AUTO_TEST_SUITE_END()
