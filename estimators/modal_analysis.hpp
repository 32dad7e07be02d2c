#pragma once
// Stage 5 of the time-frequency identification (Piovesan et al. 2012, "Identification of
// eigenvectors" and "System Decoupling and Modal Analysis", eqs 23-48): from the smoothed modal
// frequencies and amplitudes to the eigenvector matrix P(t) of the mass-normalised system and the
// joint stiffness and damping matrices K_theta(t), C_theta(t).

#include <Eigen/Core>
#include <vector>

#include "data/error.hpp"
#include "estimators/ridge.hpp"
#include "estimators/savitzky_golay.hpp"

namespace stiffid::estimators {

struct ModalAnalysisOptions {
  SavitzkyGolayOptions smoothing;  ///< stage 4: Piovesan 2012 used order 3 over 0.25 s
};

/// Everything per frame t_m (T frames, n modes = n joints).
struct ModalAnalysisResult {
  Eigen::VectorXd time_s;                   ///< [T] s
  Eigen::MatrixXd omega_rad_per_s;          ///< (T x n) smoothed omega_j, rad/s
  Eigen::MatrixXd omega_dot_rad_per_s2;     ///< (T x n) d omega_j / dt, rad/s^2
  Eigen::MatrixXd amplitude;                ///< (T x n) smoothed A_j = |A_j.| over channels, rad
  Eigen::MatrixXd alpha_per_s;              ///< (T x n) alpha_j = d ln A_j / dt, 1/s (eq 47)
  Eigen::MatrixXd alpha_dot_per_s2;         ///< (T x n) d alpha_j / dt, 1/s^2
  Eigen::MatrixXd gamma_per_s;              ///< (T x n) Gamma_j = -alpha_j - omega_j'/(2 omega_j),
                                            ///< 1/s (eq 45)
  Eigen::MatrixXd eta_squared_per_s2;       ///< (T x n) eta_j^2 = omega^2 + alpha^2
                                            ///< + alpha omega'/omega - alpha', 1/s^2 (eq 46)
  Eigen::MatrixXd phase_difference_rad;     ///< (T x n) rho_j: phase of mode j in each channel
                                            ///< relative to its strongest channel, folded into
                                            ///< (-pi/2, pi/2] (non-classical damping, eqs 41-42);
                                            ///< for 2 joints, the elbow relative to the shoulder
  Eigen::MatrixXd time_lag_s;               ///< (T x n) Delta_j = rho_j / omega_j, s (eq 42)
  std::vector<Eigen::MatrixXd> mode_shape;  ///< [T] (n x n) joint-space mode shapes phi_j
                                            ///< (columns), from eqs 37 and 41, unit norm
  std::vector<Eigen::MatrixXd> eigenvectors;  ///< [T] (n x n) P: orthonormal eigenvectors of the
                                              ///< normalised stiffness (columns, eq 43)
  std::vector<Eigen::MatrixXd> inertia_sqrt;  ///< [T] (n x n) M^1/2, sqrt(kg) m (eq 24)
  std::vector<Eigen::MatrixXd> stiffness_nm_per_rad;  ///< [T] (n x n) K_theta, N m/rad (eq 48)
  std::vector<Eigen::MatrixXd> damping_nms_per_rad;   ///< [T] (n x n) C_theta, N m s/rad (eq 48)
  /// [T] the smoothed mode shapes at frame t are separated: M^1/2 phi_j span the joint space
  /// (smallest singular value >= 1e-6 of the largest), so P, K_theta and C_theta are defined.
  /// Where false (the shapes are parallel: two ridges on one mode) the frame's K and C mean
  /// nothing; the spectrogram method's `valid` is false there.
  Eigen::Array<bool, Eigen::Dynamic, 1> separated;
  Status status;  ///< failure when the ridges failed, no frame is separated, or eta^2 non-finite
};

/// Modal analysis of tracked ridges (channels = joints = modes = n) with the inertia M(theta(t_m))
/// of every frame (kg m^2, n x n, symmetric positive definite).
///  - Smoothing (stage 4): omega_j and ln A_j by Savitzky-Golay with their first and second
///    derivatives; alpha_j is the derivative of ln A_j (eq 47).
///  - Gamma_j and eta_j^2 by eqs 45-46 with the derivative of alpha_j where the paper prints its
///    second derivative: substituting q = A cos(phi), A' = alpha A, phi' = omega into
///    q'' + 2 Gamma q' + eta^2 q = 0 gives, from the sine terms, eq 45, and from the cosine terms
///    eta^2 = omega^2 - alpha^2 - alpha' - 2 Gamma alpha = omega^2 + alpha^2 + alpha omega'/omega
///    - alpha' (docs/tfa.md).
///  - Mode shapes phi_jk = A_jk cos(phase_jk - phase_j,ref) (eqs 37, 41: amplitude ratios, with
///    the sign and the projection of the non-classical phase difference), smoothed; normalised
///    eigenvectors p_j = M^1/2 phi_j / |M^1/2 phi_j| (eq 24) made orthonormal, as P^T P = I of
///    eq 43 requires, by the nearest orthogonal matrix with each mode weighted by its
///    amplitude-to-noise power ratio at the frame (ridges.anr_db; alike without it): a weak
///    mode's noisy shape moves P less than a strong one's (orthonormal_shapes,
///    modal_parameters.hpp; docs/tfa_modal.md, "Eq 43 weighted by the modes' ANR").
///  - K_theta = M^1/2 P diag(eta^2) P^T M^1/2, C_theta = M^1/2 P diag(2 Gamma) P^T M^1/2 (eq 48,
///    whose left-hand sides are the joint, not the normalised, matrices).
/// Throws InputError when the channel count differs from the mode count or the inertia list does
/// not have one matrix per frame; frames the ridges could not resolve give NaN and a failed status.
ModalAnalysisResult modal_analysis(const RidgeResult& ridges,
                                   const std::vector<Eigen::MatrixXd>& inertia_kg_m2,
                                   const ModalAnalysisOptions& options);

}  // namespace stiffid::estimators
