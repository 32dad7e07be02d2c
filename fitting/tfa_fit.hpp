#pragma once
// Lumped-model fit to the time-varying estimates of `stiffid tfa` (issue 8, target c): the joint
// stiffness K(t), damping C(t) and inertia M(theta(t)) tracks of a single-trial time-frequency
// identification, summarized by the constant Kelvin-Voigt joint matrices
//   M d'' + C d' + K d = tau     (joint space: kg m^2, N m s/rad, N m/rad)
// that fit them best in least squares over the valid frames of an interval:
//   minimize over A   sum_t || A_t - A ||_F^2   for A in {I = M, C, K} separately,
// whose solution is the frame mean of each track (closed form: no iterative solver is needed, so
// `termination` says "closed form" and `iterations` is 0). The mean of symmetric positive
// definite frames is symmetric positive definite; a mean that is not (indefinite tracks) is a
// failed fit, reported in `status`.
//
// Standard errors: the frames of a tfa track are serially correlated (the tracks are smoothing
// splines sampled at the analysis rate), so the independent-residual formula s / sqrt(N) would be
// too small. Each entry's residual series is treated as AR(1) with lag-1 autocorrelation rho
// (estimated from the residuals, clipped to [0, 1)), which multiplies the variance of the mean by
// (1 + rho) / (1 - rho) (at most N): SE = s sqrt((1 + rho) / ((1 - rho) N)), s the residual
// standard deviation. vaf_percent per matrix (I, C, K order) is the share of the track's energy
// explained by the constant, 100 (1 - sum ||A_t - A||^2 / sum ||A_t||^2); residual_rms the RMS of
// the entry residuals in the matrix's unit.
//
// Poynting-Thomson and Duffing are refused (InputError): the modal K(t), C(t) of such a limb are
// frequency- (PT) or amplitude-dependent (Duffing) equivalents of each mode, which a constant
// matrix fit of those models cannot be read from; fit them to the trial instead.

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fitting/lumped_fit.hpp"

namespace stiffid::fitting {

/// The tracks of a `stiffid tfa` JSON.
struct TfaTarget {
  std::string source;                            ///< file name, for messages
  Eigen::VectorXd time_s;                        ///< [T] frame times, s
  std::vector<Eigen::MatrixXd> stiffness_nm_per_rad;  ///< [T] (n x n) K(t), N m/rad (NaN: null)
  std::vector<Eigen::MatrixXd> damping_nms_per_rad;   ///< [T] (n x n) C(t), N m s/rad
  std::vector<Eigen::MatrixXd> inertia_kg_m2;         ///< [T] (n x n) M(theta(t)), kg m^2
  std::vector<bool> valid;                       ///< [T] K_valid (all true when the file has none)
};

/// Reads the JSON of `stiffid tfa` (keys t_s, K_nm_per_rad, C_nms_per_rad, M_kg_m2 as [r][c][T],
/// optional K_valid [T]; null entries read as NaN). Throws InputError naming the file and key on
/// anything missing or malformed.
TfaTarget read_tfa_json(const std::string& path);

struct TfaFitOptions {
  LumpedModel model = LumpedModel::kelvin_voigt;
  double from_s = -std::numeric_limits<double>::infinity();  ///< first frame time used, s
  double to_s = std::numeric_limits<double>::infinity();     ///< last frame time used, s
};

struct TfaFitResult {
  LumpedFitResult fit;           ///< target "tfa": parameters I, C, K (joint units), vaf, status
  int frames = 0;                ///< frames used (valid, finite, inside the interval)
  double first_s = 0.0;          ///< time of the first frame used, s
  double last_s = 0.0;           ///< time of the last frame used, s
  /// [I, C, K] (n x n) variance inflation (1 + rho) / (1 - rho) applied to each entry's SE.
  std::vector<Eigen::MatrixXd> variance_inflation;
};

/// Fits the constant Kelvin-Voigt joint matrices to the tracks (see the top of this file). Throws
/// InputError on a model other than KV, an empty interval, or fewer than 3 usable frames; a mean
/// matrix that is not positive definite is a failure in fit.status.
TfaFitResult fit_tfa(const TfaTarget& target, const TfaFitOptions& options);

/// to_json(result.fit) plus "frames", "interval_s" [first, last], "vaf_of" (matrix names of
/// vaf_percent and residual_rms) and "variance_inflation" {NAME: [[...]]}.
nlohmann::json to_json(const TfaFitResult& result);

}  // namespace stiffid::fitting
