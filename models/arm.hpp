#pragma once
// Planar two-link arm in a horizontal plane (no gravity): shoulder at the origin, hand at the tip
// of link 2. Angles in rad: theta(0) = shoulder, from the x axis; theta(1) = elbow, relative to
// the upper arm. Piovesan et al. 2012 eqs 8-10 and Table 1; Perreault et al. 1999 eqs 14, 16.

#include <Eigen/Core>
#include <string>

namespace stiffid::models {

/// Inertial and geometrical parameters of the two links (Piovesan 2012 Table 1 by default).
struct ArmParameters {
  double l1_m = 0.29;         ///< upper arm length, m
  double r1_m = 0.132;        ///< shoulder to upper-arm centre of mass, m
  double m1_kg = 1.99;        ///< upper arm mass, kg
  double iz1_kg_m2 = 0.0161;  ///< upper arm moment of inertia about its centre of mass, kg m^2
  double l2_m = 0.4;          ///< forearm+hand length, m
  double r2_m = 0.17;         ///< elbow to forearm+hand centre of mass, m
  double m2_kg = 1.10;        ///< forearm+hand mass, kg
  double iz2_kg_m2 = 0.0146;  ///< forearm+hand moment of inertia about its centre of mass, kg m^2

  /// Throws InputError naming the first impossible value (non-positive length, mass or inertia,
  /// centre of mass outside its link).
  void validate() const;
};

/// Lumped inertial constants of eq 10: kappa, beta, chi in kg m^2.
struct InertiaConstants {
  double kappa = 0.0;  ///< Iz1 + Iz2 + m1 r1^2 + m2 (l1^2 + r2^2)
  double beta = 0.0;   ///< m2 l1 r2
  double chi = 0.0;    ///< Iz2 + m2 r2^2
};
InertiaConstants inertia_constants(const ArmParameters& arm);

/// Joint inertia matrix M(theta), kg m^2 (2x2, symmetric positive definite), eq 9.
Eigen::Matrix2d inertia_matrix(const ArmParameters& arm, const Eigen::Vector2d& theta_rad);
/// dM/dtheta_2 (M depends on the elbow angle only), kg m^2/rad.
Eigen::Matrix2d inertia_matrix_d_elbow(const ArmParameters& arm, const Eigen::Vector2d& theta_rad);
/// Coriolis/centripetal matrix H(theta, thetadot) of eq 9, kg m^2/s: torque = H thetadot.
Eigen::Matrix2d coriolis_matrix(const ArmParameters& arm, const Eigen::Vector2d& theta_rad,
                                const Eigen::Vector2d& theta_dot_rad_per_s);
/// Symmetric positive square root M^1/2 of an SPD matrix (eq 23), and its inverse M^-1/2.
Eigen::MatrixXd spd_sqrt(const Eigen::MatrixXd& m);
Eigen::MatrixXd spd_inverse_sqrt(const Eigen::MatrixXd& m);

/// Hand position (x, y) in m for joint angles theta (forward kinematics).
Eigen::Vector2d hand_position(const ArmParameters& arm, const Eigen::Vector2d& theta_rad);
/// Jacobian J = d(hand)/d(theta), m/rad (2x2): xdot = J thetadot.
Eigen::Matrix2d jacobian(const ArmParameters& arm, const Eigen::Vector2d& theta_rad);
/// Time derivative of the Jacobian, m/(rad s), for joint velocity thetadot.
Eigen::Matrix2d jacobian_dot(const ArmParameters& arm, const Eigen::Vector2d& theta_rad,
                             const Eigen::Vector2d& theta_dot_rad_per_s);
/// Partial derivative dJ/dtheta_i (i = 0 shoulder, 1 elbow), m/rad^2.
Eigen::Matrix2d jacobian_d_theta(const ArmParameters& arm, const Eigen::Vector2d& theta_rad, int i);
/// Inverse kinematics with the elbow flexed (theta_2 in (0, pi)), rad. Throws InputError when the
/// hand position is out of reach (distance from the shoulder outside [|l1 - l2|, l1 + l2]).
Eigen::Vector2d inverse_kinematics(const ArmParameters& arm, const Eigen::Vector2d& hand_m,
                                   const std::string& what = "hand position");

/// Endpoint stiffness (or damping) from joint stiffness at a posture, Perreault eq 16 without load:
/// K_x = J^-T K_theta J^-1. Units: (N m/rad) -> (N/m).
Eigen::Matrix2d joint_to_endpoint(const ArmParameters& arm, const Eigen::Vector2d& theta_rad,
                                  const Eigen::Matrix2d& k_joint);
/// Inverse transform: K_theta = J^T K_x J, (N/m) -> (N m/rad).
Eigen::Matrix2d endpoint_to_joint(const ArmParameters& arm, const Eigen::Vector2d& theta_rad,
                                  const Eigen::Matrix2d& k_endpoint);
/// Load (geometric) stiffness term of Piovesan eq 21 for an endpoint force f (N) held at the hand:
/// Omega = [dJ^T/dtheta_1 f, dJ^T/dtheta_2 f] (2x2, N m/rad), so that
/// K_theta = J^T K_x J + Omega  (sign convention: f is the force the hand applies to the robot).
Eigen::Matrix2d load_stiffness(const ArmParameters& arm, const Eigen::Vector2d& theta_rad,
                               const Eigen::Vector2d& hand_force_n);

}  // namespace stiffid::models
