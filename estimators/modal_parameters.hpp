#pragma once
// Modal analysis of Piovesan 2012 eqs 43-48 from the damped-mode tracks of the `modal` tfa method
// (damped_modes.hpp): the decoupled coefficients Gamma_j(t), eta_j^2(t) of each mode and the joint
// stiffness K(t) and damping C(t) matrices. Stand-in for the spectrogram pipeline's stage 5
// (issue 6) until the two are merged; see docs/tfa_modal.md.
//
// Eqs 45-46, with alpha = Re(pole) (eq 47 sign, < 0 decays):
//   Gamma_j = -alpha_j - omegadot_j / (2 omega_j)                               (eq 45)
//   eta_j^2 = omega_j^2 + alpha_j^2 + alpha_j omegadot_j / omega_j - alphadot_j   (eq 46)
// eq 46 as printed has "- alpha double-dot"; substituting q = Re exp(int (alpha + i omega)) into
// q'' + 2 Gamma q' + eta^2 q = 0 gives the real part alphadot + alpha^2 - omega^2 + 2 Gamma alpha +
// eta^2 = 0, i.e. "- alpha dot", which is used here.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "estimators/damped_modes.hpp"

namespace stiffid::estimators {

enum class ModalMapping {
  /// Eq 48 (the default): real eigenvector matrix P from the mode shapes normalized by M^1/2 (each
  /// rotated to its most real phase, eqs 38-41, then the nearest orthogonal matrix, eq 43), K =
  /// M^1/2 P diag(eta^2) P^T M^1/2 and C = M^1/2 P diag(2 Gamma) P^T M^1/2. Exact for classical
  /// damping; the shapes' non-classical phases are dropped, which keeps their noise out of C.
  /// P is the weighted nearest orthogonal matrix (orthonormal_shapes below), each mode weighted
  /// by its amplitude-to-noise power ratio: a weak mode's noisy shape moves P less than a strong
  /// mode's (docs/tfa_modal.md, "Eq 43 weighted by the modes' ANR"). At a time where some modes
  /// are flagged invalid (sunk into the noise), their weight is zero: P's columns for the valid
  /// modes come from their shapes alone and the others complete them in the orthogonal
  /// complement, not from their extrapolated shapes (docs/tfa_modal.md, "A lost mode's shape").
  paper_eq48,
  /// Second-order inverse eigenproblem: with the effective poles mu_j = -Gamma_j +
  /// i sqrt(eta_j^2 - Gamma_j^2) and complex mode shapes V (C x n, n = C), the state matrix has
  /// eigenvectors [V; V mu], so [K C] = -M [V mu^2, conj] [[V, conj], [V mu, conj]]^-1 (real
  /// part). Reduces to eq 48 for classical damping; exact for non-classical (eq 55) damping too,
  /// but C then rests on the shapes' phases, and their noise (docs/tfa_modal.md, "Mapping").
  state_space,
};

/// "eq48" or "state_space"; throws InputError otherwise. (Inline: the command line parses it.)
inline ModalMapping parse_modal_mapping(const std::string& text) {
  if (text == "eq48") return ModalMapping::paper_eq48;
  if (text == "state_space") return ModalMapping::state_space;
  throw InputError("--mapping: unknown mapping '" + text + "'; expected eq48 or state_space");
}
inline std::string to_string(ModalMapping mapping) {
  return mapping == ModalMapping::state_space ? "state_space" : "eq48";
}

struct ModalParametersOptions {
  ModalMapping mapping = ModalMapping::paper_eq48;
  bool symmetrize = true;  ///< report (K + K^T)/2 and (C + C^T)/2 (a passive network is symmetric)
};

struct ModalParametersResult {
  Eigen::VectorXd t_s;                        ///< [T] s, as the tracks
  Eigen::MatrixXd gamma_per_s;                ///< (n x T) Gamma_j(t), eq 45, 1/s
  Eigen::MatrixXd eta_squared_rad2_per_s2;    ///< (n x T) eta_j^2(t), eq 46, rad^2/s^2
  std::vector<Eigen::MatrixXd> eigenvectors;  ///< [T] (C x n) real P(t) of eq 43 (M^1/2-normalized
                                              ///< coordinates, orthonormal columns)
  std::vector<Eigen::MatrixXd> stiffness;     ///< [T] (C x C) joint stiffness K(t), N m/rad when
                                              ///< channels are rad and inertia kg m^2
  std::vector<Eigen::MatrixXd> damping;       ///< [T] (C x C) joint damping C(t), N m s/rad
  Eigen::Array<bool, Eigen::Dynamic, 1> valid;  ///< [T] every mode valid at t, eta^2 > Gamma^2,
                                                ///< K(t) positive definite and C(t) positive
                                                ///< semidefinite
};

/// Eq 43's P (C x n, orthonormal columns, n <= C) from the real M^1/2-normalized mode shapes
/// `raw` (C x n, unit columns) and a weight per shape (its precision, e.g. the mode's amplitude-
/// to-noise power ratio; only ratios matter). The modes of positive weight get the P that
/// minimizes sum_j weight_j |P e_j - raw_j|^2 (weighted orthogonal Procrustes: the polar factor
/// of raw diag(weight)); the columns of zero (or non-finite) weight complete them in the
/// orthogonal complement of their span (the lost shapes projected onto it, their sign kept). All
/// weights zero: the unweighted polar factor. Throws InputError when the sizes differ.
Eigen::MatrixXd orthonormal_shapes(const Eigen::MatrixXd& raw, const Eigen::VectorXd& weight);

/// K(t), C(t) from the tracks. `inertia_kg_m2` holds M(theta(t)) ((C x C) SPD) for every time of
/// `modes.t_s`, or one matrix for all. Throws InputError when the number of modes differs from the
/// number of channels or the inertia list has the wrong length or size.
ModalParametersResult modal_parameters(const DampedModesResult& modes,
                                       const std::vector<Eigen::MatrixXd>& inertia_kg_m2,
                                       const ModalParametersOptions& options);

}  // namespace stiffid::estimators
