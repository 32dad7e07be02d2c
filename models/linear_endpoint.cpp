#include "models/linear_endpoint.hpp"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

namespace stiffid::models {

LinearResponse simulate_linear_endpoint(const Eigen::MatrixXd& inertia,
                                        const Eigen::MatrixXd& damping,
                                        const Eigen::MatrixXd& stiffness,
                                        const Eigen::MatrixXd& force, double sample_rate_hz,
                                        InputHold hold, const Eigen::VectorXd& x0,
                                        const Eigen::VectorXd& v0) {
  const Eigen::Index n = inertia.rows(), samples = force.rows();
  const double h = 1.0 / sample_rate_hz;
  const Eigen::MatrixXd inertia_inverse = inertia.inverse();
  // Augmented generator [[A, G, 0], [0, 0, Id], [0, 0, 0]] of sizes (2n, n, n).
  Eigen::MatrixXd aug = Eigen::MatrixXd::Zero(4 * n, 4 * n);
  aug.block(0, n, n, n).setIdentity();
  aug.block(n, 0, n, n) = -inertia_inverse * stiffness;
  aug.block(n, n, n, n) = -inertia_inverse * damping;
  aug.block(n, 2 * n, n, n) = inertia_inverse;
  aug.block(2 * n, 3 * n, n, n).setIdentity();
  const Eigen::MatrixXd e = (aug * h).exp();
  const Eigen::MatrixXd phi = e.block(0, 0, 2 * n, 2 * n);
  const Eigen::MatrixXd gamma0 = e.block(0, 2 * n, 2 * n, n);
  const Eigen::MatrixXd gamma1 = e.block(0, 3 * n, 2 * n, n);

  LinearResponse out;
  out.position.resize(samples, n);
  out.velocity.resize(samples, n);
  Eigen::VectorXd s(2 * n);
  s << x0, v0;
  for (Eigen::Index k = 0; k < samples; ++k) {
    out.position.row(k) = s.head(n).transpose();
    out.velocity.row(k) = s.tail(n).transpose();
    if (k + 1 == samples) break;
    const Eigen::VectorXd f = force.row(k).transpose();
    s = phi * s + gamma0 * f;
    if (hold == InputHold::first_order) {
      s += gamma1 * ((force.row(k + 1).transpose() - f) * sample_rate_hz);
    }
  }
  return out;
}

}  // namespace stiffid::models
