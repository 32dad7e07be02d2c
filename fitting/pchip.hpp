#pragma once
// Monotone piecewise cubic Hermite interpolation (PCHIP; Fritsch & Carlson 1980, with the
// three-point end slopes of Moler's pchip, as scipy.interpolate.PchipInterpolator): between knots
// the interpolant is monotone wherever the data are, and it never overshoots a local extremum.
// Used for the regression time profiles (Piovesan et al. 2012, "Regressive Techniques").

#include <Eigen/Core>

namespace stiffid::fitting {

class Pchip {
 public:
  /// Knots x (N, strictly increasing, any unit) and values y (N x C): each column is interpolated.
  /// N = 1 gives a constant, N = 2 a straight line. Throws InputError when x is not strictly
  /// increasing or x and y differ in length or hold non-finite values.
  Pchip(const Eigen::VectorXd& x, const Eigen::MatrixXd& y);

  /// Values at t (T) -> (T x C); outside [x_0, x_N-1] the end cubics are extended.
  Eigen::MatrixXd operator()(const Eigen::VectorXd& t) const;
  /// Slopes at the knots (N x C), y units per x unit.
  const Eigen::MatrixXd& slopes() const { return slopes_; }

 private:
  Eigen::VectorXd x_;
  Eigen::MatrixXd y_;
  Eigen::MatrixXd slopes_;
};

}  // namespace stiffid::fitting
