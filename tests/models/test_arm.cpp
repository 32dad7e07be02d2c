#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <cmath>

#include "data/error.hpp"
#include "models/arm.hpp"

using stiffid::models::ArmParameters;
namespace m = stiffid::models;

// Finite-difference step and tolerance: central differences have O(h^2) truncation error
// (~1e-10 relative at h = 1e-5) plus round-off ~1e-16/h = 1e-11; 1e-7 is a safe bound.
constexpr double kStep = 1e-5;
constexpr double kFdTolerance = 1e-7;

BOOST_AUTO_TEST_CASE(inertia_matrix_matches_eq10_by_hand_for_table1) {
  // Table 1 values put into eq 10 with a calculator:
  // kappa = 0.0161 + 0.0146 + 1.99*0.132^2 + 1.10*(0.29^2 + 0.17^2) = 0.18967376
  // beta = 1.10*0.29*0.17 = 0.05423, chi = 0.0146 + 1.10*0.17^2 = 0.04639
  const auto k = m::inertia_constants(ArmParameters{});
  BOOST_CHECK_CLOSE(k.kappa, 0.18967376, 1e-9);
  BOOST_CHECK_CLOSE(k.beta, 0.05423, 1e-9);
  BOOST_CHECK_CLOSE(k.chi, 0.04639, 1e-9);
  const Eigen::Matrix2d mm = m::inertia_matrix(ArmParameters{}, {0.3, M_PI / 2});
  BOOST_CHECK_CLOSE(mm(0, 0), 0.18967376, 1e-9);  // cos(pi/2) = 0
  BOOST_CHECK_CLOSE(mm(0, 1), 0.04639, 1e-9);
}

BOOST_AUTO_TEST_CASE(inertia_matrix_is_spd_over_the_workspace) {
  const ArmParameters arm;
  for (double t1 = -M_PI; t1 <= M_PI; t1 += 0.1) {
    for (double t2 = 0.0; t2 <= M_PI; t2 += 0.05) {
      const Eigen::Matrix2d mm = m::inertia_matrix(arm, {t1, t2});
      BOOST_CHECK_EQUAL(mm(0, 1), mm(1, 0));
      BOOST_CHECK_GT(mm(0, 0), 0.0);
      BOOST_CHECK_GT(mm.determinant(), 0.0);
    }
  }
}

BOOST_AUTO_TEST_CASE(analytic_jacobian_matches_numeric_derivative_of_kinematics) {
  const ArmParameters arm;
  const Eigen::Vector2d theta(0.7, 1.3);
  const Eigen::Matrix2d j = m::jacobian(arm, theta);
  for (int i = 0; i < 2; ++i) {
    Eigen::Vector2d d = Eigen::Vector2d::Zero();
    d(i) = kStep;
    const Eigen::Vector2d fd =
        (m::hand_position(arm, theta + d) - m::hand_position(arm, theta - d)) / (2 * kStep);
    BOOST_CHECK_SMALL((fd - j.col(i)).norm(), kFdTolerance);
    const Eigen::Matrix2d dj_fd =
        (m::jacobian(arm, theta + d) - m::jacobian(arm, theta - d)) / (2 * kStep);
    BOOST_CHECK_SMALL((dj_fd - m::jacobian_d_theta(arm, theta, i)).norm(), kFdTolerance);
  }
  const Eigen::Matrix2d dm_fd = (m::inertia_matrix(arm, theta + Eigen::Vector2d(0, kStep)) -
                                 m::inertia_matrix(arm, theta - Eigen::Vector2d(0, kStep))) /
                                (2 * kStep);
  BOOST_CHECK_SMALL((dm_fd - m::inertia_matrix_d_elbow(arm, theta)).norm(), kFdTolerance);
}

BOOST_AUTO_TEST_CASE(inverse_kinematics_round_trips_and_rejects_unreachable_points) {
  const ArmParameters arm;
  const Eigen::Vector2d hand(0.4, 0.0);  // Piovesan's postural position
  const Eigen::Vector2d theta = m::inverse_kinematics(arm, hand);
  BOOST_CHECK_SMALL((m::hand_position(arm, theta) - hand).norm(), 1e-14);
  BOOST_CHECK_GT(theta(1), 0.0);
  BOOST_CHECK_THROW(m::inverse_kinematics(arm, {0.8, 0.0}), stiffid::InputError);
  BOOST_CHECK_THROW(m::inverse_kinematics(arm, {0.05, 0.0}), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(endpoint_and_joint_stiffness_transforms_are_inverse) {
  const ArmParameters arm;
  const Eigen::Vector2d theta(63 * M_PI / 180, 77 * M_PI / 180);
  Eigen::Matrix2d k_joint;
  k_joint << 10.0, 4.0, 4.0, 8.0;
  const Eigen::Matrix2d k_x = m::joint_to_endpoint(arm, theta, k_joint);
  BOOST_CHECK_SMALL((m::endpoint_to_joint(arm, theta, k_x) - k_joint).norm(), 1e-12);
}

BOOST_AUTO_TEST_CASE(load_stiffness_is_the_derivative_of_jacobian_transpose_times_force) {
  // Omega = d(J^T f)/d theta at fixed f (Piovesan eq 21), checked by finite differences.
  const ArmParameters arm;
  const Eigen::Vector2d theta(0.5, 1.1), f(3.0, -2.0);
  const Eigen::Matrix2d omega = m::load_stiffness(arm, theta, f);
  for (int i = 0; i < 2; ++i) {
    Eigen::Vector2d d = Eigen::Vector2d::Zero();
    d(i) = kStep;
    const Eigen::Vector2d fd = (m::jacobian(arm, theta + d).transpose() * f -
                                m::jacobian(arm, theta - d).transpose() * f) /
                               (2 * kStep);
    BOOST_CHECK_SMALL((fd - omega.col(i)).norm(), kFdTolerance);
  }
}

BOOST_AUTO_TEST_CASE(spd_square_root_squares_back) {
  const Eigen::Matrix2d mm = m::inertia_matrix(ArmParameters{}, {0.2, 1.4});
  const Eigen::MatrixXd s = m::spd_sqrt(mm);
  BOOST_CHECK_SMALL((s * s - mm).norm(), 1e-14);
  BOOST_CHECK_SMALL((m::spd_inverse_sqrt(mm) * s - Eigen::Matrix2d::Identity()).norm(), 1e-12);
}

BOOST_AUTO_TEST_CASE(invalid_parameters_are_named) {
  ArmParameters arm;
  arm.m2_kg = -1.0;
  try {
    arm.validate();
    BOOST_FAIL("expected InputError");
  } catch (const stiffid::InputError& e) {
    BOOST_CHECK(std::string(e.what()).find("m2_kg") != std::string::npos);
  }
}
