#pragma once
// Perreault, Kirsch & Acosta 1999, "Multiple-input, multiple-output system identification for
// characterization of limb stiffness dynamics", section 4 reproduced as a study:
// - the cell evaluator "mimo_identification": simulate a stochastic endpoint trial (linear
//   endpoint model, eq 15, or nonlinear arm, eq 14), identify the 2x2 dynamic compliance with the
//   H1 FRF (eqs 1-7) and the two-sided IRF (eqs 8-13), and score them against the exact truth;
// - the reporter "perreault1999": Tables 1-2, Fig 6B and Fig 9 with the paper's values beside ours.
// The study itself is the file validation/studies/perreault1999.json (`stiffid study
// perreault1999`).

#include <Eigen/Core>
#include <complex>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/arm.hpp"
#include "validation/study.hpp"

namespace stiffid::validation {

/// Linear endpoint impedance of eq 15: I x'' + B x' + K x = f, each (n x n).
struct EndpointImpedance {
  Eigen::MatrixXd inertia_kg;
  Eigen::MatrixXd damping_ns_per_m;
  Eigen::MatrixXd stiffness_n_per_m;
};

/// Linearized endpoint impedance of the arm at a posture, eq 16 (no load):
/// X_end = J^-T X_jnt J^-1 for X = M(theta) (kg m^2 -> kg), B_jnt (N m s/rad -> N s/m) and K_jnt
/// (N m/rad -> N/m); all (2 x 2).
EndpointImpedance arm_endpoint_impedance(const models::ArmParameters& arm,
                                         const Eigen::Vector2d& theta_rad,
                                         const Eigen::Matrix2d& joint_damping_nms_per_rad,
                                         const Eigen::Matrix2d& joint_stiffness_nm_per_rad);

/// Exact impulse response of the compliance of eq 15 for forces sampled at `sample_rate_hz` and
/// linearly interpolated between samples (first-order hold, as Perreault's simulated signals), in
/// the physical-units convention of the IRF estimator, y(k) = dt * sum_tau h(tau) f(k - tau):
/// with the exact FOH discretization s_{k+1} = Phi s_k + Gamma0 f_k + Gamma1 (f_{k+1} - f_k)/dt
/// (matrix exponential), h(0) = C Gamma1 / dt^2, h(tau) = C Phi^(tau-1) (Gamma0 + (Phi - I)
/// Gamma1 / dt) / dt for tau >= 1, and 0 for tau < 0 (causal system).
/// Layout as estimators::IrfResult::h: (n*L x n), h_ji(tau) at row i*L + (tau - first_lag),
/// column j; m/(N s).
Eigen::MatrixXd true_compliance_irf(const EndpointImpedance& model, double sample_rate_hz,
                                    int first_lag, int last_lag);

/// The transfer matrix of the same sampled system at `frequency_hz` [F] (Hz), m/N:
/// H(f) = dt * sum_{tau >= 0} h(tau) exp(-i 2 pi f tau dt), summed until the response has decayed
/// below 1e-12 of its peak; [F] of (n x n), H(f)(j, i) from input i to output j.
std::vector<Eigen::MatrixXcd> true_compliance_frf(const EndpointImpedance& model,
                                                  double sample_rate_hz,
                                                  const Eigen::VectorXd& frequency_hz);

/// Cell evaluator "mimo_identification". Trial spec keys (all optional):
///   "model": "endpoint" (eq 15 with the shared reference case's I, B, K) or "arm" (eq 14 at a
///            Fig 6 posture with models::perreault_joint_viscoelasticity()), default endpoint;
///   "position": Fig 6 posture 1..4 (arm), default 1;
///   "coupling_percent": input coupling, % of the variance of fy linearly related to fx, [0, 99];
///   "snr_db": output SNR by RMS, dB (absent: no noise);
///   "duration_s" (60), "sample_rate_hz" (50);
///   "nfft": Welch segment length, samples (256); "overlap": fraction (0.5);
///   "irf_lags_s": [first, last] IRF lags, s ([-0.2, 1.5]);
///   "band_hz": [low, high], band of the coherence and FRF summaries, Hz ([0.5, 8]);
///   "estimators": subset of ["frf", "irf"] (both).
/// Metrics (h_ji: output j of (x, y) from input i of (fx, fy), as in the paper):
///   irf: "r2_percent" (eq 24 from the predicted outputs), "vaf_x_percent", "vaf_y_percent"
///        (eq 17), "irf_vaf_hji_percent" (VAF of the estimated IRF about the true one, eq 17 over
///        the lag window);
///   frf: "frf_vaf_hji_percent" (100 (1 - sum |H^ - H|^2 / sum |H|^2) over the band's bins),
///        "multiple_coherence_x_mean", "multiple_coherence_y_mean", "partial_coherence_hji_mean"
///        (means over the band), "segments".
/// Numerical failures of the simulator or estimators are returned as the cell's status.
CellOutcome mimo_identification_evaluator(const nlohmann::json& spec, std::uint64_t seed);

/// Reporter "perreault1999": report.md, table1_coupling.csv, table2_snr.csv, fig6b_positions.csv
/// and fig9_segments.csv (the paper's values beside ours, mean and SD over replicates, and the
/// issue's acceptance criteria), plus the generic summary.csv. Designs it does not find are left
/// out of the report.
void write_perreault1999_report(const StudySpec& spec, const std::vector<ResultRow>& rows,
                                const std::string& folder);

}  // namespace stiffid::validation
