#pragma once
// The H1 transfer-function matrix of a MIMO system from Welch spectra, with ordinary, multiple and
// partial coherences, the condition of the input spectral matrix, Bendat & Piersol random-error
// bands, and the compliance-to-stiffness inversion. Perreault et al. 1999, section 2, eqs 1-7.
//
// Notation: N inputs x_i, M outputs y_j, F one-sided frequencies. Spectra follow scipy.signal.csd:
// Gxx[i][k] = E[conj(X_i) X_k] (N x N, Hermitian), Gxy[i][j] = E[conj(X_i) Y_j] (N x M).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "data/trial.hpp"
#include "estimators/spectra.hpp"

namespace stiffid::estimators {

struct FrfOptions {
  WelchOptions welch;
  /// Inputs count as perfectly coupled at a frequency when the reciprocal 2-norm condition
  /// (lambda_min / lambda_max) of the input coherence matrix D^-1/2 Gxx D^-1/2 (D = diag Gxx,
  /// dimensionless, so independent of units and input power) is below this. For two inputs it is
  /// (1 - |gamma_12|) / (1 + |gamma_12|): 1e-8 means gamma_12^2 > 1 - 4e-8, far beyond any real
  /// coupling (75 % coupling gives 0.14) yet above the 1e-16..1e-20 of an exact copy fy = a fx
  /// written with 10 or more significant digits.
  double min_reciprocal_condition = 1e-8;
  /// A frequency is inside the band with input power when every input's autospectrum there is at
  /// least this fraction of that input's peak over frequency (1e-6: within 60 dB). Coupling is
  /// judged only there: outside, Gxx holds little more than round-off and H is not determined.
  double band_power_fraction = 1e-6;
  /// Multiplier c of the random-error bands value (1 -/+ c eps); 2 gives about 95 % for
  /// approximately normal errors (z = 1.96 rounded up).
  double confidence_factor = 2.0;
  /// false: n_d = segments averaged, as Bendat & Piersol's formulas assume independent segments.
  /// true: n_d = Welch's equivalent number of independent segments (equivalent_independent_
  /// segments), which accounts for the correlation of overlapped segments (about 5 % fewer for
  /// Hann at 50 % overlap, so bands 2.5 % wider).
  bool correct_for_overlap = false;
};

/// Normalized random errors eps (dimensionless) and confidence bands of an estimate v, per
/// frequency: lower = max(0, v (1 - c eps)), upper = v (1 + c eps) (capped at 1 for coherences).
/// eps is +inf (and the band [0, inf) or [0, 1]) where the coherence is 0 or n_d is too small.
struct ErrorBand {
  std::vector<Eigen::MatrixXd> eps;    ///< [F] of (rows x cols)
  std::vector<Eigen::MatrixXd> lower;  ///< [F] of (rows x cols), units of the estimate
  std::vector<Eigen::MatrixXd> upper;  ///< [F] of (rows x cols), units of the estimate
};

/// Normalized random errors of Bendat & Piersol (Random Data, 4th ed. 2010, ch. 9: statistical
/// errors of frequency-response and coherence estimates, single and multiple input), with n_d
/// averages, q inputs and g^2 the relevant coherence:
/// - |H_ji|: eps = sqrt(1 - g^2) / (|g| sqrt(2 (n_d - q + 1))). One input: g^2 is the ordinary
///   coherence and this is B&P's SISO gain-factor error. Several inputs: g^2 is the partial
///   coherence of input i and output j given the other q - 1 inputs r, because with conditioned
///   spectra H_ji is the SISO H1 from x_i.r to y.r, whose residual noise is G_yy.r (1 - g^2), and
///   the conditioning spends q - 1 of the n_d complex degrees of freedom (B&P's MISO forms).
/// - ordinary coherence: eps = sqrt(2) (1 - g^2) / (|g| sqrt(n_d)).
/// - multiple and partial coherence: the same with n_d - q + 1 in place of n_d.
/// Overlapped segments are correlated, so with n_d = segments these are slightly optimistic (see
/// FrfOptions::correct_for_overlap). The formulas are first-order and meant for eps < ~0.2.
struct FrfRandomError {
  double averages = 0.0;                         ///< n_d used in the formulas
  double equivalent_independent_segments = 0.0;  ///< Welch's overlap-corrected count
  double confidence_factor = 2.0;                ///< c of the bands
  ErrorBand frf_magnitude;       ///< of |H|, [F] of (M x N), output units per input unit
  ErrorBand ordinary_coherence;  ///< [F] of (M x N)
  ErrorBand partial_coherence;   ///< [F] of (M x N)
  ErrorBand multiple_coherence;  ///< [F] of (M x 1)
};

struct FrfResult {
  /// ok, or why the FRF is not identifiable (inputs perfectly coupled in the band with power, an
  /// input without power). The arrays are filled in either case.
  Status status;
  double sample_rate_hz = 0.0;   ///< Hz
  int segments = 0;              ///< Welch segments averaged
  int segment_length = 0;        ///< samples per segment
  int overlap_samples = 0;       ///< samples shared by consecutive segments
  Eigen::VectorXd frequency_hz;  ///< [F], Hz
  /// [F] of (M x N): H(f)(j, i) from input i to output j (output unit per input unit), the columns
  /// of Gxx^-1 Gxy transposed (eq 2). NaN where Gxx is exactly zero.
  std::vector<Eigen::MatrixXcd> h;
  /// [F] of (M x N): |Gxy_ij|^2 / (Gxx_ii Gyy_jj) (eq 4), in [0, 1]; 0 where a spectrum is 0.
  std::vector<Eigen::MatrixXd> ordinary_coherence;
  /// [F] of (M x N): Bendat & Piersol partial coherence of input i and output j conditioned on all
  /// other inputs r, |G_iy.r|^2 / (G_ii.r G_yy.r) with G_ab.r = G_ab - G_ar G_rr^-1 G_rb (the
  /// conditioned spectra in numerator and denominator; Perreault eqs 6-7 condition the numerator
  /// only). With independent inputs it equals ordinary / (1 - sum of the other inputs' ordinary
  /// coherences with that output), so the ordinary coherence when the output depends on input i
  /// alone. In [0, 1]. Equals the ordinary coherence when N = 1.
  std::vector<Eigen::MatrixXd> partial_coherence;
  /// (F x M): Re(Gxy_j^H H_j) / Gyy_jj (eq 5), in [0, 1].
  Eigen::MatrixXd multiple_coherence;
  /// [F]: lambda_max / lambda_min of Gxx (2-norm condition, +inf when singular), dimensionless.
  Eigen::VectorXd condition_number;
  /// [F]: reciprocal condition of the input coherence matrix D^-1/2 Gxx D^-1/2 (the coupling
  /// criterion of FrfOptions::min_reciprocal_condition), in [0, 1].
  Eigen::VectorXd coupling_reciprocal_condition;
  /// [F]: 1 where every input has power (FrfOptions::band_power_fraction), else 0.
  Eigen::VectorXi in_band;
  FrfRandomError random_error;
};

/// H1 estimate and coherences from cross-spectral matrices whose first `inputs` channels are the
/// inputs and the rest the outputs (Perreault et al. 1999 eqs 1-7). Per frequency, Gxx H_j = Gxy_j
/// is solved with a pivoted LDL^T factorization of the Hermitian Gxx, and its condition comes from
/// its eigenvalues. Never throws on numerical trouble: see FrfResult::status. Only
/// options.welch.window is read from options.welch (for Welch's overlap-corrected count): it must
/// be the window the spectra were made with.
FrfResult estimate_frf(const CrossSpectra& spectra, int inputs, const FrfOptions& options = {});

/// Welch spectra of inputs (S x N) and outputs (S x M) sampled at `sample_rate_hz` (Hz), then the
/// FRF. InputError on too few samples, bad options, N = 0 or M = 0 or a sample-count mismatch.
FrfResult estimate_frf(const Eigen::Ref<const Eigen::MatrixXd>& inputs,
                       const Eigen::Ref<const Eigen::MatrixXd>& outputs, double sample_rate_hz,
                       const FrfOptions& options = {});

/// The same on named channels of a trial; messages name the trial's file and the input channels.
FrfResult estimate_frf(const data::Trial& trial, const std::vector<std::string>& inputs,
                       const std::vector<std::string>& outputs, const FrfOptions& options = {});

/// Per-frequency inverse of a square FRF, e.g. dynamic stiffness K(f) = C(f)^-1 (N/m) from
/// dynamic compliance C(f) (m/N).
struct InverseFrfResult {
  Status status;  ///< failure when not square or singular at a checked frequency
  /// [F] of (N x M): the inverse H(f)^-1 (input unit per output unit): k[f](i, j) maps output j to
  /// input i. NaN where H(f) is exactly singular.
  std::vector<Eigen::MatrixXcd> k;
  /// [F]: 2-norm condition number of H(f) (sigma_max / sigma_min), +inf when singular.
  Eigen::VectorXd condition_number;
};

/// Inverts H(f) at every frequency (LU with partial pivoting; condition from the SVD). Fails when
/// H is not square, or when at a frequency with check[f] != 0 (e.g. FrfResult::in_band; empty =
/// all) sigma_min / sigma_max < min_reciprocal_condition (default: 1e-12, where the inverse has
/// lost all but ~4 of double's 16 digits).
InverseFrfResult invert_frf(const std::vector<Eigen::MatrixXcd>& h,
                            const Eigen::VectorXi& check = Eigen::VectorXi(),
                            double min_reciprocal_condition = 1e-12);

}  // namespace stiffid::estimators
