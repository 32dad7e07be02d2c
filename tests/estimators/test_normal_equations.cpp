#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <random>

#include "estimators/normal_equations.hpp"

using stiffid::estimators::compress_least_squares;
using stiffid::estimators::CompressedLeastSquares;
using stiffid::estimators::RowMajorMatrix;

namespace {

// A tall Jacobian (seeded) with columns scaled from 1e-6 to 1e6, as the track coefficients of a
// modal fit differ in size, and a residual with a part outside J's range.
RowMajorMatrix scaled_jacobian(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  RowMajorMatrix j(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int k = 0; k < cols; ++k) j(i, k) = normal(rng);
  for (int k = 0; k < cols; ++k) j.col(k) *= std::pow(10.0, -6.0 + 12.0 * k / (cols - 1));
  return j;
}

Eigen::VectorXd random_vector(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v(i) = normal(rng);
  return v;
}

// The Levenberg-Marquardt step of |r + J d|^2 + lambda |diag(J^T J)^1/2 d|^2 (Ceres's Jacobi
// scaling) from a Householder QR of the stacked rows [J; sqrt(lambda) D]: computed without the
// normal equations, as the truth.
Eigen::VectorXd lm_step(const Eigen::MatrixXd& j, const Eigen::VectorXd& r, double lambda) {
  const Eigen::Index m = j.rows(), p = j.cols();
  Eigen::MatrixXd stacked = Eigen::MatrixXd::Zero(m + p, p);
  stacked.topRows(m) = j;
  stacked.bottomRows(p).diagonal() = (lambda * j.colwise().squaredNorm()).cwiseSqrt();
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(m + p);
  rhs.head(m) = -r;
  return stacked.colPivHouseholderQr().solve(rhs);
}

void check_compression(const RowMajorMatrix& j, const Eigen::VectorXd& r, double tolerance) {
  CompressedLeastSquares z;
  BOOST_REQUIRE(compress_least_squares(j, r, z));
  BOOST_REQUIRE_EQUAL(z.r.rows(), j.cols());
  BOOST_REQUIRE_EQUAL(z.r.cols(), j.cols());
  // Cost.
  BOOST_CHECK_CLOSE(z.c.squaredNorm() + z.s * z.s, r.squaredNorm(), 1e-9);
  // Gauss-Newton matrix and gradient, entrywise against each entry's own scale.
  const Eigen::MatrixXd n = j.transpose() * j, nz = z.r.transpose() * z.r;
  const Eigen::VectorXd g = j.transpose() * r, gz = z.r.transpose() * z.c;
  // Each column's size |J_k| (1 for a zero column, whose entries must then be 0).
  const Eigen::VectorXd size =
      n.diagonal().unaryExpr([](double v) { return v > 0.0 ? std::sqrt(v) : 1.0; });
  for (Eigen::Index a = 0; a < n.rows(); ++a) {
    for (Eigen::Index b = 0; b < n.cols(); ++b)
      BOOST_CHECK_SMALL(std::abs(nz(a, b) - n(a, b)) / (size(a) * size(b)), tolerance);
    BOOST_CHECK_SMALL(std::abs(gz(a) - g(a)) / (size(a) * r.norm()), tolerance);
  }
  // Levenberg-Marquardt steps at several damping levels: from p + 1 rows as from m.
  Eigen::MatrixXd jz = Eigen::MatrixXd::Zero(j.cols() + 1, j.cols());
  jz.topRows(j.cols()) = z.r;
  Eigen::VectorXd rz(j.cols() + 1);
  rz << z.c, z.s;
  for (const double lambda : {1e-6, 1e-2, 1.0}) {
    const Eigen::VectorXd d = lm_step(j, r, lambda), dz = lm_step(jz, rz, lambda);
    // Each coefficient relative to its own scale (|J_k| d_k is in the residual's units).
    BOOST_CHECK_SMALL((size.asDiagonal() * (dz - d)).norm() / r.norm(), 1e3 * tolerance);
  }
}

}  // namespace

BOOST_AUTO_TEST_CASE(a_tall_model_keeps_its_cost_gradient_and_steps) {
  const RowMajorMatrix j = scaled_jacobian(400, 12, 1);
  check_compression(j, random_vector(400, 2), 1e-12);
}

BOOST_AUTO_TEST_CASE(a_rank_deficient_model_keeps_its_cost_gradient_and_steps) {
  // A repeated column (two modes' coefficients that the data cannot tell apart) and a zero one
  // (a parameter the residuals do not depend on).
  RowMajorMatrix j = scaled_jacobian(300, 8, 3);
  j.col(5) = 2.0 * j.col(2);
  j.col(7).setZero();
  const Eigen::VectorXd r = random_vector(300, 4);
  check_compression(j, r, 1e-12);
  CompressedLeastSquares z;
  BOOST_REQUIRE(compress_least_squares(j, r, z));
  BOOST_CHECK_EQUAL(z.r.col(7).norm(), 0.0);
}

BOOST_AUTO_TEST_CASE(a_residual_in_the_range_leaves_nothing_outside) {
  // r = -J x exactly: the Gauss-Newton step removes it all; s is only round-off.
  const RowMajorMatrix j = scaled_jacobian(200, 6, 5);
  Eigen::VectorXd x(6);
  x << 1e6, -2e5, 3e3, 1.0, -5e-3, 7e-6;  // each column's contribution between 1 and ~200
  const Eigen::VectorXd r = -(j * x);
  CompressedLeastSquares z;
  BOOST_REQUIRE(compress_least_squares(j, r, z));
  BOOST_CHECK_SMALL(z.s / r.norm(), 1e-6);
  const Eigen::VectorXd step = z.r.colPivHouseholderQr().solve(-z.c);
  for (int k = 0; k < 6; ++k) BOOST_CHECK_CLOSE(step(k), x(k), 1e-6);
}

BOOST_AUTO_TEST_CASE(non_finite_entries_are_refused) {
  RowMajorMatrix j = scaled_jacobian(20, 3, 6);
  j(4, 1) = std::numeric_limits<double>::quiet_NaN();
  CompressedLeastSquares z;
  BOOST_CHECK(!compress_least_squares(j, random_vector(20, 7), z));
}
