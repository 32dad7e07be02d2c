#include "fitting/pchip.hpp"

#include <algorithm>
#include <cmath>

#include "data/error.hpp"

namespace stiffid::fitting {
namespace {

double sign(double v) { return (v > 0.0) - (v < 0.0); }

// Three-point end slope, shape preserving (scipy PchipInterpolator._edge_case).
double edge_slope(double h0, double h1, double d0, double d1) {
  double m = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
  if (sign(m) != sign(d0)) {
    m = 0.0;
  } else if (sign(d0) != sign(d1) && std::abs(m) > 3.0 * std::abs(d0)) {
    m = 3.0 * d0;
  }
  return m;
}

}  // namespace

Pchip::Pchip(const Eigen::VectorXd& x, const Eigen::MatrixXd& y) : x_(x), y_(y) {
  const Eigen::Index n = x.size();
  if (n < 1 || y.rows() != n) throw InputError("pchip: expected as many values as knots (>= 1)");
  if (!x.allFinite() || !y.allFinite()) throw InputError("pchip: knots and values must be finite");
  for (Eigen::Index i = 1; i < n; ++i) {
    if (!(x(i) > x(i - 1))) throw InputError("pchip: knots must be strictly increasing");
  }
  slopes_ = Eigen::MatrixXd::Zero(n, y.cols());
  if (n < 2) return;
  for (Eigen::Index c = 0; c < y.cols(); ++c) {
    Eigen::VectorXd h(n - 1), d(n - 1);
    for (Eigen::Index i = 0; i + 1 < n; ++i) {
      h(i) = x(i + 1) - x(i);
      d(i) = (y(i + 1, c) - y(i, c)) / h(i);
    }
    if (n == 2) {
      slopes_.col(c).setConstant(d(0));
      continue;
    }
    for (Eigen::Index k = 1; k + 1 < n; ++k) {
      if (sign(d(k - 1)) * sign(d(k)) <= 0.0) continue;  // extremum or flat: zero slope
      const double w1 = 2.0 * h(k) + h(k - 1), w2 = h(k) + 2.0 * h(k - 1);
      slopes_(k, c) = (w1 + w2) / (w1 / d(k - 1) + w2 / d(k));  // weighted harmonic mean
    }
    slopes_(0, c) = edge_slope(h(0), h(1), d(0), d(1));
    slopes_(n - 1, c) = edge_slope(h(n - 2), h(n - 3), d(n - 2), d(n - 3));
  }
}

Eigen::MatrixXd Pchip::operator()(const Eigen::VectorXd& t) const {
  const Eigen::Index n = x_.size();
  Eigen::MatrixXd out(t.size(), y_.cols());
  for (Eigen::Index i = 0; i < t.size(); ++i) {
    if (n == 1) {
      out.row(i) = y_.row(0);
      continue;
    }
    // interval k with x_k <= t < x_k+1, clamped to the end intervals for extrapolation
    const double* it = std::upper_bound(x_.data(), x_.data() + n, t(i));
    const Eigen::Index k = std::clamp<Eigen::Index>((it - x_.data()) - 1, 0, n - 2);
    const double h = x_(k + 1) - x_(k), s = (t(i) - x_(k)) / h;
    const double h00 = (1 + 2 * s) * (1 - s) * (1 - s), h10 = s * (1 - s) * (1 - s);
    const double h01 = s * s * (3 - 2 * s), h11 = s * s * (s - 1);
    out.row(i) = h00 * y_.row(k) + h10 * h * slopes_.row(k) + h01 * y_.row(k + 1) +
                 h11 * h * slopes_.row(k + 1);
  }
  return out;
}

}  // namespace stiffid::fitting
