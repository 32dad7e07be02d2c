#include <tbb/task_arena.h>

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "data/error.hpp"
#include "estimators/spectra.hpp"

namespace est = stiffid::estimators;

namespace {
nlohmann::json load(const std::string& name) {
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/spectra/" + name);
  BOOST_REQUIRE(in.good());
  return nlohmann::json::parse(in);
}

est::WelchOptions options_of(const nlohmann::json& c) {
  est::WelchOptions o;
  o.segment_length = c["nperseg"].get<int>();
  o.fft_length = c["nfft"].get<int>();
  o.overlap = c["overlap"].get<double>();
  o.window = est::Window::parse(c["window"].get<std::string>());
  o.detrend = est::parse_detrend(c["detrend"].get<std::string>());
  return o;
}
}  // namespace

// Fixture: scipy.signal.csd / welch on three correlated, trending random channels for every
// window and detrend, odd and even lengths, zero padding, one segment, and overlaps whose
// rounding matters (tests/data/spectra/make_fixtures.py).
BOOST_AUTO_TEST_CASE(cross_spectra_match_scipy_csd_for_every_window_detrend_and_overlap) {
  const auto fixture = load("welch.json");
  const auto rows = fixture["signals"].get<std::vector<std::vector<double>>>();
  Eigen::MatrixXd x(rows.front().size(), rows.size());
  for (size_t c = 0; c < rows.size(); ++c)
    for (size_t t = 0; t < rows[c].size(); ++t) x(t, c) = rows[c][t];

  for (const auto& c : fixture["cases"]) {
    BOOST_TEST_CONTEXT(c["name"].get<std::string>()) {
      const est::WelchOptions o = options_of(c);
      BOOST_CHECK_EQUAL(est::overlap_samples(o), c["noverlap"].get<int>());
      const est::CrossSpectra s = est::welch_cross_spectra(x, c["fs"].get<double>(), o);
      BOOST_CHECK_EQUAL(s.segments, c["segments"].get<int>());
      const auto f = c["frequency_hz"].get<std::vector<double>>();
      BOOST_REQUIRE_EQUAL(s.bins(), static_cast<int>(f.size()));
      for (int k = 0; k < s.bins(); ++k)
        BOOST_CHECK_SMALL(s.frequency_hz[k] - f[k], 1e-12 * f.back());
      double peak = 0.0;  // largest auto-spectrum value, the scale of every entry of G
      for (int k = 0; k < s.bins(); ++k) peak = std::max(peak, s.g[k].diagonal().real().maxCoeff());
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          const auto re = c["g_re"][a][b].get<std::vector<double>>();
          const auto im = c["g_im"][a][b].get<std::vector<double>>();
          for (int k = 0; k < s.bins(); ++k) {
            // Sums of a few hundred O(1) products in a different order than numpy/pocketfft:
            // round-off ~1e-15 of the spectrum's scale; 1e-12 of the peak leaves margin while any
            // scaling, window or detrend slip is >= 1e-3.
            BOOST_CHECK_SMALL(std::abs(s.g[k](a, b) - std::complex<double>(re[k], im[k])),
                              1e-12 * peak);
          }
        }
      }
      const auto pxx = c["welch_psd_0"].get<std::vector<double>>();
      for (int k = 0; k < s.bins(); ++k)
        BOOST_CHECK_SMALL(s.g[k](0, 0).real() - pxx[k], 1e-12 * peak);
    }
  }
}

// Parseval for the density scaling: for white noise of variance s^2 sampled at fs, the one-sided
// PSD is 2 s^2 / fs, so its integral over [0, fs/2] is s^2.
BOOST_AUTO_TEST_CASE(density_integrates_to_the_variance_of_white_noise) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 3.0);
  const int n = 1 << 16;
  Eigen::MatrixXd x(n, 1);
  for (int t = 0; t < n; ++t) x(t, 0) = normal(rng);
  const double fs = 100.0;
  const est::CrossSpectra s = est::welch_cross_spectra(x, fs, est::WelchOptions{});
  double integral = 0.0;
  for (int k = 0; k < s.bins(); ++k) integral += s.g[k](0, 0).real() * (fs / s.fft_length);
  // The sum of 511 segments' periodograms has relative sd ~ 1/sqrt(511 * 128 / 2) ~ 0.5 %;
  // 3 % is > 5 sd.
  BOOST_CHECK_CLOSE(integral, 9.0, 3.0);
}

BOOST_AUTO_TEST_CASE(segment_count_and_overlap_follow_scipy_truncation) {
  est::WelchOptions o;
  o.segment_length = 100;
  o.overlap = 0.29;  // 0.29 * 100 = 28.999999999999996 in doubles -> 28, as Python int()
  BOOST_CHECK_EQUAL(est::overlap_samples(o), 28);
  BOOST_CHECK_EQUAL(est::welch_segment_count(300, o), (300 - 28) / 72);
  o.overlap = 0.5;
  o.segment_length = 255;
  BOOST_CHECK_EQUAL(est::overlap_samples(o), 127);  // scipy's default nperseg // 2
  BOOST_CHECK_EQUAL(est::welch_segment_count(254, o), 0);
  // No overlap: segments are independent, the equivalent count is the count itself.
  o.overlap = 0.0;
  BOOST_CHECK_CLOSE(est::equivalent_independent_segments(10, o), 10.0, 1e-12);
  // Hann at 50 %: rho(1) = 1/6 exactly for the periodic window (Harris 1978 Table 1 gives 16.7 %),
  // so 2 (1 - 1/K) / 36 for K = 10 segments.
  o.overlap = 0.5;
  o.segment_length = 256;
  BOOST_CHECK_CLOSE(est::equivalent_independent_segments(10, o), 10.0 / (1.0 + 2.0 * 0.9 / 36.0),
                    1e-9);
}

BOOST_AUTO_TEST_CASE(bad_options_and_short_signals_are_input_errors) {
  Eigen::MatrixXd x = Eigen::MatrixXd::Random(100, 2);
  est::WelchOptions o;
  BOOST_CHECK_THROW(est::welch_cross_spectra(x, 1.0, o), stiffid::InputError);  // 100 < 256
  o.segment_length = 64;
  o.overlap = 1.0;
  BOOST_CHECK_THROW(est::welch_cross_spectra(x, 1.0, o), stiffid::InputError);
  o.overlap = 0.5;
  o.fft_length = 32;
  BOOST_CHECK_THROW(est::welch_cross_spectra(x, 1.0, o), stiffid::InputError);
  o.fft_length = 0;
  BOOST_CHECK_THROW(est::welch_cross_spectra(x, 0.0, o), stiffid::InputError);
  BOOST_CHECK_THROW(est::parse_detrend("quadratic", "--detrend"), stiffid::InputError);

  stiffid::data::Trial trial;
  trial.source = "short.csv";
  trial.sample_rate_hz = 10.0;
  trial.add_channel("fx", "N", x.col(0));
  o.segment_length = 256;
  try {
    est::welch_cross_spectra(trial, {"fx"}, o);
    BOOST_ERROR("no error for a trial shorter than one segment");
  } catch (const stiffid::InputError& e) {
    BOOST_CHECK(std::string(e.what()).find("short.csv") != std::string::npos);
  }
}

BOOST_AUTO_TEST_CASE(spectra_are_bit_identical_at_any_thread_count) {
  // The segments are summed in fixed groups (estimators/spectra.cpp), so one thread and all the
  // machine's threads must give the same bits.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(20000, 3);
  for (int k = 0; k < x.size(); ++k) x(k) = normal(rng);
  const est::CrossSpectra all = est::welch_cross_spectra(x, 500.0, est::WelchOptions{});
  tbb::task_arena one(1);
  est::CrossSpectra single;
  one.execute([&] { single = est::welch_cross_spectra(x, 500.0, est::WelchOptions{}); });
  bool same = all.bins() == single.bins();
  for (int k = 0; same && k < all.bins(); ++k) same = all.g[k] == single.g[k];
  BOOST_CHECK(same);
}
