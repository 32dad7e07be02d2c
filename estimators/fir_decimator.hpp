#pragma once
// Zero-phase low-pass FIR filter evaluated only at the kept samples of a decimation.
// Kaiser-window design (Oppenheim & Schafer 1999, eqs 7.62-7.63): a windowed sinc of odd length
// 2H + 1, centred on the output sample, so its phase is exactly zero (no delay, no distortion of
// the modes' phases); unit gain at 0 Hz.

#include <Eigen/Core>

namespace stiffid::estimators {

class FirDecimator {
 public:
  /// Decimation by factor = max(1, round(input_rate_hz / output_rate_hz)). The cutoff (-6 dB) is at
  /// 0.4 x the output rate, the transition band 0.4 x the output rate wide (pass band to 0.2, stop
  /// band from 0.6 x the output rate), 60 dB stop-band attenuation: what folds into the pass band
  /// comes from the stop band. Factor 1 means no filter (a single unit tap).
  FirDecimator(double input_rate_hz, double output_rate_hz);

  int factor() const { return factor_; }              ///< input samples per output sample
  int half_length() const { return half_length_; }    ///< H: the filter spans i - H .. i + H
  double output_rate_hz() const { return output_rate_hz_; }  ///< input rate / factor, Hz
  const Eigen::VectorXd& taps() const { return taps_; }      ///< [2H + 1], symmetric, sum 1

  /// Filtered value of every column at the input sample indices `index` (each in [H, S - H)):
  /// (indices x C), units of x.
  Eigen::MatrixXd filter_at(const Eigen::Ref<const Eigen::MatrixXd>& x,
                            const Eigen::Ref<const Eigen::VectorXi>& index) const;

 private:
  int factor_ = 1;
  int half_length_ = 0;
  double output_rate_hz_ = 0.0;
  Eigen::VectorXd taps_;
};

}  // namespace stiffid::estimators
