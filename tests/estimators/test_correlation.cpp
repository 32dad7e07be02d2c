#include <tbb/task_arena.h>

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <random>
#include <string>
#include <tuple>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "estimators/correlation.hpp"

namespace est = stiffid::estimators;

namespace {

// phi_pq(d) = 1/S sum_k p(k) q(k + d) by the O(S L) definition, means removed or not.
double direct(const Eigen::MatrixXd& x, int p, int q, int lag, bool remove_mean) {
  const int s = static_cast<int>(x.rows());
  const double mp = remove_mean ? x.col(p).mean() : 0.0;
  const double mq = remove_mean ? x.col(q).mean() : 0.0;
  double sum = 0.0;
  for (int k = 0; k < s; ++k) {
    if (k + lag >= 0 && k + lag < s) sum += (x(k, p) - mp) * (x(k + lag, q) - mq);
  }
  return sum / s;
}

Eigen::MatrixXd random_signals(int samples, int channels, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(samples, channels);
  for (int c = 0; c < channels; ++c) {
    double walk = 0.0;
    for (int t = 0; t < samples; ++t) {
      walk += 0.2 * normal(rng);  // coloured, with a non-zero mean per channel
      x(t, c) = walk + normal(rng) + 1.5 * c;
    }
  }
  return x;
}

}  // namespace

BOOST_AUTO_TEST_CASE(all_pairs_match_the_direct_sum_with_and_without_mean_removal) {
  // Includes max_lag > S - 1 (lags with no overlapping samples must be exactly 0).
  for (const auto& [samples, max_lag] : {std::pair{64, 10}, std::pair{37, 45}, std::pair{1, 0}}) {
    const Eigen::MatrixXd x = random_signals(samples, 3, 7 + samples);
    for (const bool remove_mean : {true, false}) {
      const est::Correlations r = est::correlate(x, {max_lag, remove_mean});
      BOOST_REQUIRE_EQUAL(r.phi.rows(), 2 * max_lag + 1);
      BOOST_REQUIRE_EQUAL(r.phi.cols(), 9);
      for (int p = 0; p < 3; ++p) {
        for (int q = 0; q < 3; ++q) {
          for (int d = -max_lag; d <= max_lag; ++d) {
            // FFT round-off: ~eps log(n) times the sum of |terms|/S, which is < 10 here.
            BOOST_CHECK_SMALL(r.at(p, q, d) - direct(x, p, q, d, remove_mean), 1e-12);
          }
        }
      }
    }
  }
}

BOOST_AUTO_TEST_CASE(matches_numpy_fixture) {
  // tests/data/irf/make_fixtures.py: 3 channels, 300 samples, lags -25..25, numpy slicing sums.
  const std::string dir = std::string(STIFFID_TEST_DATA_DIR) + "/irf/";
  const stiffid::data::Trial trial = stiffid::data::read_trial_csv(dir + "correlation_signals.csv");
  const stiffid::data::CsvTable expected =
      stiffid::data::read_csv(dir + "correlation_expected.csv");
  const est::Correlations r = est::correlate(trial.columns({"a", "b", "c"}), {25, true});
  const std::string names = "abc";
  BOOST_REQUIRE_EQUAL(expected.row_count(), 51);
  for (int p = 0; p < 3; ++p) {
    for (int q = 0; q < 3; ++q) {
      const int col = expected.column(std::string("phi_") + names[p] + names[q]);
      for (int row = 0; row < expected.row_count(); ++row) {
        const int lag = static_cast<int>(expected.number(row, 0));
        // Values O(1) printed with 17 digits; both sides carry ~1e-15 round-off.
        BOOST_CHECK_SMALL(r.at(p, q, lag) - expected.number(row, col), 1e-12);
      }
    }
  }
}

BOOST_AUTO_TEST_CASE(selected_pairs_equal_the_all_pairs_result) {
  const Eigen::MatrixXd x = random_signals(200, 4, 3);
  const est::Correlations all = est::correlate(x, {15, true});
  const est::BlockedSignals spectra(x, 15);
  const Eigen::MatrixXd some = spectra.correlate({{3, 1}, {2, 2}, {0, 3}});
  BOOST_CHECK_SMALL((some.col(0) - all.pair(3, 1)).cwiseAbs().maxCoeff(), 1e-13);
  BOOST_CHECK_SMALL((some.col(1) - all.pair(2, 2)).cwiseAbs().maxCoeff(), 1e-13);
  BOOST_CHECK_SMALL((some.col(2) - all.pair(0, 3)).cwiseAbs().maxCoeff(), 1e-13);
  BOOST_CHECK_THROW(spectra.correlate({{0, 4}}), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(many_blocks_match_the_direct_sum) {
  // 5000 samples with L = 40: 512-point FFTs of 432-sample blocks, so 12 blocks, a short last block
  // and lags that cross every block boundary.
  BOOST_CHECK_EQUAL(est::block_fft_length(5000, 80), 512);
  BOOST_CHECK_EQUAL(est::block_fft_length(100, 80), 180);  // one block: smooth(100 + 80)
  const Eigen::MatrixXd x = random_signals(5000, 3, 11);
  const est::BlockedSignals blocked(x, 40);
  const Eigen::MatrixXd phi = blocked.correlate({{0, 1}, {2, 0}, {1, 1}});
  const int pairs[3][2] = {{0, 1}, {2, 0}, {1, 1}};
  for (int c = 0; c < 3; ++c) {
    for (int d = -40; d <= 40; ++d) {
      BOOST_CHECK_SMALL(phi(d + 40, c) - direct(x, pairs[c][0], pairs[c][1], d, true), 1e-11);
    }
  }
}

BOOST_AUTO_TEST_CASE(blocked_convolution_matches_the_direct_sum) {
  // y_j(t) = sum_i sum_a g_ji(a) x_i(t - A - a), x zero outside the record, for causal,
  // two-sided and purely anticausal kernels, single and many blocks.
  for (const auto& [samples, first, taps] : {std::tuple{3000, -7, 30}, std::tuple{3000, 5, 100},
                                             std::tuple{60, -20, 9}, std::tuple{2500, -300, 120}}) {
    const Eigen::MatrixXd x = random_signals(samples, 2, 5 + taps);
    const est::BlockedSignals blocked(x, 0);
    std::mt19937_64 rng(taps);
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::MatrixXd g(taps, 4);  // column i + 2 j
    for (int k = 0; k < g.size(); ++k) g(k) = normal(rng);
    const Eigen::MatrixXd y = blocked.convolve(g, first, 2);
    BOOST_REQUIRE_EQUAL(y.rows(), samples);
    const Eigen::MatrixXd c = x.rowwise() - x.colwise().mean();
    double worst = 0.0;
    for (int j = 0; j < 2; ++j) {
      for (int t = 0; t < samples; ++t) {
        double sum = 0.0;
        for (int i = 0; i < 2; ++i) {
          for (int a = 0; a < taps; ++a) {
            const int u = t - first - a;
            if (u >= 0 && u < samples) sum += g(a, i + 2 * j) * c(u, i);
          }
        }
        worst = std::max(worst, std::abs(y(t, j) - sum));
      }
    }
    BOOST_CHECK_SMALL(worst, 1e-11);
  }
  const est::BlockedSignals blocked(random_signals(50, 2, 1), 0);
  BOOST_CHECK_THROW(blocked.convolve(Eigen::MatrixXd::Zero(5, 3), 0, 2), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(smooth_fft_lengths_have_only_factors_2_3_5_7) {
  // Hand-checked: 11 -> 12, 13 -> 14, 17 -> 18, 1001 = 7 11 13 -> 1008 = 2^4 3^2 7,
  // 600600 -> 602112 = 2^12 3 7^2 (no 7-smooth number in 600600..602111).
  BOOST_CHECK_EQUAL(est::smooth_fft_length(11), 12);
  BOOST_CHECK_EQUAL(est::smooth_fft_length(13), 14);
  BOOST_CHECK_EQUAL(est::smooth_fft_length(17), 18);
  BOOST_CHECK_EQUAL(est::smooth_fft_length(1000), 1000);
  BOOST_CHECK_EQUAL(est::smooth_fft_length(1001), 1008);
  BOOST_CHECK_EQUAL(est::smooth_fft_length(600600), 602112);
}

BOOST_AUTO_TEST_CASE(bad_arguments_are_input_errors) {
  const Eigen::MatrixXd x = random_signals(10, 2, 1);
  BOOST_CHECK_THROW(est::correlate(x, {-1, true}), stiffid::InputError);
  BOOST_CHECK_THROW(est::correlate(Eigen::MatrixXd(0, 2), {1, true}), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(correlations_and_convolutions_are_bit_identical_at_any_thread_count) {
  // 40000 samples with L = 30: 256-point blocks, 4 fixed groups of ~40 blocks each.
  const Eigen::MatrixXd x = random_signals(40000, 3, 21);
  const est::BlockedSignals blocked(x, 30);
  const std::vector<est::ChannelPair> pairs{{0, 0}, {0, 1}, {1, 2}, {2, 0}};
  Eigen::MatrixXd g(25, 2);  // two inputs, one output
  for (int k = 0; k < g.size(); ++k) g(k) = std::sin(0.7 * k);
  const Eigen::MatrixXd phi = blocked.correlate(pairs);
  const Eigen::MatrixXd y = blocked.convolve(g, -4, 1);
  tbb::task_arena one(1);
  Eigen::MatrixXd phi1, y1;
  one.execute([&] {
    phi1 = blocked.correlate(pairs);
    y1 = blocked.convolve(g, -4, 1);
  });
  BOOST_CHECK(phi == phi1);
  BOOST_CHECK(y == y1);
}
