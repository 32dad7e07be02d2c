#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>

#include "estimators/fft.hpp"

using stiffid::estimators::RealFft;

BOOST_AUTO_TEST_CASE(forward_matches_the_dft_definition_for_odd_and_even_lengths) {
  for (const int n : {8, 9, 30}) {
    Eigen::MatrixXd x(n, 3);
    for (int c = 0; c < 3; ++c)
      for (int t = 0; t < n; ++t) x(t, c) = std::sin(0.3 * t * (c + 1)) + 0.1 * t * c;
    RealFft fft(n, 3);
    const Eigen::MatrixXcd spectrum = fft.forward(x);
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < fft.bins(); ++k) {
        std::complex<double> direct = 0.0;
        for (int t = 0; t < n; ++t) direct += x(t, c) * std::polar(1.0, -2.0 * M_PI * k * t / n);
        // Round-off of an n-term sum of O(n) values: 1e-12 absolute is generous.
        BOOST_CHECK_SMALL(std::abs(spectrum(k, c) - direct), 1e-12);
      }
    }
    BOOST_CHECK_SMALL((fft.inverse(spectrum) - x).norm(), 1e-12);
  }
}

BOOST_AUTO_TEST_CASE(repeated_calls_reuse_the_plan_and_give_identical_bits) {
  RealFft fft(64, 2);
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(64, 2);
  const Eigen::MatrixXcd a = fft.forward(x);
  const Eigen::MatrixXcd b = fft.forward(x);
  BOOST_CHECK(a == b);
}
