// SpectralProjection (estimators/spectral_projection.hpp) against Eigen's full symmetric
// eigendecomposition (an independent implementation): eigenvalues, squared projections, V y, and
// the pseudo-inverse solve it serves, on random, indefinite, clustered and rank-deficient
// matrices.

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <random>

#include "estimators/spectral_projection.hpp"

namespace est = stiffid::estimators;

namespace {

Eigen::MatrixXd random_matrix(int rows, int cols, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd m(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) m(i, j) = normal(rng);
  return m;
}

// Compares with Eigen on a symmetric a and right-hand sides b.
void check(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const std::string& what) {
  BOOST_TEST_CONTEXT(what) {
    const est::SpectralProjection sp(a, b);
    BOOST_REQUIRE(sp.status().ok);
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a);
    const double scale = eig.eigenvalues().cwiseAbs().maxCoeff();
    BOOST_TEST((sp.eigenvalues() - eig.eigenvalues()).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    // V (V^T b) = b: the recorded rotations and Q are orthogonal and consistent.
    BOOST_TEST((sp.apply(sp.projections()) - b).cwiseAbs().maxCoeff() <=
               1e-12 * b.cwiseAbs().maxCoeff() * std::sqrt(double(a.rows())));
    // Projections on well separated eigenvalues agree up to the eigenvector's sign.
    const Eigen::MatrixXd reference = eig.eigenvectors().transpose() * b;
    const Eigen::Index n = a.rows();
    for (Eigen::Index k = 0; k < n; ++k) {
      const double gap_below = k > 0 ? eig.eigenvalues()(k) - eig.eigenvalues()(k - 1) : scale;
      const double gap_above = k + 1 < n ? eig.eigenvalues()(k + 1) - eig.eigenvalues()(k) : scale;
      if (std::min(gap_below, gap_above) < 1e-6 * scale) continue;
      for (Eigen::Index j = 0; j < b.cols(); ++j) {
        BOOST_TEST(std::abs(std::abs(sp.projections()(k, j)) - std::abs(reference(k, j))) <=
                   1e-9 * b.col(j).norm());
      }
    }
    // Truncated pseudo-inverse on the largest half of the spectrum, both ways.
    Eigen::MatrixXd y = Eigen::MatrixXd::Zero(n, b.cols());
    Eigen::MatrixXd x_ref = Eigen::MatrixXd::Zero(n, b.cols());
    for (Eigen::Index k = n / 2; k < n; ++k) {
      if (std::abs(sp.eigenvalues()(k)) < 1e-8 * scale) continue;
      y.row(k) = sp.projections().row(k) / sp.eigenvalues()(k);
      x_ref += eig.eigenvectors().col(k) * (reference.row(k) / eig.eigenvalues()(k));
    }
    const Eigen::MatrixXd x = sp.apply(y);
    BOOST_TEST((x - x_ref).cwiseAbs().maxCoeff() <= 1e-8 * x_ref.cwiseAbs().maxCoeff());
  }
}

}  // namespace

BOOST_AUTO_TEST_CASE(random_symmetric_matrices_match_the_full_decomposition) {
  std::mt19937_64 rng(3);
  for (const int n : {1, 2, 3, 10, 57, 200}) {
    const Eigen::MatrixXd r = random_matrix(n, n, rng);
    check(0.5 * (r + r.transpose()), random_matrix(n, 2, rng),
          "indefinite n = " + std::to_string(n));
    check(r * r.transpose(), random_matrix(n, 3, rng),
          "positive definite n = " + std::to_string(n));
  }
}

BOOST_AUTO_TEST_CASE(clustered_and_rank_deficient_spectra) {
  std::mt19937_64 rng(5);
  const int n = 120;
  // Repeated eigenvalues: Q diag(1, 1, 1, 2, 2, ..., 0, 0) Q^T with a random orthogonal Q.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(random_matrix(n, n, rng));
  const Eigen::MatrixXd q = qr.householderQ();
  Eigen::VectorXd w(n);
  for (int k = 0; k < n; ++k) w(k) = k < 30 ? 0.0 : std::floor(k / 30.0);
  check(q * w.asDiagonal() * q.transpose(), random_matrix(n, 2, rng), "clustered, rank 90");
  // The IRF's case: the Toeplitz autocorrelation matrix of a low-pass signal (eigenvalues
  // spread over 16 decades) - rows of phi(|i - j|).
  Eigen::VectorXd x = random_matrix(4000, 1, rng);
  for (int pass = 0; pass < 4; ++pass)
    for (int i = 1; i < x.size(); ++i) x(i) = 0.9 * x(i - 1) + 0.1 * x(i);
  Eigen::MatrixXd t(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int lag = std::abs(i - j);
      t(i, j) = x.head(x.size() - lag).dot(x.tail(x.size() - lag)) / x.size();
    }
  check(t, random_matrix(n, 2, rng), "low-pass Toeplitz");
}

BOOST_AUTO_TEST_CASE(diagonal_and_already_tridiagonal_inputs) {
  Eigen::MatrixXd d = Eigen::VectorXd::LinSpaced(8, 8.0, 1.0).asDiagonal();
  Eigen::MatrixXd b = Eigen::MatrixXd::Identity(8, 1);
  check(d, b, "diagonal");
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(9, 9);
  for (int i = 0; i < 9; ++i) {
    t(i, i) = 2.0;
    if (i + 1 < 9) t(i, i + 1) = t(i + 1, i) = -1.0;  // eigenvalues 2 - 2 cos(k pi / 10)
  }
  const est::SpectralProjection sp(t, Eigen::MatrixXd::Ones(9, 1));
  for (int k = 0; k < 9; ++k) {
    BOOST_TEST(std::abs(sp.eigenvalues()(k) - (2.0 - 2.0 * std::cos((k + 1) * M_PI / 10.0))) <
               1e-14);
  }
}
