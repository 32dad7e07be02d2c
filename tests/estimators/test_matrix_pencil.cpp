#include <Eigen/SVD>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include "data/error.hpp"
#include "estimators/matrix_pencil.hpp"

using stiffid::InputError;
using stiffid::estimators::estimate_matrix_pencil;
using stiffid::estimators::evaluate_damped_exponentials;
using stiffid::estimators::MatrixPencilOptions;

namespace {

struct Mode {
  double f_hz;
  double alpha_per_s;
  std::complex<double> a0, a1;  // complex amplitudes in channels 0 and 1
};

// Closed form of sum_j Re(a_jk exp((alpha_j + i 2 pi f_j) t)), t = i / rate.
Eigen::MatrixXd damped_sum(const std::vector<Mode>& modes, int samples, double rate_hz) {
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(samples, 2);
  for (const Mode& m : modes)
    for (int i = 0; i < samples; ++i) {
      const double t = i / rate_hz;
      const std::complex<double> e =
          std::exp(std::complex<double>(m.alpha_per_s, 2.0 * M_PI * m.f_hz) * t);
      x(i, 0) += (m.a0 * e).real();
      x(i, 1) += (m.a1 * e).real();
    }
  return x;
}

}  // namespace

BOOST_AUTO_TEST_CASE(exact_on_noise_free_sums_of_damped_exponentials) {
  const std::vector<Mode> modes = {{2.4, -1.8, {1.0, 0.3}, {0.6, -0.2}},
                                   {3.4, -2.5, {0.05, -0.1}, {-0.2, 0.12}}};
  const double rate_hz = 200.0;
  const Eigen::MatrixXd x = damped_sum(modes, 500, rate_hz);
  MatrixPencilOptions options;
  options.modes = 2;
  const auto r = estimate_matrix_pencil(x, rate_hz, options);
  BOOST_REQUIRE(r.status.ok);
  for (int j = 0; j < 2; ++j) {
    // Noise-free data of exact rank 4: the only error is round-off in the SVD and eigenvalues of
    // well-separated poles (condition ~1e3 for the weak mode); 1e-8 relative leaves a wide margin.
    BOOST_CHECK_CLOSE(r.frequency_hz(j), modes[j].f_hz, 1e-8 * 100);
    BOOST_CHECK_CLOSE(r.alpha_per_s(j), modes[j].alpha_per_s, 1e-8 * 100);
    BOOST_CHECK_SMALL(std::abs(r.amplitude(j, 0) - modes[j].a0), 1e-8);
    BOOST_CHECK_SMALL(std::abs(r.amplitude(j, 1) - modes[j].a1), 1e-8);
  }
  BOOST_CHECK_SMALL(r.residual_rms, 1e-10);
  // The model reproduces the data at any time, including beyond the record.
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(7, 0.0, 3.0);
  const Eigen::MatrixXd expected = damped_sum(modes, 601, rate_hz);
  const Eigen::MatrixXd model = evaluate_damped_exponentials(r, t);
  for (int i = 0; i < 7; ++i)
    BOOST_CHECK_SMALL((model.row(i) - expected.row(i * 100)).norm(), 1e-9);
}

BOOST_AUTO_TEST_CASE(three_modes_from_a_single_channel_and_a_growing_mode) {
  // One channel suffices when the pencil holds all poles; a growing pole (alpha > 0) is kept.
  const std::vector<Mode> modes = {{1.0, -0.5, {1.0, 0.0}, {0.0, 0.0}},
                                   {4.0, 0.3, {0.0, 0.4}, {0.0, 0.0}},
                                   {9.5, -6.0, {-0.7, 0.7}, {0.0, 0.0}}};
  const double rate_hz = 100.0;
  const Eigen::MatrixXd x = damped_sum(modes, 300, rate_hz).leftCols(1);
  MatrixPencilOptions options;
  options.modes = 3;
  const auto r = estimate_matrix_pencil(x, rate_hz, options);
  BOOST_REQUIRE(r.status.ok);
  for (int j = 0; j < 3; ++j) {
    // Round-off only (see above).
    BOOST_CHECK_CLOSE(r.frequency_hz(j), modes[j].f_hz, 1e-8 * 100);
    BOOST_CHECK_SMALL(r.alpha_per_s(j) - modes[j].alpha_per_s, 1e-8);
    BOOST_CHECK_SMALL(std::abs(r.amplitude(j, 0) - modes[j].a0), 1e-8);
  }
}

BOOST_AUTO_TEST_CASE(close_modes_with_a_weak_one_in_white_noise) {
  // 2.4 and 3.4 Hz, the weaker with 5 % of the energy, 20 dB SNR (noise RMS = signal RMS / 10),
  // 2.5 s at 200 Hz, seeded noise. For a single damped sinusoid of amplitude A in white noise of
  // variance s^2, the Cramer-Rao bound of the frequency is ~ sqrt(6 s^2 / (A^2 N T^2 pi^2)) Hz
  // before decay; for the weak mode (A ~ 0.2, s ~ 0.03, N ~ 500, T ~ 2.5) with decay shortening
  // the effective record about fourfold that is ~0.005 Hz. The matrix pencil is within a few times
  // the bound: 0.02 Hz (0.6 % of 3.4 Hz) for frequencies and 0.15 1/s for decay rates.
  const std::vector<Mode> modes = {{2.4, -1.5, {1.0, 0.0}, {0.5, 0.0}},
                                   {3.4, -2.0, {-0.1, 0.0}, {0.2, 0.0}}};
  const double rate_hz = 200.0;
  Eigen::MatrixXd x = damped_sum(modes, 500, rate_hz);
  const double rms = std::sqrt(x.squaredNorm() / x.size());
  std::mt19937_64 rng(20261123);
  std::normal_distribution<double> noise(0.0, rms / 10.0);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += noise(rng);
  const auto r = estimate_matrix_pencil(x, rate_hz, MatrixPencilOptions{});
  BOOST_REQUIRE(r.status.ok);
  for (int j = 0; j < 2; ++j) {
    BOOST_CHECK_SMALL(r.frequency_hz(j) - modes[j].f_hz, 0.02);
    BOOST_CHECK_SMALL(r.alpha_per_s(j) - modes[j].alpha_per_s, 0.15);
  }
  // Residual is the noise: within 10 % of its standard deviation (500 x 2 samples).
  BOOST_CHECK_CLOSE(r.residual_rms, rms / 10.0, 10.0);
}

BOOST_AUTO_TEST_CASE(a_fast_record_is_decimated_to_max_rate_first) {
  // The case above at 4 kHz (10,000 samples, the same 20 dB of white noise per sample). L = 160
  // samples would span 40 ms, a fraction of the slow modes' periods; with max_rate_hz = 250 the
  // pencil works on the record low-passed and decimated by D = 16 (250 Hz, L spanning 0.64 s),
  // where the noise left in the pass band is ~1/10 of the 200 Hz case's: the same limits hold.
  const std::vector<Mode> modes = {{2.4, -1.5, {1.0, 0.0}, {0.5, 0.0}},
                                   {3.4, -2.0, {-0.1, 0.0}, {0.2, 0.0}}};
  const double rate_hz = 4000.0;
  const Eigen::MatrixXd clean = damped_sum(modes, 10000, rate_hz);
  Eigen::MatrixXd x = clean;
  const double rms = std::sqrt(x.squaredNorm() / x.size());
  std::mt19937_64 rng(20261206);
  std::normal_distribution<double> noise(0.0, rms / 10.0);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += noise(rng);
  MatrixPencilOptions options;
  options.max_rate_hz = 250.0;
  const auto r = estimate_matrix_pencil(x, rate_hz, options);
  BOOST_REQUIRE(r.status.ok);
  BOOST_CHECK_EQUAL(r.rate_hz, 250.0);
  BOOST_CHECK_EQUAL(r.pencil, 160);
  for (int j = 0; j < 2; ++j) {
    BOOST_CHECK_SMALL(r.frequency_hz(j) - modes[j].f_hz, 0.02);
    BOOST_CHECK_SMALL(r.alpha_per_s(j) - modes[j].alpha_per_s, 0.15);
  }
  // Noise-free, the decimated record is the closed form within the filter's pass-band ripple
  // (1e-4) except at the ends, where the filter is cut and renormalised (20 ms of 2.5 s): the
  // poles within 1e-3 relative and the amplitudes at the first sample within 1 % of the strong
  // mode's.
  const auto exact = estimate_matrix_pencil(clean, rate_hz, options);
  BOOST_REQUIRE(exact.status.ok);
  for (int j = 0; j < 2; ++j) {
    BOOST_CHECK_CLOSE(exact.frequency_hz(j), modes[j].f_hz, 1e-3 * 100);
    BOOST_CHECK_CLOSE(exact.alpha_per_s(j), modes[j].alpha_per_s, 1e-3 * 100);
    BOOST_CHECK_SMALL(std::abs(exact.amplitude(j, 0) - modes[j].a0), 0.01);
    BOOST_CHECK_SMALL(std::abs(exact.amplitude(j, 1) - modes[j].a1), 0.01);
  }
  // Without the limit the pencil works at the input rate.
  const auto raw = estimate_matrix_pencil(clean, rate_hz, MatrixPencilOptions{});
  BOOST_CHECK_EQUAL(raw.rate_hz, rate_hz);
}

BOOST_AUTO_TEST_CASE(singular_values_are_those_of_the_stacked_hankel_matrix) {
  // The pencil takes its signal subspace from the Gram matrix of the stacked Hankel matrix H
  // (top eigenvectors only). Checked against Eigen's SVD of H built here explicitly: every
  // singular value, and the poles, on noisy data (the noise singular values are many and close)
  // and on two modes of equal amplitude 0.01 Hz apart (a near-degenerate signal cluster).
  const double rate_hz = 200.0;
  std::mt19937_64 rng(20261202);
  std::normal_distribution<double> noise(0.0, 0.05);
  Eigen::MatrixXd noisy = damped_sum(
      {{2.4, -1.5, {1.0, 0.0}, {0.5, 0.0}}, {3.4, -2.0, {-0.1, 0.0}, {0.2, 0.0}}}, 480, rate_hz);
  for (Eigen::Index i = 0; i < noisy.size(); ++i) noisy.data()[i] += noise(rng);
  const Eigen::MatrixXd close = damped_sum(
      {{3.0, -0.5, {1.0, 0.0}, {0.0, 1.0}}, {3.01, -0.5, {0.0, 1.0}, {1.0, 0.0}}}, 480, rate_hz);
  for (const Eigen::MatrixXd* x : std::vector<const Eigen::MatrixXd*>{&noisy, &close}) {
    const auto r = estimate_matrix_pencil(*x, rate_hz, MatrixPencilOptions{});
    BOOST_REQUIRE(r.status.ok);
    const int l = r.pencil, rows = static_cast<int>(x->rows()) - l;
    Eigen::MatrixXd h(2 * rows, l + 1);
    for (int k = 0; k < 2; ++k)
      for (int i = 0; i < rows; ++i)
        for (int a = 0; a <= l; ++a) h(k * rows + i, a) = (*x)(i + a, k);
    const Eigen::VectorXd sv = Eigen::BDCSVD<Eigen::MatrixXd>(h).singularValues();
    BOOST_REQUIRE_EQUAL(r.singular_values.size(), sv.size());
    // Through the Gram matrix the squares are computed, to round-off of the largest square: a
    // singular value s is then accurate to ~eps s_0^2 / s, and the exact zeros of noise-free data
    // come out near sqrt(eps) s_0 ~ 1.5e-8 s_0. Values above 1e-4 s_0 to 1e-10 s_0; the others
    // both below 1e-7 s_0.
    for (Eigen::Index i = 0; i < sv.size(); ++i) {
      if (sv(i) > 1e-4 * sv(0)) {
        BOOST_CHECK_SMALL((r.singular_values(i) - sv(i)) / sv(0), 1e-10);
      } else {
        BOOST_CHECK_SMALL(r.singular_values(i) / sv(0), 1e-7);
      }
    }
  }
  const auto r = estimate_matrix_pencil(close, rate_hz, MatrixPencilOptions{});
  BOOST_CHECK_SMALL(r.frequency_hz(0) - 3.0, 1e-8);
  BOOST_CHECK_SMALL(r.frequency_hz(1) - 3.01, 1e-8);
  BOOST_CHECK_SMALL(r.alpha_per_s(0) + 0.5, 1e-8);
  BOOST_CHECK_SMALL(r.alpha_per_s(1) + 0.5, 1e-8);
}

BOOST_AUTO_TEST_CASE(real_poles_beside_the_oscillations_are_exact_noise_free) {
  // Two damped oscillations plus a slow real exponential b_k exp(-2 t) (the creep of a
  // Poynting-Thomson element's fibres): with real_poles = 1 the model order is 5 and every pole
  // and amplitude is exact to round-off.
  const std::vector<Mode> modes = {{2.4, -1.8, {1.0, 0.3}, {0.6, -0.2}},
                                   {3.4, -2.5, {0.05, -0.1}, {-0.2, 0.12}}};
  const double rate_hz = 200.0, beta = -2.0;
  const Eigen::Vector2d b(0.4, -0.25);
  Eigen::MatrixXd x = damped_sum(modes, 500, rate_hz);
  for (int i = 0; i < 500; ++i) x.row(i) += std::exp(beta * i / rate_hz) * b.transpose();
  MatrixPencilOptions options;
  options.real_poles = 1;
  const auto r = estimate_matrix_pencil(x, rate_hz, options);
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  for (int j = 0; j < 2; ++j) {
    BOOST_CHECK_CLOSE(r.frequency_hz(j), modes[j].f_hz, 1e-8 * 100);
    BOOST_CHECK_CLOSE(r.alpha_per_s(j), modes[j].alpha_per_s, 1e-8 * 100);
    BOOST_CHECK_SMALL(std::abs(r.amplitude(j, 0) - modes[j].a0), 1e-8);
    BOOST_CHECK_SMALL(std::abs(r.amplitude(j, 1) - modes[j].a1), 1e-8);
  }
  BOOST_REQUIRE_EQUAL(r.real_rate_per_s.size(), 1);
  BOOST_CHECK_CLOSE(r.real_rate_per_s(0), beta, 1e-8 * 100);
  BOOST_CHECK_SMALL((r.real_amplitude.row(0).transpose() - b).norm(), 1e-8);
  BOOST_CHECK_SMALL(r.residual_rms, 1e-10);
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(5, 0.0, 2.0);
  const Eigen::MatrixXd model = evaluate_damped_exponentials(r, t);
  for (int i = 0; i < 5; ++i) BOOST_CHECK_SMALL((model.row(i) - x.row(i * 100)).norm(), 1e-9);
}

BOOST_AUTO_TEST_CASE(rejects_bad_input_and_reports_non_oscillatory_data) {
  const Eigen::MatrixXd short_record = Eigen::MatrixXd::Ones(9, 2);
  BOOST_CHECK_THROW(estimate_matrix_pencil(short_record, 100.0, MatrixPencilOptions{}), InputError);
  const Eigen::MatrixXd x = Eigen::MatrixXd::Ones(100, 2);
  BOOST_CHECK_THROW(estimate_matrix_pencil(x, 0.0, MatrixPencilOptions{}), InputError);
  MatrixPencilOptions zero_modes;
  zero_modes.modes = 0;
  BOOST_CHECK_THROW(estimate_matrix_pencil(x, 100.0, zero_modes), InputError);
  MatrixPencilOptions negative_real;
  negative_real.real_poles = -1;
  BOOST_CHECK_THROW(estimate_matrix_pencil(x, 100.0, negative_real), InputError);
  // Pure decaying exponentials (real poles) have no oscillatory pole: reported, not thrown.
  Eigen::MatrixXd decay(200, 1);
  for (int i = 0; i < 200; ++i) decay(i, 0) = std::exp(-0.01 * i) + 0.5 * std::exp(-0.05 * i);
  MatrixPencilOptions one_mode;
  one_mode.modes = 1;
  const auto r = estimate_matrix_pencil(decay, 100.0, one_mode);
  BOOST_CHECK(!r.status.ok);
  BOOST_CHECK(r.status.message.find("oscillatory") != std::string::npos);
}
