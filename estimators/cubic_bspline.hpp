#pragma once
// Uniform cubic B-spline basis on an interval, with values, derivatives and running integrals in
// closed form (de Boor 1978, ch. IX; uniform knots, so each basis function is the same cardinal
// cubic B-spline shifted). Used for the smooth tracks omega_j(t), alpha_j(t) and mode shapes of the
// damped-mode fit (damped_modes.hpp).

#include <Eigen/Core>

namespace stiffid::estimators {

/// Uniform cubic B-spline basis on [0, length_s]: `spans` equal spans of `spacing_s`, and
/// spans + 3 basis functions B_0..B_{spans+2} (the knots continue three spacings beyond each end,
/// so that every cubic polynomial on the interval is in the span of the basis). Basis m is non-zero
/// on spans m - 3 .. m. Times outside [0, length_s] use the first or last span's polynomial.
class UniformCubicBspline {
 public:
  /// spans = max(1, round(length_s / target_spacing_s)); spacing = length_s / spans.
  UniformCubicBspline(double length_s, double target_spacing_s);

  int size() const { return spans_ + 3; }                  ///< number of basis functions
  int spans() const { return spans_; }                     ///< number of knot spans
  double spacing_s() const { return spacing_s_; }          ///< knot spacing, s
  double length_s() const { return spacing_s_ * spans_; }  ///< interval length, s

  /// B_m(t_s): (T x size), dimensionless (partition of unity on the interval).
  Eigen::MatrixXd values(const Eigen::Ref<const Eigen::VectorXd>& t_s) const;
  /// d/dt B_m(t_s): (T x size), 1/s.
  Eigen::MatrixXd first_derivatives(const Eigen::Ref<const Eigen::VectorXd>& t_s) const;
  /// d^2/dt^2 B_m(t_s): (T x size), 1/s^2 (piecewise linear).
  Eigen::MatrixXd second_derivatives(const Eigen::Ref<const Eigen::VectorXd>& t_s) const;
  /// Running integrals int_0^t B_m(tau) dtau: (T x size), s.
  Eigen::MatrixXd integrals(const Eigen::Ref<const Eigen::VectorXd>& t_s) const;
  /// Second-difference operator on the coefficients ((size - 2) x size): rows c_{m-1} - 2 c_m +
  /// c_{m+1}, the roughness of the curve (h^2 times its second derivative at knot m).
  Eigen::MatrixXd second_differences() const;
  /// First-difference operator ((size - 1) x size): rows c_{m+1} - c_m.
  Eigen::MatrixXd first_differences() const;

 private:
  void locate(double t_s, int& span, double& u) const;
  int spans_;
  double spacing_s_;
};

}  // namespace stiffid::estimators
