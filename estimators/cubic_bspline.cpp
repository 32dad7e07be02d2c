#include "estimators/cubic_bspline.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {
namespace {

// Pieces of the cardinal cubic B-spline in local coordinate u in [0, 1): in span s the function
// B_{s+r} equals piece r.
double piece(int r, double u) {
  switch (r) {
    case 0:
      return (1 - u) * (1 - u) * (1 - u) / 6.0;
    case 1:
      return (3 * u * u * u - 6 * u * u + 4) / 6.0;
    case 2:
      return (-3 * u * u * u + 3 * u * u + 3 * u + 1) / 6.0;
    default:
      return u * u * u / 6.0;
  }
}
double piece_derivative(int r, double u) {  // d/du
  switch (r) {
    case 0:
      return -(1 - u) * (1 - u) / 2.0;
    case 1:
      return (3 * u * u - 4 * u) / 2.0;
    case 2:
      return (-3 * u * u + 2 * u + 1) / 2.0;
    default:
      return u * u / 2.0;
  }
}
double piece_second_derivative(int r, double u) {  // d^2/du^2
  switch (r) {
    case 0:
      return 1 - u;
    case 1:
      return 3 * u - 2;
    case 2:
      return -3 * u + 1;
    default:
      return u;
  }
}
double piece_integral(int r, double u) {  // int_0^u piece(r, v) dv
  const double u2 = u * u, u3 = u2 * u, u4 = u3 * u;
  switch (r) {
    case 0:
      return (1 - std::pow(1 - u, 4)) / 24.0;
    case 1:
      return (0.75 * u4 - 2 * u3 + 4 * u) / 6.0;
    case 2:
      return (-0.75 * u4 + u3 + 1.5 * u2 + u) / 6.0;
    default:
      return u4 / 24.0;
  }
}
constexpr double kPieceArea[4] = {1.0 / 24, 11.0 / 24, 11.0 / 24, 1.0 / 24};

}  // namespace

UniformCubicBspline::UniformCubicBspline(double length_s, double target_spacing_s) {
  if (!(length_s > 0.0) || !(target_spacing_s > 0.0) || !std::isfinite(length_s))
    throw InputError("cubic B-spline: length and knot spacing must be positive, got " +
                     number_text(length_s) + " s and " + number_text(target_spacing_s) + " s");
  spans_ = std::max(1, static_cast<int>(std::lround(length_s / target_spacing_s)));
  spacing_s_ = length_s / spans_;
}

void UniformCubicBspline::locate(double t_s, int& span, double& u) const {
  const double x = t_s / spacing_s_;
  span = std::clamp(static_cast<int>(std::floor(x)), 0, spans_ - 1);
  u = x - span;
}

Eigen::MatrixXd UniformCubicBspline::values(const Eigen::Ref<const Eigen::VectorXd>& t_s) const {
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(t_s.size(), size());
  for (Eigen::Index i = 0; i < t_s.size(); ++i) {
    int s;
    double u;
    locate(t_s(i), s, u);
    for (int r = 0; r < 4; ++r) b(i, s + r) = piece(r, u);
  }
  return b;
}

Eigen::MatrixXd UniformCubicBspline::first_derivatives(
    const Eigen::Ref<const Eigen::VectorXd>& t_s) const {
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(t_s.size(), size());
  for (Eigen::Index i = 0; i < t_s.size(); ++i) {
    int s;
    double u;
    locate(t_s(i), s, u);
    for (int r = 0; r < 4; ++r) b(i, s + r) = piece_derivative(r, u) / spacing_s_;
  }
  return b;
}

Eigen::MatrixXd UniformCubicBspline::second_derivatives(
    const Eigen::Ref<const Eigen::VectorXd>& t_s) const {
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(t_s.size(), size());
  const double scale = 1.0 / (spacing_s_ * spacing_s_);
  for (Eigen::Index i = 0; i < t_s.size(); ++i) {
    int s;
    double u;
    locate(t_s(i), s, u);
    for (int r = 0; r < 4; ++r) b(i, s + r) = piece_second_derivative(r, u) * scale;
  }
  return b;
}

Eigen::MatrixXd UniformCubicBspline::integrals(const Eigen::Ref<const Eigen::VectorXd>& t_s) const {
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(t_s.size(), size());
  for (Eigen::Index i = 0; i < t_s.size(); ++i) {
    int s;
    double u;
    locate(t_s(i), s, u);
    for (int m = 0; m < size(); ++m) {
      double area = 0.0;  // whole pieces of B_m in spans before s (basis m lives on m-3..m)
      for (int span = std::max(0, m - 3); span < std::min(s, m + 1); ++span)
        area += kPieceArea[m - span];
      if (m - s >= 0 && m - s <= 3) area += piece_integral(m - s, u);
      b(i, m) = area * spacing_s_;
    }
  }
  return b;
}

Eigen::MatrixXd UniformCubicBspline::second_differences() const {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(size() - 2, size());
  for (int m = 0; m + 2 < size(); ++m) d.row(m).segment(m, 3) << 1.0, -2.0, 1.0;
  return d;
}

Eigen::MatrixXd UniformCubicBspline::first_differences() const {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(size() - 1, size());
  for (int m = 0; m + 1 < size(); ++m) d.row(m).segment(m, 2) << -1.0, 1.0;
  return d;
}

}  // namespace stiffid::estimators
