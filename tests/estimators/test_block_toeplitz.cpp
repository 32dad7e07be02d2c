#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <boost/test/unit_test.hpp>
#include <random>

#include "estimators/block_toeplitz.hpp"

namespace est = stiffid::estimators;

namespace {

// T (lag-major) from its first block row [S_0 .. S_{L-1}]: block (a, b) = S_{b-a}, S_{-d} = S_d^T.
Eigen::MatrixXd dense(const Eigen::MatrixXd& row) {
  const int n_blk = static_cast<int>(row.rows());
  const int lags = static_cast<int>(row.cols()) / n_blk;
  Eigen::MatrixXd t(row.cols(), row.cols());
  for (int a = 0; a < lags; ++a) {
    for (int b = 0; b < lags; ++b) {
      const Eigen::MatrixXd s = row.middleCols(std::abs(b - a) * n_blk, n_blk);
      t.block(a * n_blk, b * n_blk, n_blk, n_blk) = b >= a ? s : Eigen::MatrixXd(s.transpose());
    }
  }
  return t;
}

// First block row of the biased correlation matrix of N coloured, coupled random channels:
// S_d(i, k) = phi_ik(-d) = (1/S) sum_t x_i(t + d) x_k(t): symmetric positive definite.
Eigen::MatrixXd correlation_row(int channels, int lags, double coupling, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int s = 4000;
  Eigen::MatrixXd x(s, channels);
  Eigen::VectorXd state = Eigen::VectorXd::Zero(channels);
  for (int t = 0; t < s; ++t) {
    for (int c = 0; c < channels; ++c) state(c) = 0.9 * state(c) + normal(rng);
    x.row(t) = state.transpose();
    for (int c = 1; c < channels; ++c) x(t, c) += coupling * x(t, 0);
  }
  Eigen::MatrixXd row(channels, channels * lags);
  for (int d = 0; d < lags; ++d) {
    for (int i = 0; i < channels; ++i) {
      for (int k = 0; k < channels; ++k) {
        double sum = 0.0;
        for (int t = 0; t + d < s; ++t) sum += x(t + d, i) * x(t, k);
        row(i, d * channels + k) = sum / s;
      }
    }
  }
  return row;
}

}  // namespace

BOOST_AUTO_TEST_CASE(factor_equals_the_dense_cholesky_factor) {
  for (const auto& [channels, lags] : {std::pair{1, 40}, std::pair{2, 35}, std::pair{3, 20}}) {
    const Eigen::MatrixXd row = correlation_row(channels, lags, 0.7, 5 + channels);
    const Eigen::MatrixXd t = dense(row);
    const est::BlockToeplitzCholesky schur(row);
    BOOST_REQUIRE(schur.ok());
    const Eigen::MatrixXd u = Eigen::LLT<Eigen::MatrixXd>(t).matrixU();
    BOOST_CHECK_SMALL((schur.upper() - u).cwiseAbs().maxCoeff() / u.cwiseAbs().maxCoeff(), 1e-12);
    Eigen::MatrixXd b = Eigen::MatrixXd::Random(t.rows(), 2);
    const Eigen::MatrixXd x = schur.solve(b);
    BOOST_CHECK_SMALL((t * x - b).cwiseAbs().maxCoeff(), 1e-10);
  }
}

BOOST_AUTO_TEST_CASE(reciprocal_condition_estimate_is_close_to_the_true_one) {
  const Eigen::MatrixXd row = correlation_row(2, 30, 0.9, 11);
  const Eigen::MatrixXd t = dense(row);
  const double norm1 = t.cwiseAbs().colwise().sum().maxCoeff();
  const double exact = 1.0 / (norm1 * t.inverse().cwiseAbs().colwise().sum().maxCoeff());
  const est::BlockToeplitzCholesky schur(row);
  BOOST_REQUIRE(schur.ok());
  const double estimate = schur.rcond(norm1);
  // Hager's estimate of ||T^-1||_1 is a lower bound, in practice within a small factor.
  BOOST_CHECK_GE(estimate, exact * (1 - 1e-12));
  BOOST_CHECK_LE(estimate, 3.0 * exact);
}

BOOST_AUTO_TEST_CASE(indefinite_and_singular_matrices_are_refused) {
  // S_1 larger than S_0: [[1, 2], [2, 1]] is indefinite.
  Eigen::MatrixXd scalar(1, 2);
  scalar << 1.0, 2.0;
  BOOST_CHECK(!est::BlockToeplitzCholesky(scalar).ok());
  // Two identical channels: every block is rank one, T is singular.
  Eigen::MatrixXd twins(2, 6);
  twins << 1.0, 1.0, 0.5, 0.5, 0.2, 0.2, 1.0, 1.0, 0.5, 0.5, 0.2, 0.2;
  const est::BlockToeplitzCholesky singular(twins);
  BOOST_CHECK(!singular.ok() ||
              singular.rcond(dense(twins).cwiseAbs().colwise().sum().maxCoeff()) < 1e-12);
}
