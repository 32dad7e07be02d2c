#pragma once
// A tall linear least-squares model compressed to its normal equations, for solvers (Ceres) that
// only need the cost, the gradient and the Gauss-Newton matrix.

#include <Eigen/Core>

namespace stiffid::estimators {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// J^T J of `jacobian` (p x p, both triangles), from a symmetric rank update (half the products
/// of J^T * J); the jacobian's units squared.
Eigen::MatrixXd normal_matrix(const Eigen::Ref<const RowMajorMatrix>& jacobian);

/// The model |residual + jacobian d|^2 (m rows, p columns; any units) in p + 1 rows: the factor
/// `r` (p x p) and `c` (p), `s` with R^T R = J^T J, R^T c = J^T residual and |c|^2 + s^2 =
/// |residual|^2, so the cost, gradient and Gauss-Newton matrix (and every Levenberg-Marquardt
/// step) are those of the m rows. From the pivoted LDL^T of J^T J scaled to unit diagonal
/// (columns of very different sizes keep their own accuracy), R = D^1/2 L^T P S^-1. A direction
/// where J^T J is singular (D_i at or below p eps, round-off of the unit diagonal) gets a zero
/// row of R and c; s is 0 when round-off makes |c| exceed |residual|.
struct CompressedLeastSquares {
  RowMajorMatrix r;
  Eigen::VectorXd c;
  double s = 0.0;
};

/// False for non-finite entries in `jacobian` or `residual`.
bool compress_least_squares(const Eigen::Ref<const RowMajorMatrix>& jacobian,
                            const Eigen::Ref<const Eigen::VectorXd>& residual,
                            CompressedLeastSquares& out);

}  // namespace stiffid::estimators
