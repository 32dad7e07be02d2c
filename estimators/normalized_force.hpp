#pragma once
// Stage 6 of the time-frequency identification: the normalised viscoelastic force of each mode
// (Piovesan et al. 2012 eq 49, in a dimensionally consistent form; derivation in docs/tfa.md).

#include <Eigen/Core>

#include "estimators/modal_analysis.hpp"
#include "estimators/ridge.hpp"

namespace stiffid::estimators {

/// Per frame and mode. Units: the normalised coordinates q = P^T M^1/2 delta theta are in
/// sqrt(kg) m rad (M^1/2 in sqrt(kg m^2) = sqrt(kg) m), forces per unit sqrt(kg) m.
struct NormalizedForceResult {
  Eigen::VectorXd time_s;          ///< [T] s
  Eigen::MatrixXd coordinate;      ///< (T x n) q_j at t_m, sqrt(kg) m rad
  Eigen::MatrixXd velocity;        ///< (T x n) dq_j/dt, sqrt(kg) m rad/s
  Eigen::MatrixXd force;           ///< (T x n) sigma_j = eta_j^2 q_j + 2 Gamma_j dq_j/dt,
                                   ///< sqrt(kg) m rad/s^2 (= -d^2 q_j/dt^2, eq 44)
  Eigen::MatrixXd envelope;        ///< (T x n) a_j, amplitude of q_j, sqrt(kg) m rad
  Eigen::MatrixXd envelope_force;  ///< (T x n) eta_j^2 a_j + 2 Gamma_j a_j', the consistent
                                   ///< form of eq 49's envelope (eq 49 prints eta_j, not eta_j^2)
};

/// q_j is the projection on p_j of the mode-j part of the deviations: q_j(t_m) =
/// p_j^T M^1/2 Re(c_j), dq_j/dt = p_j^T M^1/2 Re(lambda_j c_j) with c_j the complex amplitudes of
/// mode j in the joints (ridges.amplitude_c) and lambda_j = alpha_j + i omega_j (smoothed,
/// modal). For a second-order (Kelvin-Voigt) system sigma_j(q_j, dq_j/dt) is the straight line of
/// eq 44; departures from it show non-linear or higher-order internal forces.
NormalizedForceResult normalized_force(const RidgeResult& ridges, const ModalAnalysisResult& modal);

}  // namespace stiffid::estimators
