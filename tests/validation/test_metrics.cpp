#include <boost/test/unit_test.hpp>
#include <cmath>

#include "data/error.hpp"
#include "validation/metrics.hpp"

namespace v = stiffid::validation;

// Closed forms below are exact up to round-off of sums of a few hundred doubles (relative ~1e-14);
// BOOST_CHECK_CLOSE takes percent, so 1e-9 % (1e-11 relative) leaves three decades of margin.
constexpr double kRoundOffPercent = 1e-9;
constexpr int kSamples = 400;

namespace {
// One full period of sin and cos on kSamples points: sum sin^2 = sum cos^2 = N/2 exactly
// (discrete orthogonality), sum sin*cos = 0.
Eigen::VectorXd sine() {
  Eigen::VectorXd s(kSamples);
  for (int k = 0; k < kSamples; ++k) s(k) = std::sin(2.0 * M_PI * k / kSamples);
  return s;
}
Eigen::VectorXd cosine() {
  Eigen::VectorXd c(kSamples);
  for (int k = 0; k < kSamples; ++k) c(k) = std::cos(2.0 * M_PI * k / kSamples);
  return c;
}
}  // namespace

BOOST_AUTO_TEST_CASE(vaf_of_scaled_truth_is_one_minus_squared_gain_error) {
  const Eigen::VectorXd truth = sine();
  BOOST_CHECK_CLOSE(v::vaf_percent(1.1 * truth, truth), 100.0 * (1.0 - 0.01), kRoundOffPercent);
  BOOST_CHECK_CLOSE(v::vaf_percent(truth, truth), 100.0, kRoundOffPercent);
  // An orthogonal error e = 0.3 cos: VAF = 100 (1 - 0.09 (N/2) / (N/2)) = 91 %.
  BOOST_CHECK_CLOSE(v::vaf_percent(truth + 0.3 * cosine(), truth), 91.0, kRoundOffPercent);
  // A zero estimate explains nothing.
  BOOST_CHECK_SMALL(v::vaf_percent(Eigen::VectorXd::Zero(kSamples), truth), 1e-12);
}

BOOST_AUTO_TEST_CASE(output_vaf_and_r2_follow_eqs_17_and_24) {
  Eigen::MatrixXd measured(kSamples, 2);
  measured << sine(), cosine();
  Eigen::MatrixXd predicted(kSamples, 2);
  predicted << 0.9 * sine(), cosine() + 0.2 * sine();
  const Eigen::VectorXd vaf = v::output_vaf_percent(measured, predicted);
  BOOST_CHECK_CLOSE(vaf(0), 99.0, kRoundOffPercent);  // 1 - 0.1^2
  BOOST_CHECK_CLOSE(vaf(1), 96.0, kRoundOffPercent);  // 1 - 0.2^2 (sin and cos same energy)
  // R^2 pools errors and energies: 1 - (0.01 + 0.04)(N/2) / (N/2 + N/2) = 97.5 %.
  BOOST_CHECK_CLOSE(v::r2_percent(measured, predicted), 97.5, kRoundOffPercent);
}

BOOST_AUTO_TEST_CASE(rms_error_percent_of_an_offset_sine) {
  // rms(0.05) / rms(sin) = 0.05 / (1/sqrt 2).
  const Eigen::VectorXd truth = sine();
  const Eigen::VectorXd estimate = truth.array() + 0.05;
  BOOST_CHECK_CLOSE(v::rms_error_percent(estimate, truth), 100.0 * 0.05 * std::sqrt(2.0),
                    kRoundOffPercent);
}

BOOST_AUTO_TEST_CASE(rms_error_percent_over_an_interval_uses_only_its_samples) {
  const int n = 101;
  const Eigen::VectorXd time = Eigen::VectorXd::LinSpaced(n, 0.0, 1.0);  // 0.01 s steps
  Eigen::VectorXd truth(n);
  Eigen::VectorXd estimate(n);
  for (int i = 0; i < n; ++i) {
    truth(i) = time(i) < 0.5 ? 1.0 : 2.0;
    estimate(i) = time(i) < 0.5 ? 2.0 : 2.0;  // wrong by 100 % on the first half only
  }
  BOOST_CHECK_SMALL(v::rms_error_percent(time, estimate, truth, 0.5, 1.0), 1e-12);
  BOOST_CHECK_CLOSE(v::rms_error_percent(time, estimate, truth, 0.0, 0.4), 100.0, kRoundOffPercent);
  BOOST_CHECK_THROW(v::rms_error_percent(time, estimate, truth, 2.0, 3.0), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(mean_coherence_in_band_includes_both_edges) {
  const Eigen::VectorXd f = Eigen::VectorXd::LinSpaced(21, 0.0, 10.0);  // 0.5 Hz bins
  const Eigen::VectorXd coherence = f / 10.0;
  // Bins 2.0, 2.5, 3.0, 3.5, 4.0 Hz -> coherence 0.2 .. 0.4, mean 0.3.
  BOOST_CHECK_CLOSE(v::mean_coherence_in_band(f, coherence, 2.0, 4.0), 0.3, kRoundOffPercent);
  BOOST_CHECK_THROW(v::mean_coherence_in_band(f, coherence, 2.1, 2.4), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(coherent_band_is_the_widest_run_above_threshold) {
  const Eigen::VectorXd f = Eigen::VectorXd::LinSpaced(10, 0.0, 9.0);
  Eigen::VectorXd c(10);
  c << 0.5, 0.95, 0.97, 0.5, 0.91, 0.92, 0.99, 0.93, 0.2, 0.95;
  const v::CoherentBand band = v::coherent_band(f, c, 0.9);
  BOOST_CHECK(band.found);
  BOOST_CHECK_EQUAL(band.bins, 4);
  BOOST_CHECK_EQUAL(band.low_hz, 4.0);
  BOOST_CHECK_EQUAL(band.high_hz, 7.0);
  // Ties go to the lower band; a run at the last bin counts.
  Eigen::VectorXd tie(4);
  tie << 0.95, 0.1, 0.1, 0.95;
  const v::CoherentBand low = v::coherent_band(f.head(4), tie, 0.9);
  BOOST_CHECK_EQUAL(low.low_hz, 0.0);
  BOOST_CHECK_EQUAL(low.bins, 1);
  BOOST_CHECK(!v::coherent_band(f, c, 0.999).found);
}

BOOST_AUTO_TEST_CASE(bad_arguments_are_input_errors_naming_what) {
  const Eigen::VectorXd a = Eigen::VectorXd::Ones(3);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(4);
  try {
    v::vaf_percent(a, b, "h12");
    BOOST_FAIL("expected an InputError");
  } catch (const stiffid::InputError& e) {
    BOOST_CHECK(std::string(e.what()).find("h12") != std::string::npos);
  }
  BOOST_CHECK_THROW(v::vaf_percent(a, Eigen::VectorXd::Zero(3)), stiffid::InputError);
  BOOST_CHECK_THROW(v::r2_percent(Eigen::MatrixXd(0, 2), Eigen::MatrixXd(0, 2)),
                    stiffid::InputError);
  Eigen::VectorXd decreasing(3);
  decreasing << 0.0, 2.0, 1.0;
  BOOST_CHECK_THROW(v::coherent_band(decreasing, a, 0.5), stiffid::InputError);
}
