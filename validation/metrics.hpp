#pragma once
// Goodness-of-fit and error metrics used to score an identification against a known truth:
// VAF between estimated and true IRFs, output VAF and R^2 (Perreault et al. 1999 eqs 17 and 24),
// percentage RMS error of a parameter profile, and coherence summaries.
//
// Every function checks its arguments: mismatched sizes, empty inputs, a truth with zero energy or
// an empty interval are stiffid::InputError naming `what` (the caller's label, e.g. "h12").

#include <Eigen/Core>
#include <string>

namespace stiffid::validation {

/// Variance accounted for, percent, of `estimate` about `truth` (Perreault eq 17 with sums in place
/// of expectations): 100 * (1 - sum((truth - estimate)^2) / sum(truth^2)). No mean is removed,
/// as in eq 17, which assumes zero-mean signals; IRFs are compared sample by sample on the same lag
/// grid. Vectors of equal length L >= 1; the truth must have non-zero energy.
double vaf_percent(const Eigen::Ref<const Eigen::VectorXd>& estimate,
                   const Eigen::Ref<const Eigen::VectorXd>& truth, const std::string& what = "vaf");

/// Output VAF per output, percent (eq 17): column j of `measured` and `predicted` (S x M) gives
/// entry j of the result [M].
Eigen::VectorXd output_vaf_percent(const Eigen::Ref<const Eigen::MatrixXd>& measured,
                                   const Eigen::Ref<const Eigen::MatrixXd>& predicted,
                                   const std::string& what = "outputs");

/// Multiple correlation coefficient R^2 of a MIMO model, percent (eq 24): 100 * (1 - sum over all
/// outputs and samples of (y - yhat)^2 / sum of y^2), for `measured` and `predicted` (S x M).
double r2_percent(const Eigen::Ref<const Eigen::MatrixXd>& measured,
                  const Eigen::Ref<const Eigen::MatrixXd>& predicted,
                  const std::string& what = "outputs");

/// Percentage RMS error of a parameter profile: 100 * rms(estimate - truth) / rms(truth) over all
/// samples of the two profiles [S] (e.g. stiffness in N/m against time).
double rms_error_percent(const Eigen::Ref<const Eigen::VectorXd>& estimate,
                         const Eigen::Ref<const Eigen::VectorXd>& truth,
                         const std::string& what = "profile");

/// Same over the samples whose time lies in [start_s, end_s] (both included); `time_s` [S] in s.
/// An interval holding no sample is an InputError.
double rms_error_percent(const Eigen::Ref<const Eigen::VectorXd>& time_s,
                         const Eigen::Ref<const Eigen::VectorXd>& estimate,
                         const Eigen::Ref<const Eigen::VectorXd>& truth, double start_s,
                         double end_s, const std::string& what = "profile");

/// Mean of a coherence function [F] over the bins whose frequency [F] (Hz) lies in
/// [low_hz, high_hz] (both included). A band holding no bin is an InputError.
double mean_coherence_in_band(const Eigen::Ref<const Eigen::VectorXd>& frequency_hz,
                              const Eigen::Ref<const Eigen::VectorXd>& coherence, double low_hz,
                              double high_hz, const std::string& what = "coherence");

/// The widest run of consecutive bins whose coherence exceeds a threshold.
struct CoherentBand {
  bool found = false;    ///< false when no bin exceeds the threshold (then the rest is zero)
  double low_hz = 0.0;   ///< frequency of the first bin of the run, Hz
  double high_hz = 0.0;  ///< frequency of the last bin of the run, Hz
  int bins = 0;          ///< number of bins in the run
};

/// Widest contiguous band where coherence [F] > threshold; ties go to the lowest band.
/// `frequency_hz` [F] must increase.
CoherentBand coherent_band(const Eigen::Ref<const Eigen::VectorXd>& frequency_hz,
                           const Eigen::Ref<const Eigen::VectorXd>& coherence, double threshold,
                           const std::string& what = "coherence");

}  // namespace stiffid::validation
