#include "estimators/effective_parameters.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <vector>

namespace stiffid::estimators {

double effective_parameters(const Eigen::Ref<const Eigen::MatrixXd>& data_normal,
                            const Eigen::Ref<const Eigen::MatrixXd>& prior_normal) {
  assert(data_normal.rows() == data_normal.cols() && prior_normal.rows() == data_normal.rows() &&
         prior_normal.cols() == data_normal.cols());
  constexpr double relative_floor = 1e-10;
  const Eigen::Index p = data_normal.rows();
  // Symmetric scaling S N S with S = diag(N_ii^-1/2): tr((S N S)^+ S D S) = tr(N^-1 D) when N is
  // invertible, so the count does not depend on the parameters' units. Rows with a zero diagonal
  // (parameters neither the data nor the prior see) are left out.
  const Eigen::VectorXd diagonal = data_normal.diagonal() + prior_normal.diagonal();
  std::vector<Eigen::Index> kept;
  for (Eigen::Index i = 0; i < p; ++i) {
    if (diagonal(i) > 0.0) kept.push_back(i);
  }
  const auto m = static_cast<Eigen::Index>(kept.size());
  if (m == 0) return 0.0;
  Eigen::MatrixXd normal(m, m), prior(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const Eigen::Index i = kept[a];
    for (Eigen::Index b = 0; b <= a; ++b) {
      const Eigen::Index k = kept[b];
      const double scale = 1.0 / std::sqrt(diagonal(i) * diagonal(k));
      const double q = (i >= k ? prior_normal(i, k) : prior_normal(k, i)) * scale;
      const double d = (i >= k ? data_normal(i, k) : data_normal(k, i)) * scale;
      prior(a, b) = prior(b, a) = q;
      normal(a, b) = normal(b, a) = d + q;
    }
  }
  // tr(N^+ D) = tr(N^+ N) - tr(N^+ Q) = rank N - tr(N^+ Q).
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
  const Eigen::VectorXd pivots = ldlt.vectorD();
  if (ldlt.info() == Eigen::Success && pivots.minCoeff() > relative_floor * pivots.maxCoeff()) {
    return static_cast<double>(m) - ldlt.solve(prior).trace();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(normal);
  const Eigen::VectorXd& values = eigen.eigenvalues();
  const double top = values.maxCoeff();
  double trace = 0.0;
  for (Eigen::Index r = 0; r < m; ++r) {
    if (values(r) <= relative_floor * top) continue;
    const auto v = eigen.eigenvectors().col(r);
    trace += std::clamp(1.0 - v.dot(prior * v) / values(r), 0.0, 1.0);  // v^T D v / lambda_r
  }
  return trace;
}

}  // namespace stiffid::estimators
