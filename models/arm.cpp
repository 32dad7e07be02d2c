#include "models/arm.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

#include "data/error.hpp"

namespace stiffid::models {

void ArmParameters::validate() const {
  const std::pair<const char*, double> positive[] = {
      {"l1_m", l1_m}, {"r1_m", r1_m}, {"m1_kg", m1_kg}, {"iz1_kg_m2", iz1_kg_m2},
      {"l2_m", l2_m}, {"r2_m", r2_m}, {"m2_kg", m2_kg}, {"iz2_kg_m2", iz2_kg_m2}};
  for (const auto& [key, value] : positive) {
    if (!(value > 0.0) || !std::isfinite(value)) {
      std::ostringstream msg;
      msg << "arm." << key << ": expected a positive finite value, got " << value;
      throw InputError(msg.str());
    }
  }
  if (r1_m > l1_m) throw InputError("arm.r1_m: centre of mass beyond the upper arm (r1_m > l1_m)");
  if (r2_m > l2_m) throw InputError("arm.r2_m: centre of mass beyond the forearm (r2_m > l2_m)");
}

InertiaConstants inertia_constants(const ArmParameters& a) {
  return {a.iz1_kg_m2 + a.iz2_kg_m2 + a.m1_kg * a.r1_m * a.r1_m +
              a.m2_kg * (a.l1_m * a.l1_m + a.r2_m * a.r2_m),
          a.m2_kg * a.l1_m * a.r2_m, a.iz2_kg_m2 + a.m2_kg * a.r2_m * a.r2_m};
}

Eigen::Matrix2d inertia_matrix(const ArmParameters& arm, const Eigen::Vector2d& theta) {
  const InertiaConstants k = inertia_constants(arm);
  const double c2 = std::cos(theta(1));
  Eigen::Matrix2d m;
  m << k.kappa + 2.0 * k.beta * c2, k.chi + k.beta * c2, k.chi + k.beta * c2, k.chi;
  return m;
}

Eigen::Matrix2d inertia_matrix_d_elbow(const ArmParameters& arm, const Eigen::Vector2d& theta) {
  const double bs2 = inertia_constants(arm).beta * std::sin(theta(1));
  Eigen::Matrix2d d;
  d << -2.0 * bs2, -bs2, -bs2, 0.0;
  return d;
}

Eigen::Matrix2d coriolis_matrix(const ArmParameters& arm, const Eigen::Vector2d& theta,
                                const Eigen::Vector2d& theta_dot) {
  const double bs2 = inertia_constants(arm).beta * std::sin(theta(1));
  Eigen::Matrix2d h;
  h << -bs2 * theta_dot(1), -bs2 * (theta_dot(0) + theta_dot(1)), bs2 * theta_dot(0), 0.0;
  return h;
}

Eigen::MatrixXd spd_sqrt(const Eigen::MatrixXd& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).operatorSqrt();
}

Eigen::MatrixXd spd_inverse_sqrt(const Eigen::MatrixXd& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).operatorInverseSqrt();
}

Eigen::Vector2d hand_position(const ArmParameters& arm, const Eigen::Vector2d& theta) {
  const double s12 = theta(0) + theta(1);
  return {arm.l1_m * std::cos(theta(0)) + arm.l2_m * std::cos(s12),
          arm.l1_m * std::sin(theta(0)) + arm.l2_m * std::sin(s12)};
}

Eigen::Matrix2d jacobian(const ArmParameters& arm, const Eigen::Vector2d& theta) {
  const double s1 = std::sin(theta(0)), c1 = std::cos(theta(0));
  const double s12 = std::sin(theta(0) + theta(1)), c12 = std::cos(theta(0) + theta(1));
  Eigen::Matrix2d j;
  j << -arm.l1_m * s1 - arm.l2_m * s12, -arm.l2_m * s12, arm.l1_m * c1 + arm.l2_m * c12,
      arm.l2_m * c12;
  return j;
}

Eigen::Matrix2d jacobian_d_theta(const ArmParameters& arm, const Eigen::Vector2d& theta, int i) {
  const double s1 = std::sin(theta(0)), c1 = std::cos(theta(0));
  const double s12 = std::sin(theta(0) + theta(1)), c12 = std::cos(theta(0) + theta(1));
  Eigen::Matrix2d d;
  if (i == 0) {
    d << -arm.l1_m * c1 - arm.l2_m * c12, -arm.l2_m * c12, -arm.l1_m * s1 - arm.l2_m * s12,
        -arm.l2_m * s12;
  } else {
    d << -arm.l2_m * c12, -arm.l2_m * c12, -arm.l2_m * s12, -arm.l2_m * s12;
  }
  return d;
}

Eigen::Matrix2d jacobian_dot(const ArmParameters& arm, const Eigen::Vector2d& theta,
                             const Eigen::Vector2d& theta_dot) {
  return jacobian_d_theta(arm, theta, 0) * theta_dot(0) +
         jacobian_d_theta(arm, theta, 1) * theta_dot(1);
}

Eigen::Vector2d inverse_kinematics(const ArmParameters& arm, const Eigen::Vector2d& hand,
                                   const std::string& what) {
  const double d2 = hand.squaredNorm();
  const double l1 = arm.l1_m, l2 = arm.l2_m;
  const double c2 = (d2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
  if (!(c2 > -1.0 && c2 < 1.0)) {
    std::ostringstream msg;
    msg << what << ": (" << hand(0) << ", " << hand(1) << ") m is out of reach: distance "
        << std::sqrt(d2) << " m from the shoulder, reachable range (" << std::abs(l1 - l2) << ", "
        << l1 + l2 << ") m";
    throw InputError(msg.str());
  }
  const double theta2 = std::acos(c2);
  const double theta1 =
      std::atan2(hand(1), hand(0)) - std::atan2(l2 * std::sin(theta2), l1 + l2 * std::cos(theta2));
  return {theta1, theta2};
}

Eigen::Matrix2d joint_to_endpoint(const ArmParameters& arm, const Eigen::Vector2d& theta,
                                  const Eigen::Matrix2d& k_joint) {
  const Eigen::Matrix2d j_inv = jacobian(arm, theta).inverse();
  return j_inv.transpose() * k_joint * j_inv;
}

Eigen::Matrix2d endpoint_to_joint(const ArmParameters& arm, const Eigen::Vector2d& theta,
                                  const Eigen::Matrix2d& k_endpoint) {
  const Eigen::Matrix2d j = jacobian(arm, theta);
  return j.transpose() * k_endpoint * j;
}

Eigen::Matrix2d load_stiffness(const ArmParameters& arm, const Eigen::Vector2d& theta,
                               const Eigen::Vector2d& hand_force_n) {
  Eigen::Matrix2d omega;
  for (int i = 0; i < 2; ++i)
    omega.col(i) = jacobian_d_theta(arm, theta, i).transpose() * hand_force_n;
  return omega;
}

}  // namespace stiffid::models
