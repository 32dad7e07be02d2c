#pragma once
// Fits of lumped models (fitting/lumped_model.hpp: Kelvin-Voigt, Poynting-Thomson, Duffing; 1 to 8
// DOF) to a time-series trial: forces in (N), displacements out (m), simulate-and-compare
// residuals with exact derivatives (Ceres jets through the RK4 simulation), multiple shooting,
// Ceres Levenberg-Marquardt from a seeded Latin-hypercube multi-start, Ceres covariance for
// standard errors. See docs/fitting.md for the method in full.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "data/trial.hpp"
#include "fitting/lumped_model.hpp"

namespace ceres {
class Problem;
}

namespace stiffid::fitting {

/// Sampling range of the diagonal entries of one matrix for the multi-start. SPD matrices are
/// sampled log-uniformly (lower > 0), B (Duffing) uniformly (any sign). Units of the matrix.
struct StartRange {
  double lower = 0.0;
  double upper = 0.0;
};

struct LumpedFitOptions {
  LumpedModel model = LumpedModel::kelvin_voigt;
  InputHold hold = InputHold::first_order;
  /// Local solves: start 0 is the centre of the box (geometric centre for SPD matrices), starts
  /// 1..starts-1 a Latin hypercube over the box drawn from `seed`. Off-diagonals start at 0.
  int starts = 16;
  std::uint64_t seed = 0;
  /// Box per matrix name ("I", "C", ...) overriding the data-driven default (see default_ranges).
  std::map<std::string, StartRange> ranges;
  /// Multiple-shooting segment length, s: the trial is cut into segments of about this length,
  /// each with its own initial state; <= 0 or longer than the trial: single shooting.
  double segment_s = 1.0;
  /// Weight of the continuity residuals (state at a segment's end minus the next segment's initial
  /// state, each divided by the output's RMS or the velocity's RMS) relative to the data residuals.
  /// The solve runs first with weight 1 (segments free to disagree), then with this weight.
  double continuity_weight = 1e3;
  /// RK4 steps per sampling interval; 0 = automatic: the smallest count with h * r <= step_target,
  /// r the fastest rate of the model (sqrt of the largest eigenvalue of I^-1 K, of I^-1 C, of
  /// CP^-1 (KS + KP), with Duffing's K + 3 B max(x^2)), re-checked after a converged solve (at most
  /// 256).
  int substeps = 0;
  double step_target = 0.05;  ///< dimensionless h * rate; RK4 global error ~ (h r)^4 r T / 120
  int max_iterations = 200;   ///< per local solve stage
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-14;
  double parameter_tolerance = 1e-12;
};

/// A fitted matrix with its standard errors (delta method through the parameterization).
struct FittedMatrix {
  std::string name;           ///< "I", "C", "K", "B", "KS", "KP", "CP"
  std::string unit;           ///< "kg", "N s/m", "N/m", "N/m^3"
  Eigen::MatrixXd value;      ///< (n x n), symmetric
  Eigen::MatrixXd std_error;  ///< (n x n), NaN when the covariance could not be computed
};

struct LumpedFitResult {
  LumpedModel model = LumpedModel::kelvin_voigt;
  std::string target = "trial";  ///< "trial" (time series), "frf" (frf_fit.hpp) or "tfa"
                                 ///< (tfa_fit.hpp: vaf and residual RMS per matrix)
  int dof = 0;
  std::vector<FittedMatrix> parameters;  ///< in model_matrices order
  Eigen::VectorXd vaf_percent;           ///< [n] variance accounted for per output, %
  Eigen::VectorXd residual_rms_m;        ///< [n] RMS of measured minus simulated output, m (for
                                         ///< an FRF target: of |H_model - H_est|, m/N)
  Status status;                         ///< ok when the best start converged
  std::string termination;               ///< Ceres termination type and message of the best start
  int iterations = 0;                    ///< LM iterations of the best start (all stages)
  int starts = 0;                        ///< local solves run
  int substeps = 0;                      ///< RK4 steps per sampling interval used at the end
  int segments = 0;                      ///< multiple-shooting segments
  bool standard_errors_ok = false;       ///< false when the covariance was rank deficient
  double cost = 0.0;                     ///< 1/2 sum of squared weighted data residuals
  Eigen::VectorXd theta;                 ///< fitted parameter vector (lumped_model.hpp)
  Eigen::MatrixXd segment_states;        ///< (segments x state_size) fitted initial states
  Eigen::MatrixXd simulated_m;           ///< (S x n) simulated outputs with the fitted values
};

/// Data-driven default start box: with RMS values over all channels of the force f, displacement
/// x, velocity x' and acceleration x'' (central differences), I in [r/10, 10 r] with r = f/x'',
/// K, KS, KP in [r/10, 10 r] with r = f/x, C, CP in [r/100, 10 r] with r = f/x', B in [0, r] with
/// r = f/RMS(x^3).
std::map<std::string, StartRange> default_ranges(LumpedModel model, const Eigen::MatrixXd& inputs_n,
                                                 const Eigen::MatrixXd& outputs_m,
                                                 double sample_rate_hz);

/// Fits a lumped model to inputs (S x n forces, N) and outputs (S x n displacements, m) sampled at
/// sample_rate_hz. Throws InputError on bad input (sizes, non-finite samples, a zero channel, bad
/// options); a solver failure or non-convergence is reported in `status`.
LumpedFitResult fit_lumped(const Eigen::MatrixXd& inputs_n, const Eigen::MatrixXd& outputs_m,
                           double sample_rate_hz, const LumpedFitOptions& options);
/// Same on named channels of a trial.
LumpedFitResult fit_lumped(const data::Trial& trial, const std::vector<std::string>& inputs,
                           const std::vector<std::string>& outputs,
                           const LumpedFitOptions& options);

/// Simulated outputs (S x n, m) of a model with parameter vector theta from initial state z0
/// (state_size), inputs (S x n, N) at sample_rate_hz, with `substeps` RK4 steps per interval.
Eigen::MatrixXd simulate_lumped(LumpedModel model, const Eigen::VectorXd& theta,
                                const Eigen::VectorXd& z0, const Eigen::MatrixXd& inputs_n,
                                double sample_rate_hz, InputHold hold, int substeps);

/// Start points of the multi-start: point 0 the centre of the box (geometric for SPD matrices), the
/// others a Latin hypercube from `seed`; diagonal entries only (off-diagonals 0).
std::vector<Eigen::VectorXd> start_points(LumpedModel model, int n,
                                          const std::map<std::string, StartRange>& ranges,
                                          int starts, std::uint64_t seed);

/// d(matrix entries)/d(theta): (matrices * n^2 x P), rows matrix by matrix, entries row-major.
Eigen::MatrixXd entries_jacobian(LumpedModel model, const Eigen::VectorXd& theta, int n);

/// Fills result.parameters (values and standard errors) from result.theta, result.cost and the
/// Jacobian of `problem` at its current values: Cov(theta) = sigma^2 (J^T J)^-1, sigma^2 =
/// 2 cost / dof_left, through the SVD of the column-scaled Jacobian (rank test 1e-10), entries by
/// the delta method; NaN standard errors and standard_errors_ok false when rank deficient.
/// `blocks` lists the problem's parameter blocks, theta first.
void set_parameters(LumpedFitResult& result, ceres::Problem& problem,
                    const std::vector<double*>& blocks, double dof_left);

/// Reads a start box file: a JSON object {NAME: [lower, upper], ...} with NAME among the model's
/// matrices. Throws InputError naming the file and key on anything else.
std::map<std::string, StartRange> read_ranges_json(const std::string& path, LumpedModel model);

/// The JSON of `stiffid fit` (issue 8): model, dof, parameters {NAME: {value, std_error, unit}},
/// vaf_percent, status, termination, iterations, starts, plus message, residual_rms_m, substeps,
/// segments.
nlohmann::json to_json(const LumpedFitResult& result);

}  // namespace stiffid::fitting
