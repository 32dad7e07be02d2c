#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/error.hpp"
#include "estimators/decimate.hpp"

using stiffid::estimators::decimate;
using stiffid::estimators::DecimationOptions;
using stiffid::estimators::DecimationResult;
using stiffid::estimators::short_filter_decimation;

namespace {

Eigen::MatrixXd matrix(const nlohmann::json& rows) {
  Eigen::MatrixXd m(rows.size(), rows[0].size());
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (std::size_t k = 0; k < rows[i].size(); ++k) m(i, k) = rows[i][k].get<double>();
  return m;
}

// cos(2 pi f t + phase) sampled at rate_hz for duration_s, one column.
Eigen::MatrixXd cosine(double f_hz, double phase_rad, double rate_hz, double duration_s) {
  const int n = static_cast<int>(std::lround(duration_s * rate_hz));
  Eigen::MatrixXd x(n, 1);
  for (int i = 0; i < n; ++i) x(i, 0) = std::cos(2.0 * M_PI * f_hz * i / rate_hz + phase_rad);
  return x;
}

}  // namespace

// Fixture: scipy.signal.firwin's Kaiser low-pass applied zero-phase, every D-th sample, the taps
// inside the record renormalised at the ends (tests/data/decimate/make_fixtures.py): random-walk
// records, the short and the default filter, factors 2-20, one to three channels.
BOOST_AUTO_TEST_CASE(matches_scipy_firwin_filter_and_ends) {
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/decimate/decimate.json");
  BOOST_REQUIRE(in.good());
  const nlohmann::json cases = nlohmann::json::parse(in);
  BOOST_REQUIRE_EQUAL(cases.size(), 4u);
  for (const auto& c : cases) {
    BOOST_TEST_CONTEXT(c["name"].get<std::string>()) {
      DecimationOptions options;
      options.factor = c["factor"].get<int>();
      options.half_taps_per_factor = c["half_taps_per_factor"].get<int>();
      options.cutoff_fraction = c["cutoff_fraction"].get<double>();
      options.kaiser_beta = c["kaiser_beta"].get<double>();
      const Eigen::MatrixXd x = matrix(c["x"]);
      const Eigen::MatrixXd expected = matrix(c["y"]);
      const double rate_hz = c["rate_hz"].get<double>();
      const DecimationResult r = decimate(x, rate_hz, options);
      BOOST_CHECK_EQUAL(r.factor, options.factor);
      BOOST_CHECK_CLOSE(r.sample_rate_hz, rate_hz / options.factor, 1e-12);
      BOOST_CHECK_EQUAL(
          r.edge_samples,
          (options.half_taps_per_factor * options.factor + options.factor - 1) / options.factor);
      BOOST_REQUIRE_EQUAL(r.samples.rows(), expected.rows());
      BOOST_REQUIRE_EQUAL(r.samples.cols(), expected.cols());
      // Values up to ~40 from sums of a few hundred taps: agreement to 1e-11 absolute leaves
      // room for the two Bessel I0 implementations yet catches a wrong tap or a shifted phase.
      BOOST_CHECK_SMALL((r.samples - expected).cwiseAbs().maxCoeff(), 1e-11);
    }
  }
}

// Closed form: the modal fit's short filter at 4 kHz -> 200 Hz passes cosines up to 20 Hz (the
// modes) with gain 1 and no phase shift within 1e-4, and attenuates everything that would alias
// into the output band (150 Hz to the input Nyquist) below 1e-4, away from the record's ends.
BOOST_AUTO_TEST_CASE(short_filter_passes_modes_and_stops_aliases) {
  const double rate_hz = 4000.0;
  const DecimationOptions options = short_filter_decimation(20);
  BOOST_CHECK_EQUAL(options.factor, 20);
  BOOST_CHECK_EQUAL(options.half_taps_per_factor, 5);
  for (double f_hz : {0.5, 2.4, 3.4, 10.0, 20.0}) {
    const double phase = 0.3 * f_hz;
    const DecimationResult r = decimate(cosine(f_hz, phase, rate_hz, 3.0), rate_hz, options);
    BOOST_REQUIRE_EQUAL(r.edge_samples, 5);
    double worst = 0.0;
    for (int i = r.edge_samples; i < r.samples.rows() - r.edge_samples; ++i)
      worst = std::max(worst, std::abs(r.samples(i, 0) -
                                       std::cos(2.0 * M_PI * f_hz * i * 20.0 / rate_hz + phase)));
    BOOST_TEST_CONTEXT("f = " << f_hz << " Hz") { BOOST_CHECK_SMALL(worst, 1e-4); }
  }
  for (double f_hz : {150.0, 200.0, 437.0, 1000.0, 1990.0}) {
    const DecimationResult r = decimate(cosine(f_hz, 0.0, rate_hz, 3.0), rate_hz, options);
    const Eigen::Index inner = r.samples.rows() - 2 * r.edge_samples;
    BOOST_TEST_CONTEXT("f = " << f_hz << " Hz") {
      BOOST_CHECK_SMALL(r.samples.middleRows(r.edge_samples, inner).cwiseAbs().maxCoeff(), 1e-4);
    }
  }
}

BOOST_AUTO_TEST_CASE(factor_one_returns_the_input_and_bad_options_are_refused) {
  Eigen::MatrixXd x(5, 2);
  x << 1, 2, 3, 4, 5, 6, 7, 8, 9, 10;
  DecimationOptions options;
  const DecimationResult same = decimate(x, 100.0, options);
  BOOST_CHECK(same.samples == x);
  BOOST_CHECK_EQUAL(same.sample_rate_hz, 100.0);
  BOOST_CHECK_EQUAL(same.edge_samples, 0);
  options.factor = 0;
  BOOST_CHECK_THROW(decimate(x, 100.0, options), stiffid::InputError);
  options.factor = 2;
  BOOST_CHECK_THROW(decimate(x, 0.0, options), stiffid::InputError);
  BOOST_CHECK_THROW(decimate(x, std::nan(""), options), stiffid::InputError);
  options.half_taps_per_factor = 0;
  BOOST_CHECK_THROW(decimate(x, 100.0, options), stiffid::InputError);
}

// filter_reach_samples: an impulse one input sample beyond the reach of output sample i leaves it
// exactly 0, one sample inside moves it; the short filter reaches 5 D input samples (25 ms at
// 4 kHz -> 200 Hz), the default 12 D, and D = 1 filters nothing.
BOOST_AUTO_TEST_CASE(the_filter_reaches_as_far_as_filter_reach_samples_says) {
  using stiffid::estimators::filter_reach_samples;
  DecimationOptions plain;
  BOOST_CHECK_EQUAL(filter_reach_samples(plain), 0);
  plain.factor = 4;
  BOOST_CHECK_EQUAL(filter_reach_samples(plain), 48);
  BOOST_CHECK_EQUAL(filter_reach_samples(short_filter_decimation(20)), 100);
  BOOST_CHECK_EQUAL(filter_reach_samples(short_filter_decimation(1)), 0);
  for (const DecimationOptions& options : {plain, short_filter_decimation(20)}) {
    const int d = options.factor, reach = filter_reach_samples(options);
    const int i = reach / d + 2, centre = i * d;  // output sample i sits at input sample i D
    for (const int offset : {-reach - 1, reach + 1, -(reach - 1), reach - 1}) {
      Eigen::MatrixXd x = Eigen::MatrixXd::Zero(2 * centre, 1);
      x(centre + offset, 0) = 1.0;
      const double y = decimate(x, 1000.0, options).samples(i, 0);
      if (std::abs(offset) > reach)
        BOOST_CHECK_EQUAL(y, 0.0);
      else
        BOOST_CHECK_MESSAGE(y != 0.0, "D " << d << ", offset " << offset);  // a tap near the end
    }
  }
}
