#include "estimators/modal_parameters.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "models/arm.hpp"

namespace stiffid::estimators {
namespace {

using Complex = std::complex<double>;

// Real unit vector of a complex mode shape: rotated by the phase that makes it most real
// (maximizes |Re(e^-i phi u)|, phi = arg(sum u_k^2) / 2), the re-synchronization of eqs 41-42.
Eigen::VectorXd most_real(const Eigen::VectorXcd& u) {
  const double phi = 0.5 * std::arg(u.cwiseProduct(u).sum());
  Eigen::VectorXd v = (u * std::polar(1.0, -phi)).real();
  return v / v.norm();
}

// The M^1/2-normalized mode shapes (columns of `shapes`), each at its most real phase: real
// unit columns (eqs 38-41).
Eigen::MatrixXd real_shapes(const Eigen::MatrixXd& m_half, const Eigen::MatrixXcd& shapes) {
  Eigen::MatrixXd raw(shapes.rows(), shapes.cols());
  for (Eigen::Index j = 0; j < shapes.cols(); ++j)
    raw.col(j) = most_real(m_half.cast<Complex>() * shapes.col(j));
  return raw;
}

// Nearest matrix with orthonormal columns to `raw` (C x k, k <= C): the polar factor U V^T (eq 43).
Eigen::MatrixXd polar_factor(const Eigen::MatrixXd& raw) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(raw, Eigen::ComputeThinU | Eigen::ComputeThinV);
  return svd.matrixU() * svd.matrixV().transpose();
}

}  // namespace

Eigen::MatrixXd orthonormal_shapes(const Eigen::MatrixXd& raw, const Eigen::VectorXd& weight) {
  const int n = static_cast<int>(raw.cols());
  if (weight.size() != n)
    throw InputError("orthonormal_shapes: " + std::to_string(weight.size()) + " weights for " +
                     std::to_string(n) + " shapes");
  std::vector<int> kept, lost;
  for (int j = 0; j < n; ++j)
    (std::isfinite(weight(j)) && weight(j) > 0.0 ? kept : lost).push_back(j);
  if (kept.empty()) return polar_factor(raw);
  double largest = 0.0;
  for (const int j : kept) largest = std::max(largest, weight(j));
  Eigen::MatrixXd good(raw.rows(), kept.size()), rest(raw.rows(), lost.size());
  for (std::size_t i = 0; i < kept.size(); ++i)
    good.col(i) = (weight(kept[i]) / largest) * raw.col(kept[i]);
  const Eigen::MatrixXd u = polar_factor(good);  // weighted orthogonal Procrustes
  Eigen::MatrixXd p(raw.rows(), n);
  for (std::size_t i = 0; i < kept.size(); ++i) p.col(kept[i]) = u.col(i);
  if (lost.empty()) return p;
  for (std::size_t i = 0; i < lost.size(); ++i) rest.col(i) = raw.col(lost[i]);
  rest -= u * (u.transpose() * rest);  // into the complement of the weighted modes' span
  Eigen::MatrixXd completion;
  if (rest.colwise().norm().minCoeff() > 1e-9) {
    completion = polar_factor(rest);
  } else {
    const Eigen::JacobiSVD<Eigen::MatrixXd> full(u, Eigen::ComputeFullU);
    completion = full.matrixU().rightCols(lost.size());
  }
  for (std::size_t i = 0; i < lost.size(); ++i) {
    // the lost shape's sign kept (eq 48 does not depend on it; the JSON's eigenvectors do)
    const double sign = completion.col(i).dot(raw.col(lost[i])) < 0.0 ? -1.0 : 1.0;
    p.col(lost[i]) = sign * completion.col(i);
  }
  return p;
}

namespace {

void mapping_eq48(const Eigen::MatrixXd& m_half, const Eigen::MatrixXcd& shapes,
                  const Eigen::VectorXd& weight, const Eigen::VectorXd& eta2,
                  const Eigen::VectorXd& gamma, Eigen::MatrixXd& p, Eigen::MatrixXd& k,
                  Eigen::MatrixXd& c) {
  p = orthonormal_shapes(real_shapes(m_half, shapes), weight);  // eq 43: P^T P = I
  k = m_half * p * eta2.asDiagonal() * p.transpose() * m_half;
  c = m_half * p * (2.0 * gamma).asDiagonal() * p.transpose() * m_half;
}

void mapping_state_space(const Eigen::MatrixXd& m_half, const Eigen::MatrixXd& inertia,
                         const Eigen::MatrixXcd& shapes, const Eigen::VectorXd& eta2,
                         const Eigen::VectorXd& gamma, Eigen::MatrixXd& p, Eigen::MatrixXd& k,
                         Eigen::MatrixXd& c) {
  const int n = static_cast<int>(shapes.cols());
  Eigen::VectorXcd mu(n);
  for (int j = 0; j < n; ++j)
    mu(j) = Complex(-gamma(j), std::sqrt(std::max(0.0, eta2(j) - gamma(j) * gamma(j))));
  Eigen::MatrixXcd x(2 * n, 2 * n), y(n, 2 * n);
  x << shapes, shapes.conjugate(), shapes * mu.asDiagonal(), (shapes * mu.asDiagonal()).conjugate();
  y << shapes * mu.cwiseProduct(mu).asDiagonal(),
      (shapes * mu.cwiseProduct(mu).asDiagonal()).conjugate();
  // Bottom block of A [V; V mu] = [V; V mu] mu with A = [[0, I], [-M^-1 K, -M^-1 C]].
  const Eigen::MatrixXd kc = -(inertia.cast<Complex>() * y * x.inverse()).real();
  k = kc.leftCols(n);
  c = kc.rightCols(n);
  p = polar_factor(real_shapes(m_half, shapes));
}

// True when the symmetric matrix `s` has no eigenvalue below -1e-9 times its largest magnitude
// (round-off).
bool positive_semidefinite(const Eigen::MatrixXd& s) {
  const Eigen::VectorXd eig =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(s, Eigen::EigenvaluesOnly).eigenvalues();
  return eig.minCoeff() >= -1e-9 * eig.cwiseAbs().maxCoeff();
}

}  // namespace

ModalParametersResult modal_parameters(const DampedModesResult& modes,
                                       const std::vector<Eigen::MatrixXd>& inertia_kg_m2,
                                       const ModalParametersOptions& options) {
  const int n = static_cast<int>(modes.modes.size());
  const int t_count = static_cast<int>(modes.t_s.size());
  if (n == 0) throw InputError("modal parameters: no modes");
  const int c = static_cast<int>(modes.modes[0].shape.cols());
  if (n != c)
    throw InputError("modal parameters: " + std::to_string(n) + " modes for " + std::to_string(c) +
                     " channels; the inverse eigenproblem needs as many modes as channels");
  if (inertia_kg_m2.size() != 1 && static_cast<int>(inertia_kg_m2.size()) != t_count)
    throw InputError("modal parameters: inertia list has " + std::to_string(inertia_kg_m2.size()) +
                     " matrices; expected 1 or one per time (" + std::to_string(t_count) + ")");
  for (const auto& m : inertia_kg_m2)
    if (m.rows() != c || m.cols() != c)
      throw InputError("modal parameters: inertia matrices must be " + std::to_string(c) + "x" +
                       std::to_string(c));

  ModalParametersResult r;
  r.t_s = modes.t_s;
  r.gamma_per_s.resize(n, t_count);
  r.eta_squared_rad2_per_s2.resize(n, t_count);
  r.valid.resize(t_count);
  Eigen::MatrixXd m_half;
  for (int i = 0; i < t_count; ++i) {
    const Eigen::MatrixXd& inertia =
        inertia_kg_m2.size() == 1 ? inertia_kg_m2[0] : inertia_kg_m2[i];
    if (i == 0 || inertia_kg_m2.size() > 1) m_half = models::spd_sqrt(inertia);
    Eigen::MatrixXcd shapes(c, n);
    Eigen::VectorXd gamma(n), eta2(n);
    // Eq 43's weights: a valid mode's amplitude-to-noise power ratio (its shape's precision);
    // 0 for a mode flagged invalid.
    Eigen::VectorXd weight = Eigen::VectorXd::Zero(n);
    bool valid = true;
    for (int j = 0; j < n; ++j) {
      const ModeTrack& mt = modes.modes[j];
      const double w = mt.omega_rad_per_s(i), a = mt.alpha_per_s(i);
      const double w_dot = mt.omega_dot_rad_per_s2(i), a_dot = mt.alpha_dot_per_s2(i);
      gamma(j) = -a - w_dot / (2.0 * w);                // eq 45
      eta2(j) = w * w + a * a + a * w_dot / w - a_dot;  // eq 46 (alpha dot, see header)
      shapes.col(j) = mt.shape.row(i).transpose();
      if (mt.valid(i)) weight(j) = std::pow(10.0, mt.anr_db(i) / 10.0);
      valid = valid && mt.valid(i) && eta2(j) > gamma(j) * gamma(j);
    }
    r.gamma_per_s.col(i) = gamma;
    r.eta_squared_rad2_per_s2.col(i) = eta2;
    Eigen::MatrixXd p, k, d;
    if (options.mapping == ModalMapping::paper_eq48)
      mapping_eq48(m_half, shapes, weight, eta2, gamma, p, k, d);
    else
      mapping_state_space(m_half, inertia, shapes, eta2, gamma, p, k, d);
    if (options.symmetrize) {
      k = 0.5 * (k + k.transpose()).eval();
      d = 0.5 * (d + d.transpose()).eval();
    }
    // The joint stiffness of a limb holding a posture is positive definite, and its damping, a
    // passive viscosity, positive semidefinite (within round-off): an indefinite K(t) or C(t)
    // comes from tracks the data do not determine (e.g. two modes merged, or a mode whose
    // decay swings to growth; docs/tfa_modal.md, "Passive damping").
    r.valid(i) = valid && k.allFinite() && d.allFinite() &&
                 Eigen::LLT<Eigen::MatrixXd>(0.5 * (k + k.transpose())).info() == Eigen::Success &&
                 positive_semidefinite(0.5 * (d + d.transpose()));
    r.eigenvectors.push_back(std::move(p));
    r.stiffness.push_back(std::move(k));
    r.damping.push_back(std::move(d));
  }
  return r;
}

}  // namespace stiffid::estimators
