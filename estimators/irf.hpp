#pragma once
// Two-sided MIMO impulse response functions from correlations: Perreault et al. 1999, section 2.2
// (eqs 8-13) and Appendix (eqs 17-25); robust pseudo-inverse of Westwick & Kearney 1997.
//
// Model, in physical units (N inputs x_i, M outputs y_j, sampling step dt = 1/fs):
//   y_j(t) = dt * sum_i sum_{tau = A..B} h_ji(tau) x_i(t - tau),
// so h_ji is in (units of y_j) / ((units of x_i) s), e.g. m/(N s) for a compliance; lags A < 0 are
// the anticausal part. With phi as in correlation.hpp (biased, means removed), eq 9-11 read
//   phi_{x_i y_j}(tau) = dt * sum_k sum_s h_jk(s) phi_{x_i x_k}(tau - s),  tau, s = A..B,
// i.e. Psi H = Phi_xy with Psi the (N*L x N*L) block-Toeplitz input correlation matrix (block
// (i, k) holds phi_{x_i x_k}(tau - s) at row tau - A, column s - A; L = B - A + 1 lags), Phi_xy
// (N*L x M) and H (N*L x M) = dt * h. Psi is symmetric (phi_ki(d) = phi_ik(-d)) and positive
// semidefinite (it is Z^T Z / S for the zero-padded lagged-input matrix Z), so the full solve is a
// Cholesky factorisation solving all M outputs at once.

#include <Eigen/Core>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

/// How Psi H = Phi_xy is inverted.
enum class IrfInverse {
  full,  ///< Cholesky solve of the whole system (Perreault et al. eq 11)
  rank,  ///< pseudo-inverse keeping IrfOptions::rank eigenvectors (Westwick & Kearney 1997)
  mdl,   ///< pseudo-inverse keeping the number of eigenvectors that minimises the MDL
  /// truncated eigen-decomposition: eigenvectors in decreasing eigenvalue order, as many as
  /// minimise the same MDL. Never adds a weak direction before the stronger ones, so with output
  /// noise it cannot pick up a weakly excited direction whose noise (~1/sqrt(w_k) in h) ruins the
  /// IRF; it may drop weak directions that carry signal (bias).
  tsvd,
};
// The pseudo-inverses take Psi's eigenvalues and the projections of Phi_xy on its eigenvectors
// from SpectralProjection (spectral_projection.hpp), which never forms the eigenvectors: 10 min at
// 1 kHz, lags -0.1:0.5 s, 2 inputs (Psi 1202 x 1202): `stiffid irf --pinv mdl` 3.1 -> 1.7 s.

struct IrfOptions {
  int first_lag = 0;  ///< A, samples (negative: anticausal part), <= last_lag
  int last_lag = 0;   ///< B, samples
  IrfInverse inverse = IrfInverse::full;
  int rank = 0;  ///< eigenvectors kept when inverse == rank, in 1..N*L
  /// false: Psi is the block-Toeplitz matrix of the biased correlations (Perreault eq 11, the
  /// shared reference). true: Psi = Z^T Z / S for the lagged matrix Z of the zero-padded inputs,
  /// so H is the exact least-squares fit of the predicted outputs (`predicted`, hence the VAF and
  /// R^2 below) instead of an approximation of it whose edge terms (~L/S) the inverse amplifies
  /// by cond(Psi): with band-limited inputs and little noise the cross-term IRFs improve from
  /// ~90-99 % to >99.8 % VAF. Phi_xy is the same in both.
  bool least_squares = false;
};

struct IrfResult {
  Status status;  ///< failure when Psi is singular (full) or an output has no variance
  double sample_rate_hz = 0.0;  ///< fs, Hz
  int first_lag = 0;            ///< A, samples
  int last_lag = 0;             ///< B, samples
  int inputs = 0;               ///< N
  int outputs = 0;              ///< M
  Eigen::VectorXd lag_s;        ///< [L] lags A..B in s
  /// (N*L x M): h_ji(tau) at row i*L + (tau - A), column j, in output units per (input unit s).
  Eigen::MatrixXd h;
  /// (S x M) predicted outputs dt * sum h x over the record (inputs zero outside it), about the
  /// output means, output units.
  Eigen::MatrixXd predicted;
  /// [M] VAF of each output from the predicted outputs, %:
  /// 100 (1 - var(y_j - yhat_j) / var(y_j)) (eq 17 with E[] taken about the mean).
  Eigen::VectorXd vaf_percent;
  /// R^2 of all outputs from the predicted outputs, %: 100 (1 - sum_j sum_t (y_j - mean y_j -
  /// yhat_j)^2 / sum_j sum_t (y_j - mean y_j)^2) (eq 24).
  double r2_percent = 0.0;
  /// [M] VAF from correlations, eq 12 / 23 with this file's correlation convention:
  /// 100 * dt * sum_i sum_tau h_ji(tau) phi_{x_i y_j}(+tau) / phi_{y_j y_j}(0). Exactly the VAF of
  /// the zero-padded (autocorrelation-method) prediction, edges included; close to vaf_percent
  /// when the record is long against the lags.
  Eigen::VectorXd vaf_correlation_percent;
  double r2_correlation_percent = 0.0;  ///< eq 13 / 25, same convention, %
  int rank = 0;                         ///< eigenvectors of Psi used (N*L for the full solve)
  int full_rank = 0;                    ///< N*L
  /// Condition number of Psi: 2-norm (largest / smallest eigenvalue) for the pseudo-inverse, the
  /// Cholesky 1-norm estimate for the full solve; infinite when singular.
  double condition_number = 0.0;
  /// [K] MDL(m), m = 1..K usable eigenvectors (inverse == mdl only; empty otherwise).
  Eigen::VectorXd mdl;

  /// h_ji(tau) for tau = A..B ([L]), output units per (input unit s).
  Eigen::VectorXd irf(int output, int input) const;
};

/// Estimates the IRFs between N inputs (S x N) and M outputs (S x M) sampled at `sample_rate_hz`
/// (Hz) for lags options.first_lag..last_lag. Correlations come from one batched FFT of all
/// channels (correlation.hpp); the predicted outputs by blocked (overlap-add) convolution of the
/// same mean-removed inputs.
///
/// Pseudo-inverse (Westwick & Kearney 1997): Psi = V diag(w) V^T; eigenvector k contributes
/// c_kj = (v_k^T Phi_j)^2 / w_k / phi_{y_j y_j}(0) of the variance of output j (eq 19-21 on the
/// projected solution). Vectors are added in decreasing order of sum_j c_kj (`tsvd`: of w_k);
/// `rank` keeps the first ones. MDL (Rissanen 1978, as used by Westwick & Kearney 1997 and
/// Westwick & Kearney 2003 section 5.2.4): MDL(m) = (1 + p(m) ln(n) / n) V(m), V(m) = sum_j (1 -
/// sum_{k<=m} c_kj) the normalised residual variance from correlations, with the M outputs treated
/// as one record of n = S M samples and p(m) = m M parameters; for one output this is W&K's
/// criterion. Eigenvalues below N*L * eps * (largest) are never used.
///
/// Throws InputError on inconsistent sizes, first_lag > last_lag, S <= B - A, a non-positive
/// sample rate or a rank out of range. Numerical failure is reported in `status`.
IrfResult estimate_irf(const Eigen::Ref<const Eigen::MatrixXd>& inputs,
                       const Eigen::Ref<const Eigen::MatrixXd>& outputs, double sample_rate_hz,
                       const IrfOptions& options);

}  // namespace stiffid::estimators
