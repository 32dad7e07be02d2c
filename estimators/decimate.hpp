#pragma once
// Zero-phase FIR decimation of uniformly sampled channels (Kaiser-windowed sinc low-pass).

#include <Eigen/Core>

namespace stiffid::estimators {

struct DecimationOptions {
  int factor = 1;                 ///< D: keep every D-th sample
  int half_taps_per_factor = 12;  ///< filter half-length in input samples = this x D
  double cutoff_fraction = 0.8;   ///< cut-off as a fraction of the output Nyquist frequency
  double kaiser_beta = 9.0;       ///< filter window shape (stop band about -90 dB)
};

struct DecimationResult {
  int factor = 1;
  double sample_rate_hz = 0.0;  ///< output rate, Hz
  Eigen::MatrixXd samples;      ///< (ceil(S / D) x C) output sample i is at input sample i D
  int edge_samples = 0;         ///< output samples at each end whose filter was cut by the record
                                ///< ends (renormalised there; not exact)
};

/// The modal fit's decimation (estimators/damped_modes.cpp, and the start's matrix pencils):
/// options with factor D and a short filter, half-length 5 D input samples (25 ms at 4 kHz ->
/// 200 Hz), which passes the modes (< 20 Hz) with unit gain within 1e-4 and keeps the filter off
/// the pulse for all but the first 25 ms of the free response.
DecimationOptions short_filter_decimation(int factor);

/// How far the filter of `options` reaches on either side of an output sample, in input samples:
/// half_taps_per_factor x D, or 0 for D = 1 (no filter). Samples within this reach of a record's
/// end, or of a pulse, are filtered with what lies beyond it.
int filter_reach_samples(const DecimationOptions& options);

/// Low-pass filters each column with a symmetric (zero-phase) FIR of unit DC gain and keeps every
/// D-th sample. In the pass band (up to about half the cut-off) the gain is 1 within 1e-4. D = 1
/// returns the input. Throws InputError on D < 1 or a rate that is not positive.
DecimationResult decimate(const Eigen::Ref<const Eigen::MatrixXd>& x, double sample_rate_hz,
                          const DecimationOptions& options);

}  // namespace stiffid::estimators
