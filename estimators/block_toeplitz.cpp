#include "estimators/block_toeplitz.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace stiffid::estimators {
namespace {

// The generators are row-major: every rotation runs along two contiguous rows.
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Rotates rows p and q of g over columns [from, from + len) so that g(q, from) becomes 0 (Givens).
void givens(RowMatrix& g, int p, int q, int from, int len) {
  double* const x = g.row(p).data() + from;
  double* const y = g.row(q).data() + from;
  const double a = x[0];
  const double b = y[0];
  if (b == 0.0) return;
  const double r = std::hypot(a, b);
  const double c = a / r;
  const double s = b / r;
  for (int j = 0; j < len; ++j) {
    const double xj = x[j];
    const double yj = y[j];
    x[j] = c * xj + s * yj;
    y[j] = c * yj - s * xj;
  }
  y[0] = 0.0;
}

}  // namespace

BlockToeplitzCholesky::BlockToeplitzCholesky(
    const Eigen::Ref<const Eigen::MatrixXd>& first_block_row) {
  const int blocks_n = static_cast<int>(first_block_row.rows());  // N
  const int n = static_cast<int>(first_block_row.cols());         // N L
  if (blocks_n < 1 || n < blocks_n || n % blocks_n != 0) return;
  const int lags = n / blocks_n;
  const Eigen::LLT<Eigen::MatrixXd> leading(first_block_row.leftCols(blocks_n));
  if (leading.info() != Eigen::Success) return;
  // G1 = U0^{-T} X, X the first block row; G2 = G1 without its first block.
  RowMatrix g1 = leading.matrixL().solve(first_block_row);
  RowMatrix g2 = g1;
  g2.leftCols(blocks_n).setZero();
  // Step k works on columns [k N, n). G1 moves one block to the right at every step (Z applied
  // to the generator of the Schur complement); instead of moving it, column j of the shifted G1
  // is kept in physical column j - k N: its active part is always physical [0, n - k N), and the
  // columns shifted out at the end are simply no longer read. G2 is not shifted.
  // U is stored transposed, L = U^T (column-major): block row k of U, the first N rows of G1 from
  // column k N on, goes to block column k of L as contiguous column segments. Only the lower
  // triangle of L is written (exact zeros above the diagonal inside its diagonal block); the
  // strictly upper part is never read.
  lower_.resize(n, n);
  for (int k = 0; k < lags; ++k) {
    const int col0 = k * blocks_n;
    if (k > 0) {
      for (int c = 0; c < blocks_n; ++c) {
        const int col = col0 + c;
        const int len = n - col;
        // G1 rows c+1.. and G2 rows 1.. are rotated into G1 row c and G2 row 0 (orthogonal within
        // each generator: G1^T G1 and G2^T G2 are unchanged); columns before `col` are zero in
        // every row involved.
        for (int r = c + 1; r < blocks_n; ++r) givens(g1, c, r, c, len);
        for (int r = 1; r < blocks_n; ++r) givens(g2, 0, r, col, len);
        double* const x = g1.row(c).data() + c;    // G1 row c from column `col`
        double* const y = g2.row(0).data() + col;  // G2 row 0 from column `col`
        const double a = x[0];
        const double b = y[0];
        // Positive definiteness of the Schur complement: |b| < |a|.
        if (!(std::abs(b) < std::abs(a))) return;
        const double rho = b / a;
        const double ch = 1.0 / std::sqrt((1.0 - rho) * (1.0 + rho));
        // Hyperbolic rotation [ch, -sh; -sh, ch], sh = rho ch, in the mixed form:
        // x' = ch (x - rho y), y' = y / ch - rho x'.
        for (int j = 0; j < len; ++j) {
          const double xj = ch * (x[j] - rho * y[j]);
          y[j] = y[j] / ch - rho * xj;
          x[j] = xj;
        }
        y[0] = 0.0;
        if (x[0] < 0.0) {  // positive diagonal
          for (int j = 0; j < len; ++j) x[j] = -x[j];
        }
      }
    }
    lower_.block(col0, col0, n - col0, blocks_n) = g1.leftCols(n - col0).transpose();
  }
  ok_ = true;
}

Eigen::MatrixXd BlockToeplitzCholesky::solve(const Eigen::Ref<const Eigen::MatrixXd>& b) const {
  // T = L L^T: L y = b, then L^T x = y.
  const auto l = lower_.triangularView<Eigen::Lower>();
  Eigen::MatrixXd x = l.solve(b);
  l.transpose().solveInPlace(x);
  return x;
}

Eigen::MatrixXd BlockToeplitzCholesky::rcond_start() const {
  // Hager's start x = 1/n and Higham's alternating vector.
  const int n = size();
  Eigen::MatrixXd start(n, 2);
  start.col(0).setConstant(1.0 / n);
  for (int i = 0; i < n; ++i) {
    start(i, 1) = (i % 2 == 0 ? 1.0 : -1.0) * (1.0 + i / (n - 1.0 + (n == 1)));
  }
  return start;
}

double BlockToeplitzCholesky::rcond(double l1_norm) const {
  if (!ok_ || !(l1_norm > 0.0)) return 0.0;
  return rcond(l1_norm, solve(rcond_start()));
}

double BlockToeplitzCholesky::rcond(double l1_norm,
                                    const Eigen::Ref<const Eigen::MatrixXd>& solved) const {
  if (!ok_ || !(l1_norm > 0.0)) return 0.0;
  // Hager (1984) / Higham (1988) estimate of ||T^{-1}||_1 for symmetric T: maximize
  // ||T^{-1} x||_1 over the unit 1-norm ball by a few steps of a subgradient ascent.
  const int n = size();
  Eigen::VectorXd x = Eigen::VectorXd::Constant(n, 1.0 / n);  // rcond_start().col(0)
  Eigen::VectorXd y = solved.col(0);
  double estimate = y.lpNorm<1>();
  int last = -1;
  for (int iteration = 0; iteration < 5; ++iteration) {
    const Eigen::VectorXd sign = y.unaryExpr([](double v) { return v >= 0.0 ? 1.0 : -1.0; });
    const Eigen::VectorXd z = solve(sign);  // T symmetric: T^{-T} = T^{-1}
    Eigen::Index j = 0;
    z.cwiseAbs().maxCoeff(&j);
    if (static_cast<int>(j) == last || z.cwiseAbs().maxCoeff() <= z.dot(x)) break;
    last = static_cast<int>(j);
    x = Eigen::VectorXd::Unit(n, j);
    y = solve(x);
    const double next = y.lpNorm<1>();
    if (next <= estimate) break;
    estimate = next;
  }
  // Higham's alternating vector guards against the few matrices that fool the iteration.
  estimate = std::max(estimate, 2.0 * solved.col(1).lpNorm<1>() / (3.0 * n));
  return estimate > 0.0 ? 1.0 / (l1_norm * estimate) : 0.0;
}

}  // namespace stiffid::estimators
