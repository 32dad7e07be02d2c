#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/QR>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "estimators/irf.hpp"

namespace est = stiffid::estimators;
using stiffid::data::Trial;

namespace {

const std::string kData = STIFFID_TEST_DATA_DIR;

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  BOOST_REQUIRE_MESSAGE(in, "cannot open " + path);
  return nlohmann::json::parse(in);
}

// A known FIR system: taps[j][i] holds h_ji(tau) for tau = first..first + size - 1, in output units
// per (input unit s).
struct Fir {
  int first = 0;
  std::vector<std::vector<Eigen::VectorXd>> taps;  // [M][N]
  int outputs() const { return static_cast<int>(taps.size()); }
  int inputs() const { return static_cast<int>(taps[0].size()); }
  int lags() const { return static_cast<int>(taps[0][0].size()); }
  int last() const { return first + lags() - 1; }
};

Fir random_fir(int outputs, int inputs, int first, int lags, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Fir fir;
  fir.first = first;
  fir.taps.assign(outputs, std::vector<Eigen::VectorXd>(inputs, Eigen::VectorXd(lags)));
  for (auto& row : fir.taps)
    for (auto& h : row)
      for (int a = 0; a < lags; ++a) h(a) = uniform(rng) * std::exp(-0.15 * a);
  return fir;
}

// Independent AR(1) channels x_i(t) = pole x_i(t-1) + w, w standard normal, seeded, channel by
// channel; coloured inputs whose Psi is far from the identity.
Eigen::MatrixXd ar1_inputs(int samples, int channels, double pole, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(samples, channels);
  for (int i = 0; i < channels; ++i) {
    double state = 0.0;
    for (int t = 0; t < samples; ++t) x(t, i) = state = pole * state + normal(rng);
  }
  return x;
}

// y_j(t) = dt sum_i sum_tau h_ji(tau) x_i(t - tau) by the definition (inputs zero outside).
Eigen::MatrixXd convolve(const Fir& fir, const Eigen::MatrixXd& x, double dt) {
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(x.rows(), fir.outputs());
  for (int j = 0; j < fir.outputs(); ++j)
    for (int i = 0; i < fir.inputs(); ++i)
      for (int t = 0; t < x.rows(); ++t)
        for (int a = 0; a < fir.lags(); ++a) {
          const int k = t - (fir.first + a);
          if (k >= 0 && k < x.rows()) y(t, j) += dt * fir.taps[j][i](a) * x(k, i);
        }
  return y;
}

// Independent white inputs on samples [pad, pad + core), exactly zero mean, zero elsewhere; the
// padding holds every output sample of the FIR. On such a record the biased correlations equal
// those of the infinite zero-extended sequences, so Psi h = Phi holds exactly (eqs 9-11).
Eigen::MatrixXd padded_white_inputs(int core, int pad, int inputs, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(core + 2 * pad, inputs);
  for (int i = 0; i < inputs; ++i) {
    for (int t = 0; t < core; ++t) x(pad + t, i) = normal(rng);
    x.col(i).segment(pad, core).array() -= x.col(i).segment(pad, core).mean();
  }
  return x;
}

double max_relative_tap_error(const est::IrfResult& r, const Fir& fir) {
  double error = 0.0, scale = 0.0;
  for (int j = 0; j < fir.outputs(); ++j)
    for (int i = 0; i < fir.inputs(); ++i) {
      error = std::max(error, (r.irf(j, i) - fir.taps[j][i]).cwiseAbs().maxCoeff());
      scale = std::max(scale, fir.taps[j][i].cwiseAbs().maxCoeff());
    }
  return error / scale;
}

// VAF between an estimated and a true IRF, % (the paper's Tables 1-2 measure).
double irf_vaf_percent(const Eigen::VectorXd& estimate, const Eigen::VectorXd& truth) {
  const Eigen::ArrayXd e = (estimate - truth).array();
  const Eigen::ArrayXd t = truth.array();
  return 100.0 * (1.0 - (e - e.mean()).square().sum() / (t - t.mean()).square().sum());
}

struct Endpoint {
  Trial trial;
  stiffid::data::CsvTable truth;  // lag_s, h_x_fx, h_x_fy, h_y_fx, h_y_fy
};

Endpoint endpoint_case(const std::string& name) {
  return {stiffid::data::read_trial_csv(kData + "/irf/endpoint_" + name + ".csv"),
          stiffid::data::read_csv(kData + "/irf/endpoint_true_irf.csv")};
}

// VAF vs truth of h_x_fx, h_x_fy, h_y_fx, h_y_fy (%), lags -5..50 samples as the fixture.
std::array<double, 4> vaf_vs_truth(const est::IrfResult& r, const stiffid::data::CsvTable& truth) {
  std::array<double, 4> vaf{};
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      Eigen::VectorXd t(truth.row_count());
      for (int row = 0; row < truth.row_count(); ++row) t(row) = truth.number(row, 1 + 2 * j + i);
      vaf[2 * j + i] = irf_vaf_percent(r.irf(j, i), t);
    }
  return vaf;
}

est::IrfResult estimate(const Trial& trial, est::IrfInverse inverse, int rank = 0) {
  est::IrfOptions options{-5, 50, inverse, rank};
  return est::estimate_irf(trial.columns({"fx", "fy"}), trial.columns({"x", "y"}),
                           trial.sample_rate_hz, options);
}

}  // namespace

BOOST_AUTO_TEST_CASE(reference_case_irfs_vaf_and_r2) {
  // tests/data/mimo: the shared reference computed with numpy/scipy outside this project.
  const Trial trial = stiffid::data::read_trial_csv(kData + "/mimo/mimo_endpoint_c25_snr20.csv");
  const nlohmann::json ref = read_json(kData + "/mimo/mimo_endpoint_c25_snr20.ref.json")["irf"];
  est::IrfOptions options;
  options.first_lag = ref["lag_samples"][0];
  options.last_lag = ref["lag_samples"][1];
  const est::IrfResult r = est::estimate_irf(trial.columns({"fx", "fy"}), trial.columns({"x", "y"}),
                                             trial.sample_rate_hz, options);
  BOOST_REQUIRE(r.status.ok);
  BOOST_REQUIRE_EQUAL(r.lag_s.size(), ref["lag_s"].size());
  for (int a = 0; a < r.lag_s.size(); ++a) {
    BOOST_CHECK_SMALL(r.lag_s(a) - ref["lag_s"][a].get<double>(), 1e-12);
  }
  const std::vector<std::string> ins{"fx", "fy"}, outs{"x", "y"};
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const auto values = ref["h"][outs[j]][ins[i]].get<std::vector<double>>();
      const Eigen::VectorXd expected =
          Eigen::Map<const Eigen::VectorXd>(values.data(), values.size());
      // The 1e-6 relative (max error over the largest |h| of the subsystem); Psi has a
      // condition number ~2e4, so the two solvers agree to ~1e-11 and the CSV's 10 digits limit it.
      const double rel =
          (r.irf(j, i) - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff();
      BOOST_TEST_MESSAGE(outs[j] << "/" << ins[i] << " relative error " << rel);
      BOOST_CHECK_LT(rel, 1e-6);
    }
    BOOST_CHECK_SMALL(r.vaf_percent(j) - ref["vaf_percent"][outs[j]].get<double>(), 0.01);
  }
  BOOST_CHECK_SMALL(r.r2_percent - ref["r2_percent"].get<double>(), 0.01);
  BOOST_CHECK_EQUAL(r.rank, 112);
}

BOOST_AUTO_TEST_CASE(noise_free_fir_2x2_taps_recovered_to_round_off) {
  const double fs = 100.0;
  const Fir fir = random_fir(2, 2, 0, 12, 21);
  const Eigen::MatrixXd x = padded_white_inputs(1500, 20, 2, 22);
  const Eigen::MatrixXd y = convolve(fir, x, 1.0 / fs);
  const est::IrfResult r = est::estimate_irf(x, y, fs, {fir.first, fir.last()});
  BOOST_REQUIRE(r.status.ok);
  // White inputs: Psi ~ identity (condition ~1.5), so the solve loses nothing: round-off only.
  BOOST_CHECK_LT(max_relative_tap_error(r, fir), 1e-10);
  for (int j = 0; j < 2; ++j) {
    BOOST_CHECK_CLOSE(r.vaf_percent(j), 100.0, 1e-9);
    BOOST_CHECK_CLOSE(r.vaf_correlation_percent(j), 100.0, 1e-9);
  }
  BOOST_CHECK_CLOSE(r.r2_percent, 100.0, 1e-9);
  BOOST_CHECK_SMALL((r.predicted - y).cwiseAbs().maxCoeff(), 1e-12 * y.cwiseAbs().maxCoeff());
}

BOOST_AUTO_TEST_CASE(noise_free_fir_3_inputs_2_outputs_two_sided_taps_recovered) {
  const double fs = 250.0;
  const Fir fir = random_fir(2, 3, -4, 15, 31);  // lags -4..10: anticausal part included
  const Eigen::MatrixXd x = padded_white_inputs(2000, 15, 3, 32);
  const Eigen::MatrixXd y = convolve(fir, x, 1.0 / fs);
  const est::IrfResult r = est::estimate_irf(x, y, fs, {fir.first, fir.last()});
  BOOST_REQUIRE(r.status.ok);
  BOOST_CHECK_LT(max_relative_tap_error(r, fir), 1e-10);  // as above: round-off only
  BOOST_CHECK_CLOSE(r.lag_s(0), -4.0 / fs, 1e-12);
  BOOST_CHECK_CLOSE(r.lag_s(14), 10.0 / fs, 1e-12);
  BOOST_CHECK_EQUAL(r.full_rank, 45);
  // All eigenvectors: the pseudo-inverse is the same solution.
  const est::IrfResult p =
      est::estimate_irf(x, y, fs, {fir.first, fir.last(), est::IrfInverse::rank, 45});
  BOOST_CHECK_LT(max_relative_tap_error(p, fir), 1e-10);
}

BOOST_AUTO_TEST_CASE(noisy_fir_error_is_within_the_estimator_variance) {
  // With output noise e (variance s_e^2) the estimate is h + Psi^-1 Z^T e / S, whose squared error
  // summed over taps has mean s_e^2 trace(Psi^-1) / (S dt^2) ~= s_e^2 N L / (S_core s_x^2 dt^2)
  // per output for white inputs. Over M N L = 120 taps the sum is ~chi-square with 120 degrees of
  // freedom (sd 13 % of its mean): [0.5, 2] times the mean is > 3.8 sd from it on either side.
  const double fs = 100.0, dt = 1.0 / fs;
  const int core = 4000, pad = 25, lags = 20;
  const Fir fir = random_fir(2, 3, -5, lags, 41);
  const Eigen::MatrixXd x = padded_white_inputs(core, pad, 3, 42);
  Eigen::MatrixXd y = convolve(fir, x, dt);
  std::mt19937_64 rng(43);
  const double noise_sd = 0.05;
  std::normal_distribution<double> normal(0.0, noise_sd);
  for (int t = 0; t < y.rows(); ++t)
    for (int j = 0; j < 2; ++j) y(t, j) += normal(rng);
  const est::IrfResult r = est::estimate_irf(x, y, fs, {fir.first, fir.last()});
  BOOST_REQUIRE(r.status.ok);
  double squared_error = 0.0;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 3; ++i) squared_error += (r.irf(j, i) - fir.taps[j][i]).squaredNorm();
  const double input_variance = x.squaredNorm() / (3.0 * core);
  const double expected = 2.0 * noise_sd * noise_sd * 3 * lags / (core * input_variance * dt * dt);
  BOOST_TEST_MESSAGE("squared tap error " << squared_error << ", expected " << expected);
  BOOST_CHECK_GT(squared_error, 0.5 * expected);
  BOOST_CHECK_LT(squared_error, 2.0 * expected);
}

BOOST_AUTO_TEST_CASE(coupled_inputs_75_percent_identified_as_in_table_1) {
  // Paper Table 1, 75 % coupling: VAF between estimated and true IRFs > 97 %. The fixture's
  // band-limited forces (cond Psi ~6e4) amplify the biased-correlation edge effects of a 60 s
  // record, so the plain inverse reaches this only for the direct terms; the robust estimate
  // (MDL, Westwick & Kearney 1997) reaches it for all four subsystems and is at least as good.
  const Endpoint c = endpoint_case("c75");
  const est::IrfResult full = estimate(c.trial, est::IrfInverse::full);
  const est::IrfResult mdl = estimate(c.trial, est::IrfInverse::mdl);
  BOOST_REQUIRE(full.status.ok && mdl.status.ok);
  const auto vaf_full = vaf_vs_truth(full, c.truth);
  const auto vaf_mdl = vaf_vs_truth(mdl, c.truth);
  for (int k = 0; k < 4; ++k) {
    BOOST_TEST_MESSAGE("subsystem " << k << ": full " << vaf_full[k] << " %, mdl " << vaf_mdl[k]
                                    << " % (rank " << mdl.rank << ")");
    BOOST_CHECK_GT(vaf_mdl[k], 97.0);
    BOOST_CHECK_GE(vaf_mdl[k], vaf_full[k]);
  }
  BOOST_CHECK_GT(vaf_full[0], 97.0);  // h_x_fx
  BOOST_CHECK_GT(vaf_full[3], 97.0);  // h_y_fy
  // No output noise: the outputs are predicted almost entirely (edge effects only).
  BOOST_CHECK_GT(full.r2_percent, 99.0);
}

BOOST_AUTO_TEST_CASE(pseudo_inverse_is_at_least_as_good_as_the_full_inverse_with_noise) {
  // 75 % coupling and 20 dB output noise: the full inverse amplifies the noise along the small
  // eigenvalues of Psi; MDL keeps fewer eigenvectors and so does an explicit rank below full.
  const Endpoint c = endpoint_case("c75_snr20");
  const est::IrfResult full = estimate(c.trial, est::IrfInverse::full);
  const est::IrfResult mdl = estimate(c.trial, est::IrfInverse::mdl);
  const est::IrfResult ranked = estimate(c.trial, est::IrfInverse::rank, 40);
  BOOST_REQUIRE(full.status.ok && mdl.status.ok && ranked.status.ok);
  BOOST_CHECK_LT(mdl.rank, mdl.full_rank);
  BOOST_CHECK_EQUAL(ranked.rank, 40);
  BOOST_CHECK_EQUAL(mdl.mdl.size(), mdl.full_rank);
  const auto vaf_full = vaf_vs_truth(full, c.truth);
  const auto vaf_mdl = vaf_vs_truth(mdl, c.truth);
  const auto vaf_ranked = vaf_vs_truth(ranked, c.truth);
  for (int k = 0; k < 4; ++k) {
    BOOST_TEST_MESSAGE("subsystem " << k << ": full " << vaf_full[k] << " %, mdl " << vaf_mdl[k]
                                    << " % (rank " << mdl.rank << "), rank 40 " << vaf_ranked[k]);
    BOOST_CHECK_GE(vaf_mdl[k], vaf_full[k]);
    BOOST_CHECK_GE(vaf_ranked[k], vaf_full[k]);
    // Table 1-2 ballpark with noise: direct terms > 99 %, cross terms > 90 %.
    BOOST_CHECK_GT(vaf_mdl[k], k == 0 || k == 3 ? 99.0 : 90.0);
  }
  // Fewer parameters fit the noise less: R^2 of the predicted outputs stays at the noise bound.
  const nlohmann::json cases = read_json(kData + "/irf/endpoint_cases.json")["cases"];
  const double best = cases["c75_snr20"]["best_r2_percent"];
  BOOST_CHECK_SMALL(mdl.r2_percent - best, 0.5);
}

BOOST_AUTO_TEST_CASE(ten_db_output_noise_gives_r2_near_91_percent_as_in_table_2) {
  // SNR 10 dB by RMS: noise variance = 0.1 signal variance, so the best achievable R^2 is
  // 1 / 1.1 = 90.9 % (paper Table 2: 91.2 %); the fixture's realised noise gives 91.06 %. The fit
  // adds ~ (N L / S) of the noise variance by fitting noise (112 / 3000 * 9 % = 0.3 points) and
  // loses a little to edge effects, and the paper's own value differs from 90.9 by 0.3: 1 point.
  const Endpoint c = endpoint_case("snr10");
  const nlohmann::json cases = read_json(kData + "/irf/endpoint_cases.json")["cases"];
  const double best = cases["snr10"]["best_r2_percent"];
  const est::IrfResult full = estimate(c.trial, est::IrfInverse::full);
  BOOST_REQUIRE(full.status.ok);
  BOOST_TEST_MESSAGE("R^2 " << full.r2_percent << " %, best achievable " << best << " %");
  BOOST_CHECK_SMALL(full.r2_percent - 100.0 / 1.1, 1.0);
  BOOST_CHECK_SMALL(full.r2_percent - 91.2, 1.0);
  BOOST_CHECK_SMALL(full.r2_percent - best, 1.0);
  // The correlation form (eq 13) measures the same fit within the edge effects.
  BOOST_CHECK_SMALL(full.r2_correlation_percent - full.r2_percent, 1.0);
  // Robust estimate: the IRFs themselves stay close to the truth (Table 2, 10 dB: 97.5-99.5 %).
  const auto vaf = vaf_vs_truth(estimate(c.trial, est::IrfInverse::mdl), c.truth);
  BOOST_CHECK_GT(vaf[0], 99.0);
  BOOST_CHECK_GT(vaf[3], 99.0);
  BOOST_CHECK_GT(vaf[1], 90.0);
  BOOST_CHECK_GT(vaf[2], 90.0);
}

BOOST_AUTO_TEST_CASE(perfectly_coupled_inputs_fail_the_full_solve_but_not_the_pseudo_inverse) {
  const double fs = 100.0;
  const Fir fir = random_fir(1, 2, 0, 8, 51);
  Eigen::MatrixXd x = padded_white_inputs(1000, 10, 2, 52);
  x.col(1) = -2.0 * x.col(0);  // 100 % coupling
  const Eigen::MatrixXd y = convolve(fir, x, 1.0 / fs);
  const est::IrfResult full = est::estimate_irf(x, y, fs, {0, 7});
  BOOST_CHECK(!full.status.ok);
  BOOST_CHECK(full.status.message.find("singular") != std::string::npos);
  const est::IrfResult mdl = est::estimate_irf(x, y, fs, {0, 7, est::IrfInverse::mdl});
  BOOST_REQUIRE(mdl.status.ok);
  BOOST_CHECK_LE(mdl.rank, 8);                     // only 8 independent directions exist
  BOOST_CHECK_CLOSE(mdl.r2_percent, 100.0, 1e-6);  // the output is still predicted exactly
}

BOOST_AUTO_TEST_CASE(bad_options_are_input_errors) {
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(50, 2), y = Eigen::MatrixXd::Random(50, 1);
  BOOST_CHECK_THROW(est::estimate_irf(x, y, 100.0, {3, 2}), stiffid::InputError);
  BOOST_CHECK_THROW(est::estimate_irf(x, y, 0.0, {0, 2}), stiffid::InputError);
  BOOST_CHECK_THROW(est::estimate_irf(x, y, 100.0, {0, 60}), stiffid::InputError);
  BOOST_CHECK_THROW(est::estimate_irf(x, y.topRows(40), 100.0, {0, 2}), stiffid::InputError);
  BOOST_CHECK_THROW(est::estimate_irf(x, y, 100.0, {0, 2, est::IrfInverse::rank, 7}),
                    stiffid::InputError);
  BOOST_CHECK_THROW(est::estimate_irf(x, y, 100.0, {0, 2, est::IrfInverse::rank, 0}),
                    stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(least_squares_psi_is_the_normal_matrix_of_the_zero_padded_lagged_inputs) {
  // Colored inputs (AR(1), pole 0.95: cond(Psi) ~1e3) that are non-zero up to both ends of the
  // record, output by the definition (inputs zero outside). The biased correlations miss the
  // products across the record's ends (~L/S of Psi) and the Toeplitz solve carries that error;
  // with least_squares the estimate is the minimiser of the zero-padded prediction error, checked
  // against an explicit QR solve of Z H = Y (mean-removed Y, as the estimator's outputs).
  const double fs = 200.0;
  const Fir fir = random_fir(2, 2, -3, 14, 51);
  Eigen::MatrixXd x = ar1_inputs(1200, 2, 0.95, 52);
  x.rowwise() -= x.colwise().mean();
  const Eigen::MatrixXd y = convolve(fir, x, 1.0 / fs);
  est::IrfOptions options{fir.first, fir.last()};
  const est::IrfResult toeplitz = est::estimate_irf(x, y, fs, options);
  options.least_squares = true;
  const est::IrfResult exact = est::estimate_irf(x, y, fs, options);
  BOOST_REQUIRE(toeplitz.status.ok && exact.status.ok);
  const int lags = fir.lags();
  Eigen::MatrixXd z = Eigen::MatrixXd::Zero(x.rows(), 2 * lags);
  for (int i = 0; i < 2; ++i)
    for (int a = 0; a < lags; ++a)
      for (int t = 0; t < x.rows(); ++t) {
        const int k = t - (fir.first + a);
        if (k >= 0 && k < x.rows()) z(t, i * lags + a) = x(k, i) / fs;
      }
  const Eigen::MatrixXd centred = y.rowwise() - y.colwise().mean();
  const Eigen::MatrixXd h_qr = z.colPivHouseholderQr().solve(centred);
  const double scale = h_qr.cwiseAbs().maxCoeff();
  BOOST_TEST_MESSAGE("from the QR solution: least squares "
                     << (exact.h - h_qr).cwiseAbs().maxCoeff() / scale << ", Toeplitz "
                     << (toeplitz.h - h_qr).cwiseAbs().maxCoeff() / scale);
  BOOST_CHECK_LT((exact.h - h_qr).cwiseAbs().maxCoeff(), 1e-9 * scale);
  BOOST_CHECK_GT((toeplitz.h - h_qr).cwiseAbs().maxCoeff(), 1e-4 * scale);  // edge terms are real
  // The minimiser predicts at least as well as the Toeplitz solution, and the taps are closer.
  BOOST_CHECK_GE(exact.r2_percent, toeplitz.r2_percent);
  BOOST_CHECK_LT(max_relative_tap_error(exact, fir), max_relative_tap_error(toeplitz, fir));
}

BOOST_AUTO_TEST_CASE(truncated_eigen_decomposition_keeps_the_strong_directions_first) {
  // 75 % coupling, 20 dB noise: tsvd keeps the leading eigenvectors of Psi (MDL rank), so its
  // solution is the projection of the full one onto them; it beats the full inverse on every
  // subsystem and keeps the direct terms at Table 2's level.
  const Endpoint c = endpoint_case("c75_snr20");
  const est::IrfResult full = estimate(c.trial, est::IrfInverse::full);
  const est::IrfResult tsvd = estimate(c.trial, est::IrfInverse::tsvd);
  BOOST_REQUIRE(full.status.ok && tsvd.status.ok);
  BOOST_CHECK_LT(tsvd.rank, tsvd.full_rank);
  BOOST_CHECK_EQUAL(tsvd.mdl.size(), tsvd.full_rank);
  Eigen::Index best = 0;
  tsvd.mdl.minCoeff(&best);
  BOOST_CHECK_EQUAL(tsvd.rank, best + 1);
  const auto vaf_full = vaf_vs_truth(full, c.truth);
  const auto vaf_tsvd = vaf_vs_truth(tsvd, c.truth);
  for (int k = 0; k < 4; ++k) {
    BOOST_TEST_MESSAGE("subsystem " << k << ": full " << vaf_full[k] << " %, tsvd " << vaf_tsvd[k]
                                    << " % (rank " << tsvd.rank << ")");
    BOOST_CHECK_GE(vaf_tsvd[k], vaf_full[k]);
  }
  BOOST_CHECK_GT(vaf_tsvd[0], 99.0);
  BOOST_CHECK_GT(vaf_tsvd[3], 99.0);
  // Keeping every eigenvector in eigenvalue order is the full solution.
  const est::IrfResult all = estimate(c.trial, est::IrfInverse::rank, tsvd.full_rank);
  BOOST_CHECK_LT((all.h - full.h).cwiseAbs().maxCoeff(), 1e-6 * full.h.cwiseAbs().maxCoeff());
}

BOOST_AUTO_TEST_CASE(block_toeplitz_solve_equals_the_dense_solve_and_reports_the_condition) {
  // Three coupled AR(1) inputs, two-sided lags: Psi (eq 11) built here from direct biased sums,
  // solved densely and inverted explicitly, against the estimator's generalized Schur solve and
  // its condition estimate (a lower bound of the exact 1-norm condition number, within 3x).
  const double fs = 100.0;
  const Fir fir = random_fir(2, 3, -4, 12, 61);
  Eigen::MatrixXd x = ar1_inputs(3000, 3, 0.8, 62);
  x.col(2) -= 0.4 * x.col(1);  // coupled: each channel mixes in its predecessor
  x.col(1) += 0.6 * x.col(0);
  const Eigen::MatrixXd y = convolve(fir, x, 1.0 / fs);
  const est::IrfResult r = est::estimate_irf(x, y, fs, {fir.first, fir.last()});
  BOOST_REQUIRE(r.status.ok);
  const int lags = fir.lags();
  const int s = static_cast<int>(x.rows());
  const Eigen::MatrixXd xc = x.rowwise() - x.colwise().mean();
  const Eigen::MatrixXd yc = y.rowwise() - y.colwise().mean();
  auto phi = [&](const Eigen::MatrixXd& p, int i, const Eigen::MatrixXd& q, int k, int d) {
    double sum = 0.0;
    for (int t = 0; t < s; ++t) {
      if (t + d >= 0 && t + d < s) sum += p(t, i) * q(t + d, k);
    }
    return sum / s;
  };
  Eigen::MatrixXd psi(3 * lags, 3 * lags), rhs(3 * lags, 2);
  for (int i = 0; i < 3; ++i) {
    for (int a = 0; a < lags; ++a) {
      for (int k = 0; k < 3; ++k)
        for (int b = 0; b < lags; ++b) psi(i * lags + a, k * lags + b) = phi(xc, i, xc, k, a - b);
      for (int j = 0; j < 2; ++j) rhs(i * lags + a, j) = phi(xc, i, yc, j, fir.first + a);
    }
  }
  const Eigen::MatrixXd dense = psi.llt().solve(rhs) * fs;  // h = H / dt
  BOOST_CHECK_SMALL((r.h - dense).cwiseAbs().maxCoeff() / dense.cwiseAbs().maxCoeff(), 1e-9);
  const double exact = psi.cwiseAbs().colwise().sum().maxCoeff() *
                       psi.inverse().cwiseAbs().colwise().sum().maxCoeff();
  BOOST_CHECK_LE(r.condition_number, exact * (1 + 1e-9));
  BOOST_CHECK_GE(r.condition_number, exact / 3.0);
}
