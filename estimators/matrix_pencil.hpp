#pragma once
// Multichannel matrix pencil: n damped oscillations shared by all channels of uniformly sampled
// real signals (Hua & Sarkar 1990, IEEE Trans. ASSP 38(5) eqs 10-25; the multichannel form stacks
// the Hankel matrices of all channels so that they share one signal subspace). Used as the start of
// the damped-mode fit (damped_modes.hpp) of the `modal` tfa method (issue 7).
//
// Model, for channel k and sample i (t_i = i / sample_rate_hz, t_0 = 0 at the first sample):
//   x_k(t_i) = sum_j Re( a_jk exp(lambda_j t_i) ) + sum_r b_rk exp(beta_r t_i),
// lambda_j = alpha_j + i omega_j, with R optional real poles beta_r (non-oscillatory exponentials,
// e.g. the slow creep of a Poynting-Thomson element; options.real_poles, default none),
// the real form of Piovesan 2012 eqs 29-34 (each real mode is a conjugate pair of complex poles,
// a_jk = 2 c_j v_jk carries the complex mode shape v_j of eq 38 and the modal amplitude C_j e^-i
// phi_j of eq 33). alpha_j follows the paper's sign (eq 47: alpha = d/dt ln A, negative for a
// decaying mode); the decay rate is -alpha_j.

#include <Eigen/Core>

#include "data/error.hpp"

namespace stiffid::estimators {

struct MatrixPencilOptions {
  int modes = 2;       ///< n real damped oscillations (2n complex poles)
  int real_poles = 0;  ///< R real poles beside them (model order 2n + R)
  double pencil_fraction =
      1.0 / 3.0;             ///< pencil parameter L as a fraction of the samples, (0, 0.5]
  int max_pencil = 160;      ///< cap on L, samples: the cost is O(channels * samples * L +
                             ///< channels * L^2 + L^3) (Gram matrix, eigenproblem)
  double max_rate_hz = 0.0;  ///< > 0: samples at a higher rate are first low-passed and
                             ///< decimated (decimate.hpp, D = ceil(rate / max_rate_hz)) so that
                             ///< L spans L / max_rate_hz s or more, not L samples of a fast
                             ///< record (at 4 kHz, 160 samples are 40 ms: slow modes look like
                             ///< a trend there and the subspace fills with noise); 0: never
};

struct MatrixPencilResult {
  Status status;                    ///< failure when fewer than n oscillatory poles (or, with
                                    ///< real_poles R, fewer than R real ones) were found
  Eigen::VectorXd frequency_hz;     ///< [n] damped frequencies omega_j / 2 pi, Hz, ascending
  Eigen::VectorXd omega_rad_per_s;  ///< [n] damped angular frequencies omega_j, rad/s
  Eigen::VectorXd alpha_per_s;      ///< [n] alpha_j = Re(lambda_j), 1/s (eq 47 sign: < 0 decays)
  Eigen::MatrixXcd amplitude;       ///< (n x C) a_jk at the first sample, channel units
  Eigen::VectorXd real_rate_per_s;  ///< [R] real poles beta_r, 1/s (< 0 decays), slowest first
  Eigen::MatrixXd real_amplitude;   ///< (R x C) b_rk at the first sample, channel units
  Eigen::VectorXd singular_values;  ///< [L + 1] of the stacked Hankel matrix (model order
                                    ///< check; from its Gram matrix, so those below ~1e-8 of
                                    ///< the largest are not accurate)
  double residual_rms = 0.0;        ///< RMS of data minus model over all samples, channel units
                                    ///< (the decimated samples when max_rate_hz decimated them)
  int pencil = 0;                   ///< pencil parameter L used, samples (at rate_hz)
  double rate_hz = 0.0;             ///< rate the pencil worked at, Hz (the input rate, or the
                                    ///< decimated one under max_rate_hz)
};

/// Fewest samples a pencil of n oscillations and R real poles needs: 2 (2n + R) + 2.
inline int matrix_pencil_min_samples(int modes, int real_poles) {
  return 2 * (2 * modes + real_poles) + 2;
}

/// Estimates n damped oscillations (and R real poles) shared by the columns of `samples` (S x C,
/// one channel per column, S >= 4n + 2R + 2). Signal subspace: the 2n + R dominant right singular
/// vectors V ((L+1) x (2n + R)) of
/// the stacked Hankel matrix [Y_1; ...; Y_C], Y_k(i, l) = x_k(i + l) ((S - L) x (L + 1) each);
/// poles z = eig(V_1^+ V_2) with V_1, V_2 the first and last L rows of V (Hua & Sarkar eq 23);
/// lambda = ln(z) * sample_rate_hz; amplitudes by linear least squares on the damped-exponential
/// basis. The n poles with positive imaginary part and the lowest frequencies are reported, and the
/// real poles. Throws InputError on too few samples, a non-positive rate, n < 1 or R < 0.
MatrixPencilResult estimate_matrix_pencil(const Eigen::Ref<const Eigen::MatrixXd>& samples,
                                          double sample_rate_hz,
                                          const MatrixPencilOptions& options);

/// Model of the result at times t_s (seconds from the first sample): (T x C), channel units.
Eigen::MatrixXd evaluate_damped_exponentials(const MatrixPencilResult& result,
                                             const Eigen::Ref<const Eigen::VectorXd>& t_s);

}  // namespace stiffid::estimators
