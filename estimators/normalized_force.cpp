#include "estimators/normalized_force.hpp"

#include <complex>

namespace stiffid::estimators {

NormalizedForceResult normalized_force(const RidgeResult& ridges,
                                       const ModalAnalysisResult& modal) {
  const int frames = static_cast<int>(modal.time_s.size());
  const int n = static_cast<int>(modal.omega_rad_per_s.cols());
  NormalizedForceResult r;
  r.time_s = modal.time_s;
  r.coordinate.resize(frames, n);
  r.velocity.resize(frames, n);
  r.force.resize(frames, n);
  r.envelope.resize(frames, n);
  r.envelope_force.resize(frames, n);
  for (int m = 0; m < frames; ++m) {
    for (int j = 0; j < n; ++j) {
      const Eigen::VectorXd projector =
          modal.inertia_sqrt[m] * modal.eigenvectors[m].col(j);  // M^1/2 p_j (M^1/2 symmetric)
      const Eigen::VectorXcd c = ridges.amplitude_c[j].row(m).transpose();
      const std::complex<double> z =
          projector.dot(c.real()) + std::complex<double>(0.0, 1.0) * projector.dot(c.imag());
      const std::complex<double> lambda(modal.alpha_per_s(m, j), modal.omega_rad_per_s(m, j));
      const double eta2 = modal.eta_squared_per_s2(m, j), gamma = modal.gamma_per_s(m, j);
      r.coordinate(m, j) = z.real();
      r.velocity(m, j) = (lambda * z).real();
      r.force(m, j) = eta2 * r.coordinate(m, j) + 2.0 * gamma * r.velocity(m, j);
      r.envelope(m, j) = std::abs(z);
      r.envelope_force(m, j) =
          eta2 * r.envelope(m, j) + 2.0 * gamma * modal.alpha_per_s(m, j) * r.envelope(m, j);
    }
  }
  return r;
}

}  // namespace stiffid::estimators
