#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/error.hpp"
#include "estimators/window.hpp"

using stiffid::estimators::Window;
using stiffid::estimators::WindowSymmetry;

namespace {
nlohmann::json load(const std::string& name) {
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/spectra/" + name);
  BOOST_REQUIRE(in.good());
  return nlohmann::json::parse(in);
}
}  // namespace

// Fixture: scipy.signal.get_window (tests/data/spectra/make_fixtures.py) for every kind, odd and
// even lengths, periodic (fftbins=True) and symmetric.
BOOST_AUTO_TEST_CASE(samples_match_scipy_get_window_periodic_and_symmetric) {
  const auto cases = load("windows.json");
  BOOST_REQUIRE_GE(cases.size(), 60u);
  for (const auto& c : cases) {
    const Window w = Window::parse(c["window"].get<std::string>());
    const int n = c["n"].get<int>();
    const auto symmetry =
        c["periodic"].get<bool>() ? WindowSymmetry::periodic : WindowSymmetry::symmetric;
    const Eigen::VectorXd got = w.samples(n, symmetry);
    const auto expected = c["w"].get<std::vector<double>>();
    BOOST_REQUIRE_EQUAL(got.size(), static_cast<Eigen::Index>(expected.size()));
    for (int k = 0; k < n; ++k) {
      // Values in [0, 1] from a cosine or Bessel I0 ratio: both libraries are accurate to a few
      // ulps, so 1e-13 absolute leaves margin yet catches any wrong formula or off-by-one length.
      BOOST_TEST_CONTEXT(c["window"] << " n=" << n << " periodic=" << c["periodic"] << " k=" << k) {
        BOOST_CHECK_SMALL(got[k] - expected[k], 1e-13);
      }
    }
  }
}

BOOST_AUTO_TEST_CASE(periodic_window_is_the_symmetric_one_of_length_n_plus_one_truncated) {
  for (const Window& w : {Window::hann(), Window::hamming(), Window::kaiser(5.0)}) {
    const Eigen::VectorXd p = w.periodic(16);
    const Eigen::VectorXd s = w.symmetric(17);
    BOOST_CHECK_SMALL((p - s.head(16)).norm(), 1e-15);
    // Symmetry w[k] = w[n-1-k] of the symmetric window, exact up to cos round-off.
    BOOST_CHECK_SMALL((s - s.reverse()).norm(), 1e-15);
  }
  // Hann closed form: 0.5 - 0.5 cos(2 pi k / n) for the periodic window of n samples.
  const Eigen::VectorXd h = Window::hann().periodic(10);
  for (int k = 0; k < 10; ++k)
    BOOST_CHECK_SMALL(h[k] - (0.5 - 0.5 * std::cos(2 * M_PI * k / 10)), 1e-15);
}

BOOST_AUTO_TEST_CASE(text_forms_parse_and_round_trip) {
  BOOST_CHECK(Window::parse("hann") == Window::hann());
  BOOST_CHECK(Window::parse("Hamming") == Window::hamming());
  BOOST_CHECK(Window::parse("rect") == Window::rectangular());
  BOOST_CHECK(Window::parse("boxcar") == Window::rectangular());
  BOOST_CHECK(Window::parse("kaiser:8.6") == Window::kaiser(8.6));
  for (const Window& w : {Window::hann(), Window::hamming(), Window::rectangular(),
                          Window::kaiser(0.1), Window::kaiser(14)}) {
    BOOST_CHECK(Window::parse(w.name()) == w);
  }
  BOOST_CHECK_EQUAL(Window::hann().samples(0).size(), 0);
  BOOST_CHECK_EQUAL(Window::hann().samples(1)[0], 1.0);
}

BOOST_AUTO_TEST_CASE(bad_text_is_an_input_error_naming_the_flag) {
  for (const std::string bad : {"", "hanning2", "kaiser", "kaiser:", "kaiser:abc", "kaiser:-1",
                                "kaiser:1e9", "kaiser:5x", "kaiser:nan"}) {
    try {
      Window::parse(bad, "--window");
      BOOST_ERROR("no error for '" + bad + "'");
    } catch (const stiffid::InputError& e) {
      const std::string what = e.what();
      BOOST_CHECK(what.find("--window") != std::string::npos);
      BOOST_CHECK(what.find("kaiser:BETA") != std::string::npos);
    }
  }
  BOOST_CHECK_THROW(Window::kaiser(-0.5), stiffid::InputError);
}
