#pragma once
// Exact discretization of the linear endpoint model I x'' + B x' + K x = f (Perreault et al. 1999
// eq 15, any dimension n) for inputs sampled at a uniform rate and held between samples either
// constant (zero-order hold, like the shared reference case) or linear (first-order hold, the
// linear interpolation Perreault applied to the simulated signals). With the state s = [x; x'],
// s' = A s + G f, A = [0 I; -I^-1 K -I^-1 B], G = [0; I^-1], and the input on one sample step h
// f(t_k + tau) = f_k + w tau (w = 0 for ZOH, (f_{k+1} - f_k) / h for FOH), the exact update is
//   s_{k+1} = Phi s_k + Gamma0 f_k + Gamma1 w,
// with Phi, Gamma0, Gamma1 blocks of the matrix exponential of [[A, G, 0], [0, 0, Id], [0, 0, 0]] h
// (Van Loan's augmented-matrix method; Eigen's MatrixFunctions module computes the exponential).

#include <Eigen/Core>

#include "models/perturbation.hpp"

namespace stiffid::models {

struct LinearResponse {
  Eigen::MatrixXd position;  ///< (S x n) x, m
  Eigen::MatrixXd velocity;  ///< (S x n) x', m/s
};

/// Response of I x'' + B x' + K x = f to the force samples f (S x n, N) at `sample_rate_hz`,
/// from x(0) = x0 (n, m) and x'(0) = v0 (n, m/s). I (kg), B (N s/m), K (N/m) are (n x n); I must
/// be invertible. Exact for the chosen hold up to the accuracy of the matrix exponential.
LinearResponse simulate_linear_endpoint(const Eigen::MatrixXd& inertia_kg,
                                        const Eigen::MatrixXd& damping_ns_per_m,
                                        const Eigen::MatrixXd& stiffness_n_per_m,
                                        const Eigen::MatrixXd& force_n, double sample_rate_hz,
                                        InputHold hold, const Eigen::VectorXd& x0,
                                        const Eigen::VectorXd& v0);

}  // namespace stiffid::models
