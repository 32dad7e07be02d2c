#include "validation/metrics.hpp"

#include <cmath>

#include "data/error.hpp"

namespace stiffid::validation {
namespace {

void require_same_shape(Eigen::Index rows_a, Eigen::Index cols_a, Eigen::Index rows_b,
                        Eigen::Index cols_b, const std::string& what) {
  if (rows_a != rows_b || cols_a != cols_b) {
    throw InputError(what + ": estimate is " + std::to_string(rows_a) + "x" +
                     std::to_string(cols_a) + " but truth is " + std::to_string(rows_b) + "x" +
                     std::to_string(cols_b) + "; expected the same shape");
  }
  if (rows_a == 0 || cols_a == 0) throw InputError(what + ": empty signal, expected samples");
}

double checked_energy(double energy, const std::string& what) {
  if (!(energy > 0.0) || !std::isfinite(energy)) {
    throw InputError(what + ": the reference signal has zero or non-finite energy (" +
                     std::to_string(energy) + "), so a relative error is undefined");
  }
  return energy;
}

}  // namespace

double vaf_percent(const Eigen::Ref<const Eigen::VectorXd>& estimate,
                   const Eigen::Ref<const Eigen::VectorXd>& truth, const std::string& what) {
  require_same_shape(estimate.size(), 1, truth.size(), 1, what);
  const double energy = checked_energy(truth.squaredNorm(), what);
  return 100.0 * (1.0 - (truth - estimate).squaredNorm() / energy);
}

Eigen::VectorXd output_vaf_percent(const Eigen::Ref<const Eigen::MatrixXd>& measured,
                                   const Eigen::Ref<const Eigen::MatrixXd>& predicted,
                                   const std::string& what) {
  require_same_shape(predicted.rows(), predicted.cols(), measured.rows(), measured.cols(), what);
  Eigen::VectorXd vaf(measured.cols());
  for (Eigen::Index j = 0; j < measured.cols(); ++j) {
    vaf(j) = vaf_percent(predicted.col(j), measured.col(j), what + " column " + std::to_string(j));
  }
  return vaf;
}

double r2_percent(const Eigen::Ref<const Eigen::MatrixXd>& measured,
                  const Eigen::Ref<const Eigen::MatrixXd>& predicted, const std::string& what) {
  require_same_shape(predicted.rows(), predicted.cols(), measured.rows(), measured.cols(), what);
  const double energy = checked_energy(measured.squaredNorm(), what);
  return 100.0 * (1.0 - (measured - predicted).squaredNorm() / energy);
}

double rms_error_percent(const Eigen::Ref<const Eigen::VectorXd>& estimate,
                         const Eigen::Ref<const Eigen::VectorXd>& truth, const std::string& what) {
  require_same_shape(estimate.size(), 1, truth.size(), 1, what);
  // rms(e)/rms(t) = sqrt(sum e^2 / sum t^2): the common 1/S cancels.
  const double energy = checked_energy(truth.squaredNorm(), what);
  return 100.0 * std::sqrt((estimate - truth).squaredNorm() / energy);
}

double rms_error_percent(const Eigen::Ref<const Eigen::VectorXd>& time_s,
                         const Eigen::Ref<const Eigen::VectorXd>& estimate,
                         const Eigen::Ref<const Eigen::VectorXd>& truth, double start_s,
                         double end_s, const std::string& what) {
  require_same_shape(estimate.size(), 1, truth.size(), 1, what);
  require_same_shape(time_s.size(), 1, truth.size(), 1, what + " (time)");
  double error = 0.0;
  double energy = 0.0;
  int count = 0;
  for (Eigen::Index i = 0; i < time_s.size(); ++i) {
    if (time_s(i) < start_s || time_s(i) > end_s) continue;
    error += (estimate(i) - truth(i)) * (estimate(i) - truth(i));
    energy += truth(i) * truth(i);
    ++count;
  }
  if (count == 0) {
    throw InputError(what + ": no sample lies in the interval [" + std::to_string(start_s) + ", " +
                     std::to_string(end_s) + "] s");
  }
  return 100.0 * std::sqrt(error / checked_energy(energy, what));
}

double mean_coherence_in_band(const Eigen::Ref<const Eigen::VectorXd>& frequency_hz,
                              const Eigen::Ref<const Eigen::VectorXd>& coherence, double low_hz,
                              double high_hz, const std::string& what) {
  require_same_shape(coherence.size(), 1, frequency_hz.size(), 1, what);
  double sum = 0.0;
  int count = 0;
  for (Eigen::Index i = 0; i < frequency_hz.size(); ++i) {
    if (frequency_hz(i) < low_hz || frequency_hz(i) > high_hz) continue;
    sum += coherence(i);
    ++count;
  }
  if (count == 0) {
    throw InputError(what + ": no frequency bin lies in the band [" + std::to_string(low_hz) +
                     ", " + std::to_string(high_hz) + "] Hz");
  }
  return sum / count;
}

CoherentBand coherent_band(const Eigen::Ref<const Eigen::VectorXd>& frequency_hz,
                           const Eigen::Ref<const Eigen::VectorXd>& coherence, double threshold,
                           const std::string& what) {
  require_same_shape(coherence.size(), 1, frequency_hz.size(), 1, what);
  for (Eigen::Index i = 1; i < frequency_hz.size(); ++i) {
    if (!(frequency_hz(i) > frequency_hz(i - 1))) {
      throw InputError(what + ": frequencies must increase (bin " + std::to_string(i) + ")");
    }
  }
  CoherentBand best;
  Eigen::Index run_start = -1;
  const Eigen::Index n = coherence.size();
  for (Eigen::Index i = 0; i <= n; ++i) {
    const bool above = i < n && coherence(i) > threshold;
    if (above && run_start < 0) run_start = i;
    if (!above && run_start >= 0) {
      const int bins = static_cast<int>(i - run_start);
      if (bins > best.bins) {
        best = {true, frequency_hz(run_start), frequency_hz(i - 1), bins};
      }
      run_start = -1;
    }
  }
  return best;
}

}  // namespace stiffid::validation
