#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "data/csv.hpp"
#include "estimators/frf.hpp"

namespace est = stiffid::estimators;
using cd = std::complex<double>;

namespace {

// A discrete IIR filter y[t] = sum_k b[k] x[t-k] - sum_{k>=1} a[k] y[t-k] (a[0] = 1).
struct Iir {
  std::vector<double> b, a;

  Eigen::VectorXd filter(const Eigen::VectorXd& x) const {
    Eigen::VectorXd y = Eigen::VectorXd::Zero(x.size());
    for (Eigen::Index t = 0; t < x.size(); ++t) {
      double v = 0.0;
      for (size_t k = 0; k < b.size() && k <= static_cast<size_t>(t); ++k) v += b[k] * x[t - k];
      for (size_t k = 1; k < a.size() && k <= static_cast<size_t>(t); ++k) v -= a[k] * y[t - k];
      y[t] = v;
    }
    return y;
  }
  // Exact frequency response B(z) / A(z) at z = exp(i 2 pi f / fs): the truth.
  cd response(double f_over_fs) const {
    const cd z1 = std::polar(1.0, -2.0 * M_PI * f_over_fs);
    cd num = 0.0, den = 0.0, p = 1.0;
    for (size_t k = 0; k < std::max(a.size(), b.size()); ++k, p *= z1) {
      if (k < b.size()) num += b[k] * p;
      if (k < a.size()) den += a[k] * p;
    }
    return num / den;
  }
};

// Poles of radius <= 0.7: impulse responses fall below 1e-6 within 40 samples, so segments of 256
// samples leave no visible leakage bias next to the random error of ~500 averages.
const std::vector<std::vector<Iir>> kSystem2x2 = {
    {{{1.0, 0.5}, {1.0, -0.6}}, {{0.3, -0.2}, {1.0, 0.5}}},
    {{{0.0, 0.4, 0.2}, {1.0, -0.3, 0.2}}, {{0.8}, {1.0, -0.7}}}};
const std::vector<std::vector<Iir>> kSystem3x2 = {
    {{{0.5, 0.25}, {1.0, -0.5}}, {{0.0, 0.0, 0.6}, {1.0}}, {{0.2, 0.3, 0.1}, {1.0, 0.4}}},
    {{{0.7}, {1.0, 0.3, 0.3}}, {{0.4, -0.4}, {1.0, -0.2}}, {{1.0, 0.0, -0.3}, {1.0}}}};

struct Simulation {
  Eigen::MatrixXd x;  // (S x N) inputs
  Eigen::MatrixXd y;  // (S x M) outputs
};

// White Gaussian inputs (unit variance), optionally mixed by `mixing` (N x N), through `system`
// (outputs x inputs filters), plus independent white output noise of sd `noise_sd`.
Simulation simulate(const std::vector<std::vector<Iir>>& system, const Eigen::MatrixXd& mixing,
                    int samples, double noise_sd, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const int n = static_cast<int>(mixing.rows());
  const int m = static_cast<int>(system.size());
  Eigen::MatrixXd e(samples, n);
  for (int c = 0; c < n; ++c)
    for (int t = 0; t < samples; ++t) e(t, c) = normal(rng);
  Simulation s{e * mixing.transpose(), Eigen::MatrixXd::Zero(samples, m)};
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < n; ++i) s.y.col(j) += system[j][i].filter(s.x.col(i));
    for (int t = 0; t < samples; ++t) s.y(t, j) += noise_sd * normal(rng);
  }
  return s;
}

est::FrfOptions frf_options(int nfft) {
  est::FrfOptions o;
  o.welch.segment_length = nfft;
  return o;
}

// Checks H against the exact FRF within the Bendat & Piersol random error: the complex error
// H_est - H has variance 2 eps^2 |H|^2 (eps is the error of |H|, half the variance lies along
// |H|), close to circular normal, so P(|error| > k sqrt(2) eps |H|) = exp(-k^2): k = 4.5 gives
// 2e-9 per bin, negligible over the ~600 bins checked. |H| is taken from the estimate, as B&P
// do: eps |H_est| = sqrt((1 - g^2) G_yy.r / (2 n_d G_ii.r)) stays finite where the true H has a
// zero. Also checks that eps is calibrated: the mean of |error|^2 / (2 eps^2 |H_est|^2) over all
// bins is 1 for a correct eps; its sd over ~600 bins (neighbouring Hann bins are correlated) is
// < 0.1, so [0.75, 1.3] rejects an eps wrong by a factor 1.15 or more.
void check_against_truth(const est::FrfResult& r, const std::vector<std::vector<Iir>>& system) {
  BOOST_REQUIRE(r.status.ok);
  double ratio_sum = 0.0;
  int count = 0;
  for (int f = 0; f < static_cast<int>(r.h.size()); ++f) {
    for (size_t j = 0; j < system.size(); ++j) {
      for (size_t i = 0; i < system[j].size(); ++i) {
        const cd truth = system[j][i].response(r.frequency_hz[f] / r.sample_rate_hz);
        const cd got = r.h[f](j, i);
        const double sd =
            std::sqrt(2.0) * r.random_error.frf_magnitude.eps[f](j, i) * std::abs(got);
        BOOST_TEST_CONTEXT("f=" << r.frequency_hz[f] << " out " << j << " in " << i) {
          BOOST_CHECK_LE(std::abs(got - truth), 4.5 * sd);
        }
        ratio_sum += std::norm(got - truth) / (sd * sd);
        ++count;
      }
    }
  }
  BOOST_TEST_MESSAGE("mean normalized squared error " << ratio_sum / count);
  BOOST_CHECK_GT(ratio_sum / count, 0.75);
  BOOST_CHECK_LT(ratio_sum / count, 1.3);
}

nlohmann::json load_json(const std::string& path) {
  std::ifstream in(path);
  BOOST_REQUIRE(in.good());
  return nlohmann::json::parse(in);
}

std::vector<double> vec(const nlohmann::json& j) { return j.get<std::vector<double>>(); }

}  // namespace

// Reference computed outside stiffid (scipy 1.10 csd + numpy solve, full-precision signals), same
// Welch settings. The CSV carries 10 significant digits, and the inputs are 4th-order digital
// Butterworth noise whose spectrum falls towards a zero at fs/2: above ~16 Hz the input power is
// < 1e-4 of its peak and the rounding noise of the CSV dominates the H1 estimate there (relative
// differences up to 1e-4 at 25 Hz, for any implementation). So the 1e-6 relative check covers the
// excitation band, where every input autospectrum is within 40 dB of its peak (80 of 129 bins);
// there the CSV rounding contributes < 1e-8.
BOOST_AUTO_TEST_CASE(frf_and_coherences_match_the_mimo_reference_in_the_excitation_band) {
  const std::string dir = std::string(STIFFID_TEST_DATA_DIR) + "/mimo/";
  const auto ref = load_json(dir + "mimo_endpoint_c25_snr20.ref.json");
  const auto trial = stiffid::data::read_trial_csv(dir + "mimo_endpoint_c25_snr20.csv");
  est::FrfOptions o;
  o.welch.segment_length = ref["welch"]["nperseg"].get<int>();
  o.welch.overlap = ref["welch"]["noverlap"].get<double>() / o.welch.segment_length;
  o.welch.window = est::Window::parse(ref["welch"]["window"].get<std::string>());
  o.welch.detrend = est::parse_detrend(ref["welch"]["detrend"].get<std::string>());
  const auto inputs = ref["inputs"].get<std::vector<std::string>>();
  const auto outputs = ref["outputs"].get<std::vector<std::string>>();
  const est::FrfResult r = est::estimate_frf(trial, inputs, outputs, o);
  BOOST_REQUIRE(r.status.ok);
  BOOST_CHECK_EQUAL(r.overlap_samples, ref["welch"]["noverlap"].get<int>());
  const auto f = vec(ref["frequency_hz"]);
  BOOST_REQUIRE_EQUAL(r.frequency_hz.size(), static_cast<Eigen::Index>(f.size()));

  // Excitation band: both input autospectra >= 1e-4 of their peaks (from our spectra; the band
  // only selects bins, the values compared come from the reference).
  const est::CrossSpectra s = est::welch_cross_spectra(trial, inputs, o.welch);
  std::vector<int> band;
  for (int k = 0; k < s.bins(); ++k) {
    bool ok = true;
    for (int i = 0; i < 2; ++i) {
      double peak = 0.0;
      for (int q = 0; q < s.bins(); ++q) peak = std::max(peak, s.g[q](i, i).real());
      ok = ok && s.g[k](i, i).real() >= 1e-4 * peak;
    }
    if (ok) band.push_back(k);
  }
  BOOST_CHECK_GE(band.size(), 70u);

  for (int j = 0; j < 2; ++j) {
    const std::string out = outputs[j];
    const auto mult = vec(ref["coherence"]["multiple"][out]);
    for (int k : band) {
      BOOST_CHECK_SMALL(r.frequency_hz[k] - f[k], 1e-12);
      // Coherences lie in [0, 1]: relative 1e-6 with a floor of 1e-2 (an ordinary coherence of
      // 6e-4 is compared to 1e-8 absolute, still 100x the CSV-rounding effect).
      BOOST_CHECK_SMALL(r.multiple_coherence(k, j) - mult[k], 1e-6 * std::max(mult[k], 1e-2));
    }
    for (int i = 0; i < 2; ++i) {
      const std::string in = inputs[i];
      const auto re = vec(ref["frf"][out][in]["re"]);
      const auto im = vec(ref["frf"][out][in]["im"]);
      const auto ord = vec(ref["coherence"]["ordinary"][out][in]);
      const auto par = vec(ref["coherence"]["partial"][out][in]);
      for (int k : band) {
        BOOST_TEST_CONTEXT(out << "/" << in << " f=" << f[k]) {
          const cd expected(re[k], im[k]);
          BOOST_CHECK_LE(std::abs(r.h[k](j, i) - expected), 1e-6 * std::abs(expected));
          BOOST_CHECK_SMALL(r.ordinary_coherence[k](j, i) - ord[k], 1e-6 * std::max(ord[k], 1e-2));
          BOOST_CHECK_SMALL(r.partial_coherence[k](j, i) - par[k], 1e-6 * std::max(par[k], 1e-2));
        }
      }
    }
  }
}

BOOST_AUTO_TEST_CASE(known_2x2_discrete_system_is_recovered_within_its_random_error) {
  const Simulation s = simulate(kSystem2x2, Eigen::MatrixXd::Identity(2, 2), 1 << 16, 0.5, 11);
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 100.0, frf_options(256));
  BOOST_CHECK_EQUAL(r.segments, 511);
  check_against_truth(r, kSystem2x2);
}

BOOST_AUTO_TEST_CASE(known_3_input_2_output_discrete_system_is_recovered_within_its_random_error) {
  const Simulation s = simulate(kSystem3x2, Eigen::MatrixXd::Identity(3, 3), 1 << 16, 0.5, 12);
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 1.0, frf_options(256));
  BOOST_REQUIRE_EQUAL(r.h.front().rows(), 2);
  BOOST_REQUIRE_EQUAL(r.h.front().cols(), 3);
  check_against_truth(r, kSystem3x2);
}

// Perreault et al. 1999 Table 1: 75 % input coupling is still identified. x2 = 0.75 x1 + 0.66 e2.
BOOST_AUTO_TEST_CASE(seventy_five_percent_coupled_inputs_are_still_identified) {
  Eigen::MatrixXd mixing(2, 2);
  mixing << 1.0, 0.0, 0.75, std::sqrt(1.0 - 0.75 * 0.75);
  const Simulation s = simulate(kSystem2x2, mixing, 1 << 16, 0.5, 13);
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 100.0, frf_options(256));
  // Input coherence 0.5625 at every frequency: reciprocal condition (1 - 0.75) / (1 + 0.75).
  BOOST_CHECK_CLOSE(r.coupling_reciprocal_condition[40], 0.25 / 1.75, 10.0);
  check_against_truth(r, kSystem2x2);
}

// Independent inputs, each output driven by one input: conditioning on the other input removes
// nothing, so partial = ordinary coherence; they differ only by estimator variance, bounded by
// 4 times the B&P random error of the coherence (sqrt(2) (1 - g^2) / (|g| sqrt(n_d))).
BOOST_AUTO_TEST_CASE(partial_equals_ordinary_coherence_for_independent_inputs) {
  std::vector<std::vector<Iir>> diagonal = kSystem2x2;
  diagonal[0][1] = {{0.0}, {1.0}};
  diagonal[1][0] = {{0.0}, {1.0}};
  const Simulation s = simulate(diagonal, Eigen::MatrixXd::Identity(2, 2), 1 << 16, 0.5, 14);
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 1.0, frf_options(256));
  for (size_t f = 0; f < r.h.size(); ++f) {
    for (int j = 0; j < 2; ++j) {
      const int i = j;  // the driving input
      const double g2 = r.ordinary_coherence[f](j, i);
      const double eps = r.random_error.ordinary_coherence.eps[f](j, i);
      BOOST_CHECK_SMALL(r.partial_coherence[f](j, i) - g2, 4.0 * eps * g2);
    }
  }
}

// Closed-form truth for independent unit-variance white inputs (G_ii = 2 / fs) and output noise of
// variance s^2 (G_nn = 2 s^2 / fs): ordinary = |H_i|^2 / (sum_k |H_k|^2 + s^2), partial (given the
// other inputs) = |H_i|^2 / (|H_i|^2 + s^2), multiple = sum_k |H_k|^2 / (sum_k |H_k|^2 + s^2).
// Tolerance from the B&P standard deviation of a coherence estimate at the true g^2,
// sqrt(2) (1 - g^2) |g| / sqrt(n), n = n_d (ordinary) or n_d - q + 1 (partial, multiple): the
// estimate is skewed with heavier tails than normal (a 27,000-bin scipy simulation of this system,
// tests/data/spectra/README.md, gave standardized errors of sd 1.03, 99.9 % below 3.4 and a maximum
// of 6.0), so 7 sd, plus 3 / n for the bias of about (1 - g^2)^2 / n that dominates where g^2 ~ 0.
BOOST_AUTO_TEST_CASE(coherences_match_their_closed_forms_for_independent_inputs) {
  const double noise_sd = 0.5;
  const Simulation c = simulate(kSystem3x2, Eigen::MatrixXd::Identity(3, 3), 1 << 16, noise_sd, 15);
  const est::FrfResult q = est::estimate_frf(c.x, c.y, 1.0, frf_options(256));
  const double nd = q.segments;
  const double nd_conditioned = nd - 2;
  const auto tolerance = [](double g2, double n) {
    return 7.0 * std::sqrt(2.0) * (1.0 - g2) * std::sqrt(g2) / std::sqrt(n) + 3.0 / n;
  };
  for (size_t f = 0; f < q.h.size(); ++f) {
    for (int j = 0; j < 2; ++j) {
      Eigen::Vector3d power;
      for (int i = 0; i < 3; ++i)
        power[i] = std::norm(kSystem3x2[j][i].response(q.frequency_hz[f]));
      const double total = power.sum() + noise_sd * noise_sd;
      const double multiple = power.sum() / total;
      BOOST_CHECK_SMALL(q.multiple_coherence(f, j) - multiple, tolerance(multiple, nd_conditioned));
      for (int i = 0; i < 3; ++i) {
        const double ordinary = power[i] / total;
        const double partial = power[i] / (power[i] + noise_sd * noise_sd);
        BOOST_TEST_CONTEXT("f=" << q.frequency_hz[f] << " out " << j << " in " << i) {
          BOOST_CHECK_SMALL(q.ordinary_coherence[f](j, i) - ordinary, tolerance(ordinary, nd));
          BOOST_CHECK_SMALL(q.partial_coherence[f](j, i) - partial,
                            tolerance(partial, nd_conditioned));
        }
      }
    }
  }
}

BOOST_AUTO_TEST_CASE(single_input_gives_partial_equal_to_ordinary_and_siso_error_formula) {
  const std::vector<std::vector<Iir>> siso = {{kSystem2x2[0][0]}};
  const Simulation s = simulate(siso, Eigen::MatrixXd::Identity(1, 1), 1 << 14, 0.5, 16);
  est::FrfOptions o = frf_options(128);
  o.correct_for_overlap = true;
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 1.0, o);
  // Bendat & Piersol SISO formulas, written out: |H| eps = sqrt(1 - g2) / (|g| sqrt(2 n_d)).
  const double nd = r.random_error.equivalent_independent_segments;
  BOOST_CHECK_LT(nd, r.segments);
  for (size_t f = 0; f < r.h.size(); ++f) {
    const double g2 = r.ordinary_coherence[f](0, 0);
    BOOST_CHECK_EQUAL(r.partial_coherence[f](0, 0), g2);
    BOOST_CHECK_CLOSE(r.multiple_coherence(f, 0), g2, 1e-9);  // one input: multiple = ordinary
    BOOST_CHECK_CLOSE(r.random_error.frf_magnitude.eps[f](0, 0),
                      std::sqrt(1.0 - g2) / (std::sqrt(g2) * std::sqrt(2.0 * nd)), 1e-9);
    BOOST_CHECK_CLOSE(r.random_error.ordinary_coherence.eps[f](0, 0),
                      std::sqrt(2.0) * (1.0 - g2) / (std::sqrt(g2) * std::sqrt(nd)), 1e-9);
    const double mag = std::abs(r.h[f](0, 0));
    const double eps = r.random_error.frf_magnitude.eps[f](0, 0);
    BOOST_CHECK_CLOSE(r.random_error.frf_magnitude.upper[f](0, 0), mag * (1 + 2 * eps), 1e-9);
    BOOST_CHECK_CLOSE(r.random_error.frf_magnitude.lower[f](0, 0),
                      std::max(0.0, mag * (1 - 2 * eps)), 1e-9);
  }
}

BOOST_AUTO_TEST_CASE(perfectly_coupled_inputs_give_a_clear_failure_status) {
  Simulation s = simulate(kSystem2x2, Eigen::MatrixXd::Identity(2, 2), 1 << 13, 0.5, 17);
  s.x.col(1) = 2.0 * s.x.col(0);  // fy = 2 fx
  const est::FrfResult r = est::estimate_frf(s.x, s.y, 1.0, frf_options(256));
  BOOST_CHECK(!r.status.ok);
  BOOST_CHECK(r.status.message.find("perfectly coupled") != std::string::npos);
  BOOST_CHECK_GT(r.condition_number[10], 1e12);
}

BOOST_AUTO_TEST_CASE(stiffness_is_the_per_frequency_inverse_of_compliance) {
  // Closed form: a 2x2 inverse is adj / det.
  std::vector<Eigen::MatrixXcd> h(2, Eigen::MatrixXcd(2, 2));
  h[0] << cd(1, 1), cd(0.5, 0), cd(0.2, -0.1), cd(2, 0);
  h[1] << cd(3, 0), cd(0, 1), cd(0, -1), cd(1, 0);  // Hermitian with det 2
  const est::InverseFrfResult k = est::invert_frf(h);
  BOOST_REQUIRE(k.status.ok);
  for (int f = 0; f < 2; ++f) {
    const cd det = h[f](0, 0) * h[f](1, 1) - h[f](0, 1) * h[f](1, 0);
    Eigen::Matrix2cd adj;
    adj << h[f](1, 1), -h[f](0, 1), -h[f](1, 0), h[f](0, 0);
    BOOST_CHECK_SMALL((k.k[f] - adj / det).norm(), 1e-14);
  }
  // Singular at a checked frequency -> failure; unchecked -> fine.
  h[1] << cd(1, 0), cd(2, 0), cd(2, 0), cd(4, 0);
  BOOST_CHECK(!est::invert_frf(h).status.ok);
  Eigen::VectorXi check(2);
  check << 1, 0;
  BOOST_CHECK(est::invert_frf(h, check).status.ok);
  const std::vector<Eigen::MatrixXcd> wide(1, Eigen::MatrixXcd::Ones(2, 3));
  BOOST_CHECK(!est::invert_frf(wide).status.ok);
}
