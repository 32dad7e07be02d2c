// The whole time-frequency pipeline (stages 1-6) on free responses known in closed form: a 2-DOF
// arm at Piovesan's posture with constant K and C, whose free response is the eigen-decomposition
// of its state matrix (computed here with Eigen's general eigensolver, not with the code under
// test).
#include <Eigen/Eigenvalues>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>

#include "data/trial.hpp"
#include "estimators/tfa.hpp"
#include "models/arm.hpp"

namespace est = stiffid::estimators;
namespace models = stiffid::models;

namespace {

/// Posture (0.4, 0) m of Piovesan 2012: elbow flexed solution of the inverse kinematics.
Eigen::Vector2d piovesan_posture() {
  return models::inverse_kinematics(models::ArmParameters{}, Eigen::Vector2d(0.4, 0.0));
}

/// 5 s at `fs` of M x'' + C x' + K x = 0 from t = onset with x = 0, x' = v0 (the state right after
/// an ideal impulse), x = 0 before; angles = posture + x. Closed form: x(t) = Re sum_i V_i e^{l_i
/// t} b_i with the eigenvectors V of the state matrix [0 I; -M^-1 K, -M^-1 C].
stiffid::data::Trial free_response_trial(const Eigen::Matrix2d& k, const Eigen::Matrix2d& c,
                                         const Eigen::Vector2d& v0, double fs, double onset_s) {
  const Eigen::Vector2d theta0 = piovesan_posture();
  const Eigen::Matrix2d m = models::inertia_matrix(models::ArmParameters{}, theta0);
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a.topRightCorner<2, 2>().setIdentity();
  a.bottomLeftCorner<2, 2>() = -m.inverse() * k;
  a.bottomRightCorner<2, 2>() = -m.inverse() * c;
  const Eigen::EigenSolver<Eigen::Matrix4d> eig(a);
  const Eigen::Matrix4cd v = eig.eigenvectors();
  Eigen::Vector4cd x0;
  x0 << 0.0, 0.0, v0(0), v0(1);
  const Eigen::Vector4cd b = v.partialPivLu().solve(x0);
  stiffid::data::Trial trial;
  trial.sample_rate_hz = fs;
  trial.names = {"th1", "th2"};
  trial.units = {"rad", "rad"};
  const int samples = static_cast<int>(std::lround(5.0 * fs));
  trial.samples.resize(samples, 2);
  for (int i = 0; i < samples; ++i) {
    const double t = i / fs - onset_s;
    Eigen::Vector2d x = Eigen::Vector2d::Zero();
    if (t >= 0) {
      Eigen::Vector4cd s = Eigen::Vector4cd::Zero();
      for (int q = 0; q < 4; ++q) s += v.col(q) * b(q) * std::exp(eig.eigenvalues()(q) * t);
      x = s.head<2>().real();
    }
    trial.samples.row(i) = (theta0 + x).transpose();
  }
  return trial;
}

double worst_relative_error(const est::TfaResult& r, bool damping, const Eigen::Matrix2d& truth,
                            double t0, double t1) {
  double worst = 0.0;
  for (int m = 0; m < r.modal.time_s.size(); ++m) {
    const double t = r.modal.time_s(m);
    if (t < t0 || t > t1) continue;
    const Eigen::MatrixXd& e =
        damping ? r.modal.damping_nms_per_rad[m] : r.modal.stiffness_nm_per_rad[m];
    worst = std::max(worst, (e - truth).cwiseAbs().maxCoeff() / truth.cwiseAbs().maxCoeff());
  }
  return worst;
}

}  // namespace

BOOST_AUTO_TEST_CASE(constant_k_and_c_are_recovered_to_one_percent_from_a_free_response) {
  Eigen::Matrix2d k;
  k << 35, 5, 5, 20;                   // Piovesan eq 52, N m/rad
  const Eigen::Matrix2d c = 0.01 * k;  // N m s/rad
  // Initial joint velocity of a 5 N x 20 ms push along +y at the hand: M^-1 J^T f dt.
  const Eigen::Vector2d theta0 = piovesan_posture();
  const models::ArmParameters arm;
  const Eigen::Vector2d v0 = models::inertia_matrix(arm, theta0).inverse() *
                             models::jacobian(arm, theta0).transpose() * Eigen::Vector2d(0, 0.1);
  const stiffid::data::Trial trial = free_response_trial(k, c, v0, 4000.0, 2.5);
  // Both methods: the spectrogram pipeline (issue 6) and the default damped-mode fit (issue 7).
  for (const est::TfaMethod method : {est::TfaMethod::spectrogram, est::TfaMethod::modal}) {
    est::TfaOptions o;
    o.method = method;
    o.deviation.angle_channels = {"th1", "th2"};
    o.deviation.onset_s = 2.5;
    o.deviation.pulse_s = 0.0;  // an ideal impulse: free from the onset on
    const est::TfaResult r = est::identify_tfa(trial, o);
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    const double ek = worst_relative_error(r, false, k, 2.6, 4.5);
    const double ec = worst_relative_error(r, true, c, 2.6, 4.5);
    BOOST_TEST_MESSAGE(est::to_string(method)
                       << ": worst |K - K0| / max|K0| = " << ek << ", C: " << ec << ", frequencies "
                       << r.modal.omega_rad_per_s.row(200) / (2 * M_PI));
    // 1 % of the largest coefficient (issues 6 and 7). The signal is an exact sum of two damped
    // cosines, so what remains is the Savitzky-Golay edge fit (spectrogram), the spline tracks
    // (modal) and the decimation filter's pass-band ripple.
    BOOST_CHECK_LT(ek, 0.01);
    BOOST_CHECK_LT(ec, 0.01);
  }
}
