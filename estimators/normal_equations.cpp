#include "estimators/normal_equations.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

namespace stiffid::estimators {

Eigen::MatrixXd normal_matrix(const Eigen::Ref<const RowMajorMatrix>& jacobian) {
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(jacobian.cols(), jacobian.cols());
  normal.selfadjointView<Eigen::Lower>().rankUpdate(jacobian.transpose());
  normal.triangularView<Eigen::StrictlyUpper>() = normal.transpose();
  return normal;
}

bool compress_least_squares(const Eigen::Ref<const RowMajorMatrix>& jacobian,
                            const Eigen::Ref<const Eigen::VectorXd>& residual,
                            CompressedLeastSquares& out) {
  const Eigen::Index p = jacobian.cols();
  if (!jacobian.allFinite() || !residual.allFinite()) return false;
  Eigen::MatrixXd normal = normal_matrix(jacobian);
  // S = diag(N_ii)^-1/2, a zero column left at 1.
  const Eigen::VectorXd scale =
      normal.diagonal().unaryExpr([](double v) { return v > 0.0 ? 1.0 / std::sqrt(v) : 1.0; });
  normal = scale.asDiagonal() * normal * scale.asDiagonal();
  // Its info() is not checked: it reports a singular matrix, whose pivots are cut below.
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
  // c = D^-1/2 L^-1 P S g with g = J^T residual.
  out.c = ldlt.transpositionsP() * (scale.asDiagonal() * (jacobian.transpose() * residual));
  ldlt.matrixL().solveInPlace(out.c);
  // Pivots at round-off level of the unit diagonal (p eps) are zero: a direction J^T J does not
  // resolve in double precision (diagonal pivoting puts them last).
  const double cut = static_cast<double>(p) * std::numeric_limits<double>::epsilon();
  const Eigen::VectorXd root =
      ldlt.vectorD().unaryExpr([cut](double d) { return d > cut ? std::sqrt(d) : 0.0; });
  for (Eigen::Index i = 0; i < p; ++i) out.c(i) = root(i) > 0.0 ? out.c(i) / root(i) : 0.0;
  // R^T = S^-1 P^T L D^1/2 (Eigen applies its transpositions from the left: N = P^T L D L^T P).
  Eigen::MatrixXd rt = Eigen::MatrixXd(ldlt.matrixL()) * root.asDiagonal();
  rt = ldlt.transpositionsP().transpose() * rt;
  out.r = (scale.cwiseInverse().asDiagonal() * rt).transpose();
  out.s = std::sqrt(std::max(0.0, residual.squaredNorm() - out.c.squaredNorm()));
  return out.r.allFinite() && out.c.allFinite() && std::isfinite(out.s);
}

}  // namespace stiffid::estimators
