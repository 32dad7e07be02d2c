#pragma once
// Lumped-model fits to the time-varying estimates of `stiffid tfa` (issue 8, target c): the joint
// stiffness K(t), damping C(t) and inertia M(theta(t)) tracks of a single-trial time-frequency
// identification, with its modal amplitudes, summarized by constant joint matrices (joint space:
// kg m^2, N m s/rad, N m/rad, N m/rad^3) that fit them best in least squares over the valid
// frames of an interval.
//
// Kelvin-Voigt  M d'' + C d' + K d = tau:
//   minimize over A   sum_t || A_t - A ||_F^2   for A in {I = M, C, K} separately,
// whose solution is the frame mean of each track (closed form: no iterative solver is needed, so
// `termination` says "closed form" and `iterations` is 0). The mean of symmetric positive
// definite frames is symmetric positive definite; a mean that is not (indefinite tracks) is a
// failed fit, reported in `status`.
//
// Duffing  M d'' + C d' + K d + B d.^3 = tau (B diagonal): the free response's modal frequencies
// rise with its amplitude (the backbone). To first order in B (harmonic balance / averaging, modes
// at incommensurate frequencies), mode j of mass-normalized shape phi_j (the columns of
// Phi = M^-1/2 P, P the tfa eigenvectors) and normalized amplitude a_j (the envelope of
// q_j = p_j^T M^1/2 d, `normalized_force.envelope`) has
//   eta_j^2 = phi_j^T K phi_j + sum_i B_ii g_ij,
//   g_ij = phi_ij^2 (3/4 phi_ij^2 a_j^2 + 3/2 sum_{k!=j} phi_ik^2 a_k^2)
// (the cubic force's component at mode j's frequency, projected on the mode). The tfa stiffness
// K(t) = M^1/2 P diag(eta_j^2) P^T M^1/2 (eq 48) is therefore modelled as
//   K(t) = K + sum_i B_ii G_i(t),   G_i = M^1/2 P diag_j(g_ij) P^T M^1/2,
// linear in the n(n+1)/2 entries of K and the n entries of B: one linear least-squares problem
// over all frames (Householder QR; Frobenius norm, so off-diagonal entries weigh twice). C and I
// are frame means as for Kelvin-Voigt. The amplitudes must vary over the interval (a decaying free
// response) for K and B to be told apart; a rank-deficient or ill-conditioned system is a failure.
// B may come out negative (a softening limb). This is only as good as the tracks: it needs a tfa
// that follows the frequency's rise (the spectrogram method does; the damped-mode method assumes
// linear modes) and modes the trial excites; see docs/fitting.md.
//
// Poynting-Thomson is refused (InputError): the tfa tracks give two numbers per mode (eta_j^2 and
// Gamma_j at the mode's frequency), while K_S, K_P and C_P hold three symmetric matrices; the
// relaxation pole that would separate them is not tracked. Fit it to the trial instead.
//
// Standard errors: the frames of a tfa track are serially correlated (the tracks are smoothing
// splines sampled at the analysis rate), so the independent-residual formula s / sqrt(N) would be
// too small. Each entry's residual series is treated as AR(1) with lag-1 autocorrelation rho
// (estimated from the residuals, clipped to [0, 1)), which multiplies the variance of the mean by
// (1 + rho) / (1 - rho) (at most N): SE = s sqrt((1 + rho) / ((1 - rho) N)), s the residual
// standard deviation. For the Duffing K and B, the least-squares covariance s^2 (A^T A)^-1 is
// inflated by the largest factor of the K entries. vaf_percent per matrix (I, C, K order) is the
// share of the track's energy explained by the fit,
// 100 (1 - sum ||A_t - fit_t||^2 / sum ||A_t||^2); residual_rms the RMS of the entry residuals in
// the matrix's unit.

#include <Eigen/Core>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitting/lumped_fit.hpp"

namespace stiffid::fitting {

/// The tracks of a `stiffid tfa` JSON.
struct TfaTarget {
  std::string source;                                 ///< file name, for messages
  Eigen::VectorXd time_s;                             ///< [T] frame times, s
  std::vector<Eigen::MatrixXd> stiffness_nm_per_rad;  ///< [T] (n x n) K(t), N m/rad (NaN: null)
  std::vector<Eigen::MatrixXd> damping_nms_per_rad;   ///< [T] (n x n) C(t), N m s/rad
  std::vector<Eigen::MatrixXd> inertia_kg_m2;         ///< [T] (n x n) M(theta(t)), kg m^2
  std::vector<bool> valid;                            ///< [T] K_valid and every mode's "valid" (all
                                                      ///< true when the file has neither)
  std::vector<Eigen::MatrixXd> eigenvectors;          ///< [T] (n x n) P(t), columns = modes
                                              ///< (orthonormal; empty when the file has none)
  Eigen::MatrixXd envelope;     ///< (T x n) a_j(t), amplitude of the normalized
                                ///< modal coordinate q_j, sqrt(kg) m rad (0 x 0
                                ///< when the file has none)
  bool chirped_frames = false;  ///< made with the spectrogram's chirped frame fits ("options":
                                ///< {"chirp": true}), which move the Duffing backbone's B
};

/// Reads the JSON of `stiffid tfa` (keys t_s, K_nm_per_rad, C_nms_per_rad, M_kg_m2 as [r][c][T],
/// optional K_valid [T], valid [j][T], eigenvectors [r][c][T], normalized_force.envelope [j][T],
/// options.chirp; null entries read as NaN). Throws InputError naming the file and key on
/// anything missing or malformed.
TfaTarget read_tfa_json(const std::string& path);

struct TfaFitOptions {
  LumpedModel model = LumpedModel::kelvin_voigt;
  double from_s = -std::numeric_limits<double>::infinity();  ///< first frame time used, s
  double to_s = std::numeric_limits<double>::infinity();     ///< last frame time used, s
};

struct TfaFitResult {
  LumpedFitResult fit;   ///< target "tfa": parameters I, C, K (joint units), vaf, status
  int frames = 0;        ///< frames used (valid, finite, inside the interval)
  double first_s = 0.0;  ///< time of the first frame used, s
  double last_s = 0.0;   ///< time of the last frame used, s
  /// [I, C, K(, B)] (n x n) variance inflation (1 + rho) / (1 - rho) applied to each entry's SE.
  std::vector<Eigen::MatrixXd> variance_inflation;
};

/// Fits the constant Kelvin-Voigt or Duffing joint matrices to the tracks (see the top of this
/// file). Throws InputError on Poynting-Thomson, an empty interval, fewer than 3 usable frames, or
/// (Duffing) a file without eigenvectors and envelopes; a fitted I, C or K that is not positive
/// definite, or (Duffing) K and B that the tracks cannot tell apart, is a failure in fit.status.
TfaFitResult fit_tfa(const TfaTarget& target, const TfaFitOptions& options);

/// to_json(result.fit) plus "frames", "interval_s" [first, last], "vaf_of" (matrix names of
/// vaf_percent and residual_rms) and "variance_inflation" {NAME: [[...]]}.
nlohmann::json to_json(const TfaFitResult& result);

}  // namespace stiffid::fitting
