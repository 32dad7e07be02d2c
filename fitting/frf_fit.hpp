#pragma once
// Lumped-model fits to a frequency response (issue 8, target b): the compliance H(f) (m/N,
// outputs x inputs) estimated by `stiffid frf`, against the model's
//   KV  H(s) = (I s^2 + C s + K)^-1,
//   PT  H(s) = (I s^2 + KS - KS (KS + KP + CP s)^-1 KS)^-1        (q eliminated: eq 16),
// at s = i 2 pi f. Residuals per frequency f, output j and input i (real and imaginary parts):
//   sqrt(w_j(f)) (H_model - H_est)_ji / rms_f |H_est_j.|,
// with w_j(f) the multiple coherence of output j (Bendat & Piersol: 1 for a noise-free linear
// output, the fraction of its power explained otherwise), frequencies with w below
// `min_coherence` or outside the band left out. Same parameterization (SPD by log-Cholesky),
// seeded Latin-hypercube multi-start, Ceres Levenberg-Marquardt and standard errors as the
// time-series fit (lumped_fit.hpp). Duffing has no frequency response (cubic term): InputError.

#include <Eigen/Core>
#include <complex>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "fitting/lumped_fit.hpp"

namespace stiffid::fitting {

/// A frequency response as written by `stiffid frf` (as many outputs as inputs).
struct FrfTarget {
  std::string source;                        ///< file name, for messages
  std::vector<std::string> inputs, outputs;  ///< channel names
  Eigen::VectorXd frequency_hz;              ///< [F] Hz
  std::vector<Eigen::MatrixXcd> compliance;  ///< [F] (n x n) H(f), output x input, m/N
  Eigen::MatrixXd coherence;                 ///< (F x n) multiple coherence of each output
};

/// Reads the JSON of `stiffid frf` (keys frequency_hz, inputs, outputs, frf[OUT][IN].re/.im,
/// coherence.multiple[OUT]). Throws InputError naming the file and key on anything missing or
/// malformed, or when the numbers of inputs and outputs differ.
FrfTarget read_frf_json(const std::string& path);

struct FrfFitOptions {
  LumpedModel model = LumpedModel::kelvin_voigt;
  int starts = 16;  ///< box centre + Latin hypercube (seeded)
  std::uint64_t seed = 0;
  std::map<std::string, StartRange> ranges;  ///< start box per matrix; default from the FRF
  double band_low_hz = 0.0;                  ///< frequencies used, Hz (inclusive); 0 Hz never used
  double band_high_hz = std::numeric_limits<double>::infinity();
  double min_coherence = 0.5;  ///< frequencies where an output's multiple coherence is
                               ///< lower are left out for that output
  int max_iterations = 200;
};

/// Data-driven start box from the FRF: K, KS, KP in [r/10, 10 r] with r = 1 / |H| at the lowest
/// used frequency (largest eigenvalue magnitude of H^-1), I with r = |H^-1| / omega^2 at the
/// highest, C, CP in [r/100, 10 r] with r = |Im H^-1| / omega at the frequency of largest |H|.
std::map<std::string, StartRange> default_frf_ranges(LumpedModel model, const FrfTarget& target,
                                                     const FrfFitOptions& options);

/// The compliance of a model at f (Hz): (n x n) complex, m/N.
Eigen::MatrixXcd model_compliance(LumpedModel model, const Eigen::VectorXd& theta, int n,
                                  double frequency_hz);

/// Fits the model. In the result, vaf_percent[j] is the VAF of the weighted complex FRF of output
/// j over the used frequencies, residual_rms_m[j] the RMS of |H_model - H_est| (m/N), segments and
/// substeps 0. Throws InputError on bad input (Duffing, no usable frequency, bad options); a
/// solver failure or non-convergence is in `status`.
LumpedFitResult fit_frf(const FrfTarget& target, const FrfFitOptions& options);

}  // namespace stiffid::fitting
