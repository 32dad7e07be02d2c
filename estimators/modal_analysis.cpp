#include "estimators/modal_analysis.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "estimators/modal_parameters.hpp"
#include "models/arm.hpp"

namespace stiffid::estimators {
namespace {

/// Folds a phase difference into (-pi/2, pi/2]: a mode in phase or in antiphase between channels
/// is classical; the remainder is the non-classical shift.
double fold_half_pi(double x) {
  x = std::remainder(x, M_PI);  // (-pi/2, pi/2]
  return x <= -M_PI / 2 ? x + M_PI : x;
}

}  // namespace

ModalAnalysisResult modal_analysis(const RidgeResult& ridges,
                                   const std::vector<Eigen::MatrixXd>& inertia_kg_m2,
                                   const ModalAnalysisOptions& options) {
  const int frames = static_cast<int>(ridges.time_s.size());
  const int n = static_cast<int>(ridges.omega_rad_per_s.cols());
  if (n < 1 || static_cast<int>(ridges.amplitude.size()) != n || ridges.amplitude[0].cols() != n) {
    throw InputError("modal analysis: needs as many channels (joints) as modes, got " +
                     std::to_string(ridges.amplitude.empty() ? 0 : ridges.amplitude[0].cols()) +
                     " channels for " + std::to_string(n) + " modes");
  }
  if (static_cast<int>(inertia_kg_m2.size()) != frames) {
    throw InputError("modal analysis: one inertia matrix per frame is needed");
  }
  if (frames < 2) throw InputError("modal analysis: needs at least two frames");
  const double rate_hz = 1.0 / (ridges.time_s(1) - ridges.time_s(0));

  ModalAnalysisResult r;
  r.time_s = ridges.time_s;
  // Stage 4: smoothing and derivatives of omega_j and ln A_j.
  Eigen::MatrixXd log_amplitude(frames, n);
  for (int j = 0; j < n; ++j) {
    log_amplitude.col(j) = 0.5 * ridges.amplitude[j].rowwise().squaredNorm().array().log();
  }
  const SavitzkyGolayResult omega =
      savitzky_golay(ridges.omega_rad_per_s, rate_hz, options.smoothing);
  const SavitzkyGolayResult log_a = savitzky_golay(log_amplitude, rate_hz, options.smoothing);
  r.omega_rad_per_s = omega.value;
  r.omega_dot_rad_per_s2 = omega.first_derivative;
  r.amplitude = log_a.value.array().exp().matrix();
  r.alpha_per_s = log_a.first_derivative;
  r.alpha_dot_per_s2 = log_a.second_derivative;
  const Eigen::ArrayXXd w = r.omega_rad_per_s.array(), wd = r.omega_dot_rad_per_s2.array();
  const Eigen::ArrayXXd a = r.alpha_per_s.array(), ad = r.alpha_dot_per_s2.array();
  r.gamma_per_s = (-a - wd / (2.0 * w)).matrix();                     // eq 45
  r.eta_squared_per_s2 = (w * w + a * a + a * wd / w - ad).matrix();  // eq 46, alpha-dot

  // Mode shapes in joint space (eqs 37, 41), unit norm, sign continuous over frames.
  r.phase_difference_rad = Eigen::MatrixXd::Zero(frames, n);
  std::vector<Eigen::MatrixXd> shapes(n, Eigen::MatrixXd(frames, n));  // [j] (T x channel)
  for (int j = 0; j < n; ++j) {
    Eigen::VectorXd previous = Eigen::VectorXd::Zero(n);
    for (int m = 0; m < frames; ++m) {
      const Eigen::RowVectorXcd c = ridges.amplitude_c[j].row(m);
      Eigen::Index ref = 0;
      c.cwiseAbs().maxCoeff(&ref);
      Eigen::VectorXd phi(n);
      double largest_shift = 0.0;
      for (int k = 0; k < n; ++k) {
        const double d = std::arg(c(k) * std::conj(c(ref)));
        phi(k) = std::abs(c(k)) * std::cos(d);
        const double folded = fold_half_pi(d);
        if (std::abs(folded) > std::abs(largest_shift)) largest_shift = folded;
      }
      // For 2 joints report the second channel relative to the first, as eq 41.
      if (n == 2) {
        r.phase_difference_rad(m, j) = fold_half_pi(std::arg(c(1) * std::conj(c(0))));
      } else {
        r.phase_difference_rad(m, j) = largest_shift;
      }
      phi.normalize();
      if (phi.dot(previous) < 0.0 || (m == 0 && phi(ref) < 0.0)) phi = -phi;
      if (phi.allFinite()) previous = phi;
      shapes[j].row(m) = phi.transpose();
    }
    shapes[j] = savitzky_golay(shapes[j], rate_hz, options.smoothing).value;
  }
  r.time_lag_s = (r.phase_difference_rad.array() / w).matrix();

  r.separated.resize(frames);
  for (int m = 0; m < frames; ++m) {
    const Eigen::MatrixXd& mass = inertia_kg_m2[m];
    const Eigen::MatrixXd root = models::spd_sqrt(mass);
    Eigen::MatrixXd phi(n, n), p(n, n);
    for (int j = 0; j < n; ++j) {
      phi.col(j) = shapes[j].row(m).transpose().normalized();
      p.col(j) = (root * phi.col(j)).normalized();
    }
    r.separated(m) = p.allFinite();
    if (r.separated(m)) {  // nearest orthonormal matrix (eq 43), weighted by the modes' ANR
      const Eigen::JacobiSVD<Eigen::MatrixXd> svd(p);
      r.separated(m) = svd.singularValues().minCoeff() >= 1e-6 * svd.singularValues().maxCoeff();
      // (a mode of non-finite ANR gets a weight of 0 or NaN: its column completes the others')
      Eigen::VectorXd weight = Eigen::VectorXd::Ones(n);
      if (ridges.anr_db.rows() == frames)
        for (int j = 0; j < n; ++j) weight(j) = std::pow(10.0, ridges.anr_db(m, j) / 10.0);
      p = orthonormal_shapes(p, weight);
    }
    const Eigen::VectorXd eta2 = r.eta_squared_per_s2.row(m).transpose();
    const Eigen::VectorXd two_gamma = 2.0 * r.gamma_per_s.row(m).transpose();
    r.mode_shape.push_back(phi);
    r.eigenvectors.push_back(p);
    r.inertia_sqrt.push_back(root);
    r.stiffness_nm_per_rad.push_back(root * p * eta2.asDiagonal() * p.transpose() * root);
    r.damping_nms_per_rad.push_back(root * p * two_gamma.asDiagonal() * p.transpose() * root);
  }
  if (!ridges.status.ok) {
    r.status = ridges.status;
  } else if (!r.separated.any()) {
    r.status = Status::failure("modal analysis: the mode shapes are parallel at every one of the " +
                               std::to_string(frames) + " frames (modes not separated)");
  } else if (!r.eta_squared_per_s2.allFinite()) {
    r.status = Status::failure("modal analysis: non-finite natural frequencies");
  }
  return r;
}

}  // namespace stiffid::estimators
