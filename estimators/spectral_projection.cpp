#include "estimators/spectral_projection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace stiffid::estimators {
namespace {

// c, s with [c s; -s c]^T [x; z] = [r; 0] (Golub & Van Loan algorithm 5.1.3).
void givens(double x, double z, double& c, double& s) {
  if (z == 0.0) {
    c = 1.0;
    s = 0.0;
  } else if (std::abs(z) > std::abs(x)) {
    const double tau = -x / z;
    s = 1.0 / std::sqrt(1.0 + tau * tau);
    c = s * tau;
  } else {
    const double tau = -z / x;
    c = 1.0 / std::sqrt(1.0 + tau * tau);
    s = c * tau;
  }
}

}  // namespace

SpectralProjection::SpectralProjection(const Eigen::Ref<const Eigen::MatrixXd>& a,
                                       const Eigen::Ref<const Eigen::MatrixXd>& b)
    : tridiagonal_(a) {
  const Eigen::Index n = a.rows();
  Eigen::VectorXd d = tridiagonal_.diagonal();                 // T[k][k]
  Eigen::VectorXd e = tridiagonal_.subDiagonal();              // T[k+1][k] = T[k][k+1]
  Eigen::MatrixXd p = tridiagonal_.matrixQ().transpose() * b;  // Z^T Q^T b as Z grows
  const double eps = std::numeric_limits<double>::epsilon();
  const long max_sweeps = 30 * static_cast<long>(std::max<Eigen::Index>(n, 1));
  long sweeps = 0;
  Eigen::Index end = n - 1;
  while (end > 0) {
    for (Eigen::Index i = 0; i < end; ++i) {  // deflate negligible off-diagonals
      if (std::abs(e(i)) <= eps * (std::abs(d(i)) + std::abs(d(i + 1)))) e(i) = 0.0;
    }
    while (end > 0 && e(end - 1) == 0.0) --end;
    if (end == 0) break;
    Eigen::Index start = end - 1;
    while (start > 0 && e(start - 1) != 0.0) --start;
    if (++sweeps > max_sweeps) {
      status_ = Status::failure("symmetric eigenvalues: the QR iteration did not converge");
      return;
    }
    // One implicit QR step with the Wilkinson shift on T[start..end] (algorithm 8.3.2): the
    // first rotation comes from the shift, the following ones chase the bulge T[k+1][k-1] down.
    const double delta = 0.5 * (d(end - 1) - d(end));
    const double f = e(end - 1);
    const double root = std::hypot(delta, f);
    const double mu = d(end) - f * f / (delta + (delta >= 0.0 ? root : -root));
    double x = d(start) - mu;
    double z = e(start);
    for (Eigen::Index k = start; k < end; ++k) {
      double c = 1.0, s = 0.0;
      givens(x, z, c, s);
      if (k > start) e(k - 1) = c * x - s * z;  // the bulge is annihilated
      // T <- G^T T G on rows and columns k, k + 1.
      const double dk = d(k), ek = e(k), dk1 = d(k + 1);
      d(k) = c * c * dk - 2.0 * c * s * ek + s * s * dk1;
      d(k + 1) = s * s * dk + 2.0 * c * s * ek + c * c * dk1;
      e(k) = c * s * (dk - dk1) + (c * c - s * s) * ek;
      if (k + 1 < end) {
        z = -s * e(k + 1);  // new bulge T[k+2][k]
        e(k + 1) *= c;
      }
      x = e(k);
      // Z <- Z G, so Z^T b <- G^T (Z^T b) on rows k, k + 1.
      for (Eigen::Index j = 0; j < p.cols(); ++j) {
        const double pk = p(k, j), pk1 = p(k + 1, j);
        p(k, j) = c * pk - s * pk1;
        p(k + 1, j) = s * pk + c * pk1;
      }
      rotations_.push_back({static_cast<int>(k), c, s});
    }
  }
  order_.resize(static_cast<std::size_t>(n));
  std::iota(order_.begin(), order_.end(), 0);
  std::stable_sort(order_.begin(), order_.end(), [&](int i, int j) { return d(i) < d(j); });
  eigenvalues_.resize(n);
  projections_.resize(n, b.cols());
  for (Eigen::Index k = 0; k < n; ++k) {
    eigenvalues_(k) = d(order_[k]);
    projections_.row(k) = p.row(order_[k]);
  }
  status_ = Status::success();
}

Eigen::MatrixXd SpectralProjection::apply(const Eigen::Ref<const Eigen::MatrixXd>& y) const {
  Eigen::MatrixXd z(y.rows(), y.cols());  // back to the QR order
  for (Eigen::Index k = 0; k < y.rows(); ++k) z.row(order_[k]) = y.row(k);
  // Z z = G_1 (G_2 (... (G_R z))): the rotations in reverse order, each G acting on rows k, k+1.
  for (auto r = rotations_.rbegin(); r != rotations_.rend(); ++r) {
    for (Eigen::Index j = 0; j < z.cols(); ++j) {
      const double zk = z(r->k, j), zk1 = z(r->k + 1, j);
      z(r->k, j) = r->c * zk + r->s * zk1;
      z(r->k + 1, j) = -r->s * zk + r->c * zk1;
    }
  }
  return tridiagonal_.matrixQ() * z;
}

}  // namespace stiffid::estimators
