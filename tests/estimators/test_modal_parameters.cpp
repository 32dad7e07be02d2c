#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <limits>

#include "data/error.hpp"
#include "estimators/damped_modes.hpp"
#include "estimators/modal_analysis.hpp"
#include "estimators/modal_parameters.hpp"
#include "models/arm.hpp"

using stiffid::InputError;
using stiffid::estimators::DampedModesOptions;
using stiffid::estimators::fit_damped_modes;
using stiffid::estimators::modal_parameters;
using stiffid::estimators::ModalMapping;
using stiffid::estimators::ModalParametersOptions;

namespace {

constexpr double kRateHz = 4000.0;
constexpr double kOnsetS = 2.5;
constexpr double kFreeS = 2.52;

// Free response of M q'' + C q' + K q = 0 from q(0) = 0, q'(0) = v0, in closed form from the
// eigendecomposition of the state matrix A = [[0, I], [-M^-1 K, -M^-1 C]]:
// [q; q'](t) = V exp(Lambda t) V^-1 [0; v0] (independent of the code under test).
Eigen::MatrixXd free_response(const Eigen::Matrix2d& m, const Eigen::Matrix2d& k,
                              const Eigen::Matrix2d& c, const Eigen::Vector2d& v0) {
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a.topRightCorner<2, 2>() = Eigen::Matrix2d::Identity();
  a.bottomLeftCorner<2, 2>() = -m.inverse() * k;
  a.bottomRightCorner<2, 2>() = -m.inverse() * c;
  const Eigen::EigenSolver<Eigen::Matrix4d> eig(a);
  const Eigen::Matrix4cd v = eig.eigenvectors();
  const Eigen::Vector4cd lambda = eig.eigenvalues();
  Eigen::Vector4d x0;
  x0 << 0.0, 0.0, v0;
  const Eigen::Vector4cd coef = v.inverse() * x0.cast<std::complex<double>>();
  const int s = static_cast<int>(5.0 * kRateHz);
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(s, 2);
  for (int i = 0; i < s; ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau < 0.0) continue;
    const Eigen::Vector4cd state = v * (lambda.array() * tau).exp().matrix().cwiseProduct(coef);
    q.row(i) = state.head<2>().real().transpose();
  }
  return q;
}

struct Case {
  Eigen::Matrix2d m, k, c;
};

// Piovesan 2012 eq 52 at the postural hand position (0.4, 0) m with the Table 1 arm.
Case paper_case(double damping_rotation_rad) {
  const stiffid::models::ArmParameters arm;
  const Eigen::Vector2d theta = stiffid::models::inverse_kinematics(arm, {0.4, 0.0});
  Case cs;
  cs.m = stiffid::models::inertia_matrix(arm, theta);
  cs.k << 35.0, 5.0, 5.0, 20.0;
  Eigen::Matrix2d rotation;  // eq 55
  rotation << std::cos(damping_rotation_rad), -std::sin(damping_rotation_rad),
      std::sin(damping_rotation_rad), std::cos(damping_rotation_rad);
  cs.c = rotation * (0.01 * cs.k) * rotation.transpose();
  return cs;
}

// Largest relative error of K and C over 2.6-4.5 s, relative to the largest coefficient of each
// (k12 and c12 are small: an element-wise relative error would measure the others' noise).
std::pair<double, double> worst_errors(const Case& cs, ModalMapping mapping,
                                       const Eigen::Vector2d& v0) {
  const Eigen::MatrixXd q = free_response(cs.m, cs.k, cs.c, v0);
  const auto modes = fit_damped_modes(q, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(modes.status.ok, modes.status.message);
  ModalParametersOptions options;
  options.mapping = mapping;
  const auto r = modal_parameters(modes, {cs.m}, options);
  double ek = 0.0, ec = 0.0;
  for (Eigen::Index i = 0; i < r.t_s.size(); ++i) {
    if (r.t_s(i) < 2.6 || r.t_s(i) > 4.5) continue;
    // Noise-free input is fitted as 40 dB data (the noise floor of damped_modes.cpp): a frame may
    // be invalid only because a mode has sunk below that floor (ANR < 0 dB), never otherwise.
    double weakest_anr_db = std::numeric_limits<double>::infinity();
    for (const auto& track : modes.modes)
      weakest_anr_db = std::min(weakest_anr_db, track.anr_db(i));
    BOOST_CHECK_MESSAGE(
        r.valid(i) || weakest_anr_db < DampedModesOptions{}.anr_threshold_db,
        "t = " << r.t_s(i) << " s invalid with every mode's ANR >= " << weakest_anr_db << " dB");
    ek = std::max(ek, (r.stiffness[i] - cs.k).cwiseAbs().maxCoeff() / cs.k.cwiseAbs().maxCoeff());
    ec = std::max(ec, (r.damping[i] - cs.c).cwiseAbs().maxCoeff() / cs.c.cwiseAbs().maxCoeff());
  }
  return {ek, ec};
}

// One frame of a mode with constant tracks: omega (rad/s), alpha (1/s; negative: decaying), a
// real shape, its ANR (dB), flagged valid.
stiffid::estimators::ModeTrack constant_track(double omega, double alpha,
                                              const Eigen::Vector2d& shape, double anr_db) {
  stiffid::estimators::ModeTrack mt;
  mt.omega_rad_per_s = Eigen::VectorXd::Constant(1, omega);
  mt.frequency_hz = mt.omega_rad_per_s / (2.0 * M_PI);
  mt.omega_dot_rad_per_s2 = Eigen::VectorXd::Zero(1);
  mt.alpha_per_s = Eigen::VectorXd::Constant(1, alpha);
  mt.alpha_dot_per_s2 = Eigen::VectorXd::Zero(1);
  mt.shape = (0.01 * shape).cast<std::complex<double>>().transpose();
  mt.anr_db = Eigen::VectorXd::Constant(1, anr_db);
  mt.valid = Eigen::Array<bool, Eigen::Dynamic, 1>::Constant(1, true);
  return mt;
}

}  // namespace

BOOST_AUTO_TEST_CASE(constant_k_and_proportional_c_recovered_to_one_percent_noise_free) {
  // Issue 7: an exact 2-DOF system with constant K and C, noise-free: K, C to 1 %. Both mappings
  // are exact for classical damping; pulse directions 45 and 135 degrees excite the modes in
  // different proportions.
  const Case cs = paper_case(0.0);
  for (const double direction_deg : {45.0, 135.0}) {
    const double a = direction_deg * M_PI / 180.0;
    const stiffid::models::ArmParameters arm;
    const Eigen::Vector2d theta = stiffid::models::inverse_kinematics(arm, {0.4, 0.0});
    // 5 N for 20 ms at the hand: joint impulse J^T F dt, velocity M^-1 J^T F dt.
    const Eigen::Vector2d v0 = cs.m.inverse() * stiffid::models::jacobian(arm, theta).transpose() *
                               Eigen::Vector2d(std::cos(a), std::sin(a)) * 5.0 * 0.02;
    for (const ModalMapping mapping : {ModalMapping::state_space, ModalMapping::paper_eq48}) {
      const auto [ek, ec] = worst_errors(cs, mapping, v0);
      BOOST_TEST_MESSAGE("direction " << direction_deg << " mapping " << int(mapping) << ": K "
                                      << ek << ", C " << ec);
      BOOST_CHECK_SMALL(ek, 0.01);
      BOOST_CHECK_SMALL(ec, 0.01);
    }
  }
}

BOOST_AUTO_TEST_CASE(non_classical_damping_recovered_by_the_state_space_mapping) {
  // Eq 55 with nu = pi/6: complex modes. The state-space inverse is exact for any linear
  // time-invariant system; eq 48 (real P) is an approximation and is not asserted.
  const Case cs = paper_case(M_PI / 6.0);
  const Eigen::Vector2d v0(0.3, -0.5);
  const auto [ek, ec] = worst_errors(cs, ModalMapping::state_space, v0);
  BOOST_TEST_MESSAGE("non-classical, state space: K " << ek << ", C " << ec);
  BOOST_CHECK_SMALL(ek, 0.01);
  BOOST_CHECK_SMALL(ec, 0.01);
}

BOOST_AUTO_TEST_CASE(a_lost_modes_shape_is_completed_from_the_valid_ones) {
  // A mode sunk into the noise keeps its tracks' extrapolation, shape included. Eq 48's P (M^1/2-
  // orthonormal shapes) is then fixed by the valid mode: the lost one's column is its orthogonal
  // complement, exact for classical damping whatever the lost shape says. Exact 2-DOF system,
  // noise-free fit; from 3.5 s on, mode 1's shape is replaced by an arbitrary one and flagged
  // invalid: K, C there stay within 1 % (eta_j^2 and Gamma_j are still the fit's). Left valid,
  // the same wrong shape enters P's polar factor and K is off by more than 10 %.
  const Case cs = paper_case(0.0);
  const Eigen::MatrixXd q = free_response(cs.m, cs.k, cs.c, {0.3, -0.5});
  auto modes = fit_damped_modes(q, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(modes.status.ok, modes.status.message);
  auto corrupt = modes;
  for (Eigen::Index i = 0; i < corrupt.t_s.size(); ++i) {
    if (corrupt.t_s(i) < 3.5) continue;
    corrupt.modes[1].shape.row(i) << std::complex<double>(0.8, 0.1), std::complex<double>(0.6, 0.0);
    corrupt.modes[1].valid(i) = false;
  }
  auto flagged_valid = corrupt;
  for (Eigen::Index i = 0; i < flagged_valid.t_s.size(); ++i)
    flagged_valid.modes[1].valid(i) = true;
  const auto completed = modal_parameters(corrupt, {cs.m}, {});
  const auto polar = modal_parameters(flagged_valid, {cs.m}, {});
  double ek = 0.0, ec = 0.0, ek_polar = 0.0;
  int frames = 0;
  for (Eigen::Index i = 0; i < completed.t_s.size(); ++i) {
    if (completed.t_s(i) < 3.5 || completed.t_s(i) > 4.5) continue;
    ++frames;
    BOOST_CHECK(!completed.valid(i));  // still flagged: K is only as valid as the weaker mode
    const double scale_k = cs.k.cwiseAbs().maxCoeff(), scale_c = cs.c.cwiseAbs().maxCoeff();
    ek = std::max(ek, (completed.stiffness[i] - cs.k).cwiseAbs().maxCoeff() / scale_k);
    ec = std::max(ec, (completed.damping[i] - cs.c).cwiseAbs().maxCoeff() / scale_c);
    ek_polar = std::max(ek_polar, (polar.stiffness[i] - cs.k).cwiseAbs().maxCoeff() / scale_k);
    // P stays orthonormal
    BOOST_CHECK_SMALL((completed.eigenvectors[i].transpose() * completed.eigenvectors[i] -
                       Eigen::Matrix2d::Identity())
                          .norm(),
                      1e-12);
  }
  BOOST_TEST_MESSAGE(frames << " frames: completed K " << ek << ", C " << ec << "; polar K "
                            << ek_polar);
  BOOST_REQUIRE_GT(frames, 100);
  BOOST_CHECK_SMALL(ek, 0.01);
  BOOST_CHECK_SMALL(ec, 0.01);
  BOOST_CHECK_GT(ek_polar, 0.1);
}

BOOST_AUTO_TEST_CASE(a_weak_modes_noisy_shape_moves_p_by_its_weight) {
  // Eq 43 weighted by the modes' amplitude-to-noise power ratios. M = I, true P = I; the strong
  // mode's shape is exact (e1), the weak one's, 10 dB below it, is off by delta = 0.2 rad. The P
  // maximizing w1 cos(phi) + w2 cos(phi - delta) (w = 10^(ANR/10)) is the rotation by phi with
  // tan phi = w2 sin delta / (w1 + w2 cos delta): K = R(phi) diag(eta^2) R(phi)^T in closed
  // form. Equal ANRs give phi = delta / 2 (the unweighted polar factor).
  const double delta = 0.2, omega1 = 15.0, omega2 = 22.0, alpha1 = -1.0, alpha2 = -2.0;
  for (const double weak_db : {30.0, 40.0}) {
    stiffid::estimators::DampedModesResult modes;
    modes.t_s = Eigen::VectorXd::Constant(1, 3.0);
    modes.modes = {constant_track(omega1, alpha1, {1.0, 0.0}, 40.0),
                   constant_track(omega2, alpha2, {-std::sin(delta), std::cos(delta)}, weak_db)};
    const auto r = modal_parameters(modes, {Eigen::Matrix2d::Identity()}, {});
    const double w2 = std::pow(10.0, (weak_db - 40.0) / 10.0);
    const double phi = std::atan2(w2 * std::sin(delta), 1.0 + w2 * std::cos(delta));
    Eigen::Matrix2d rotation;
    rotation << std::cos(phi), -std::sin(phi), std::sin(phi), std::cos(phi);
    // eq 46 with constant tracks: eta^2 = omega^2 + alpha^2; eq 45: Gamma = -alpha
    const Eigen::Vector2d eta2(omega1 * omega1 + alpha1 * alpha1,
                               omega2 * omega2 + alpha2 * alpha2);
    const Eigen::Vector2d two_gamma(-2.0 * alpha1, -2.0 * alpha2);
    const Eigen::Matrix2d k = rotation * eta2.asDiagonal() * rotation.transpose();
    const Eigen::Matrix2d c = rotation * two_gamma.asDiagonal() * rotation.transpose();
    BOOST_TEST_MESSAGE("weak mode at " << weak_db << " dB: phi " << phi << " rad");
    BOOST_CHECK_SMALL((r.stiffness[0] - k).norm() / k.norm(), 1e-12);
    BOOST_CHECK_SMALL((r.damping[0] - c).norm() / c.norm(), 1e-12);
    if (weak_db == 40.0) BOOST_CHECK_CLOSE(phi, delta / 2.0, 1e-9);
  }
  // The weights' scale does not matter; a zero weight completes the column; sizes are checked.
  Eigen::Matrix2d raw;
  raw << 1.0, -std::sin(delta), 0.0, std::cos(delta);
  using stiffid::estimators::orthonormal_shapes;
  const Eigen::MatrixXd p = orthonormal_shapes(raw, Eigen::Vector2d(1e11, 1e10));
  BOOST_CHECK_SMALL((p - orthonormal_shapes(raw, Eigen::Vector2d(1.0, 0.1))).norm(), 1e-12);
  BOOST_CHECK_SMALL(
      (orthonormal_shapes(raw, Eigen::Vector2d(1.0, 0.0)) - Eigen::Matrix2d::Identity()).norm(),
      1e-12);
  BOOST_CHECK_THROW(orthonormal_shapes(raw, Eigen::Vector3d::Ones()), InputError);
}

BOOST_AUTO_TEST_CASE(rejects_mismatched_inertia) {
  const Case cs = paper_case(0.0);
  const Eigen::MatrixXd q = free_response(cs.m, cs.k, cs.c, {0.3, -0.5});
  const auto modes = fit_damped_modes(q, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_CHECK_THROW(modal_parameters(modes, {cs.m, cs.m}, {}), InputError);
  BOOST_CHECK_THROW(modal_parameters(modes, {Eigen::Matrix3d::Identity()}, {}), InputError);
}

BOOST_AUTO_TEST_CASE(tracks_feed_the_spectrogram_pipelines_modal_analysis) {
  // The whole chain of the tfa pipeline with the modal method: fit -> as_ridges -> stage 4-5
  // modal_analysis (Savitzky-Golay smoothing, eqs 45-48 with a real P). Noise-free exact 2-DOF
  // system with classical damping: K, C to 1 % (issue 7) over 2.6-4.5 s.
  const Case cs = paper_case(0.0);
  const Eigen::MatrixXd q = free_response(cs.m, cs.k, cs.c, {0.3, -0.5});
  const auto modes = fit_damped_modes(q, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE(modes.status.ok);
  const auto ridges = stiffid::estimators::as_ridges(modes);
  const std::vector<Eigen::MatrixXd> inertia(ridges.time_s.size(), cs.m);
  const auto r = stiffid::estimators::modal_analysis(ridges, inertia, {});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  double ek = 0.0, ec = 0.0;
  for (Eigen::Index i = 0; i < r.time_s.size(); ++i) {
    if (r.time_s(i) < 2.6 || r.time_s(i) > 4.5) continue;
    ek = std::max(
        ek, (r.stiffness_nm_per_rad[i] - cs.k).cwiseAbs().maxCoeff() / cs.k.cwiseAbs().maxCoeff());
    ec = std::max(
        ec, (r.damping_nms_per_rad[i] - cs.c).cwiseAbs().maxCoeff() / cs.c.cwiseAbs().maxCoeff());
  }
  BOOST_TEST_MESSAGE("chain through modal_analysis: K " << ek << ", C " << ec);
  BOOST_CHECK_SMALL(ek, 0.01);
  BOOST_CHECK_SMALL(ec, 0.01);
}

BOOST_AUTO_TEST_CASE(frames_whose_mode_shapes_are_parallel_are_flagged_not_fatal) {
  // Two ridges on one mode over 0.5 s (mode 2's amplitudes replaced by mode 1's): there the
  // smoothed shapes are parallel and P is undefined. Those frames are flagged (separated false)
  // and the rest keep the exact K of the noise-free 2-DOF system; only a record without any
  // separated frame is a failure.
  const Case cs = paper_case(0.0);
  const Eigen::MatrixXd q = free_response(cs.m, cs.k, cs.c, {0.3, -0.5});
  const auto modes = fit_damped_modes(q, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE(modes.status.ok);
  auto ridges = stiffid::estimators::as_ridges(modes);
  const Eigen::Index frames = ridges.time_s.size();
  const std::vector<Eigen::MatrixXd> inertia(frames, cs.m);
  for (Eigen::Index i = 0; i < frames; ++i) {
    if (ridges.time_s(i) >= 3.5 && ridges.time_s(i) <= 4.0) {
      ridges.amplitude_c[1].row(i) = ridges.amplitude_c[0].row(i);
      ridges.amplitude[1].row(i) = ridges.amplitude[0].row(i);
    }
  }
  const auto r = stiffid::estimators::modal_analysis(ridges, inertia, {});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_REQUIRE_EQUAL(r.separated.size(), frames);
  int flagged = 0;
  double ek = 0.0;
  for (Eigen::Index i = 0; i < frames; ++i) {
    const double t = r.time_s(i);
    if (!r.separated(i)) {
      ++flagged;
      BOOST_CHECK(t >= 3.5 && t <= 4.0);  // only inside the corrupted span
    }
    if (t >= 3.75 - 0.1 && t <= 3.75 + 0.1) BOOST_CHECK(!r.separated(i));  // its middle
    if (t >= 2.6 && t <= 3.2) {  // away from it, by more than the smoothing window
      BOOST_CHECK(r.separated(i));
      ek = std::max(ek, (r.stiffness_nm_per_rad[i] - cs.k).cwiseAbs().maxCoeff() /
                            cs.k.cwiseAbs().maxCoeff());
    }
  }
  BOOST_TEST_MESSAGE("parallel shapes: " << flagged << " frames flagged; K elsewhere " << ek);
  BOOST_CHECK_GT(flagged, 0);
  BOOST_CHECK_SMALL(ek, 0.01);
  // Every frame parallel: a failure that says so.
  for (Eigen::Index i = 0; i < frames; ++i) {
    ridges.amplitude_c[1].row(i) = ridges.amplitude_c[0].row(i);
    ridges.amplitude[1].row(i) = ridges.amplitude[0].row(i);
  }
  const auto all = stiffid::estimators::modal_analysis(ridges, inertia, {});
  BOOST_CHECK(!all.status.ok);
  BOOST_CHECK(all.status.message.find("parallel at every one") != std::string::npos);
  BOOST_CHECK(!all.separated.any());
}

BOOST_AUTO_TEST_CASE(a_growing_mode_makes_c_indefinite_and_the_frame_invalid) {
  // M = I, modes along e1 and e2, omega 15 and 22 rad/s: K = diag(eta^2), C = diag(2 Gamma) with
  // Gamma = -alpha (eq 45, constant tracks). A passive joint's damping is positive semidefinite:
  // a mode whose fitted decay turns into growth (alpha2 > 0) gives C an eigenvalue -2 alpha2 < 0,
  // and the frame is not vouched for even though K is positive definite. An undamped mode
  // (alpha2 = 0: C singular, semidefinite) and a decaying one keep it.
  for (const double alpha2 : {-2.0, 0.0, 2.0}) {
    stiffid::estimators::DampedModesResult modes;
    modes.t_s = Eigen::VectorXd::Constant(1, 3.0);
    modes.modes = {constant_track(15.0, -1.0, {1.0, 0.0}, 40.0),
                   constant_track(22.0, alpha2, {0.0, 1.0}, 40.0)};
    const auto r = modal_parameters(modes, {Eigen::Matrix2d::Identity()}, {});
    BOOST_CHECK_SMALL(r.damping[0](1, 1) + 2.0 * alpha2, 1e-12);
    BOOST_CHECK(r.stiffness[0].llt().info() == Eigen::Success);  // K positive definite
    BOOST_CHECK_EQUAL(static_cast<bool>(r.valid(0)), alpha2 <= 0.0);
  }
}
