// The time-frequency identification on simulated Piovesan 2012 posture trials (nonlinear two-link
// arm, Kelvin-Voigt joints, 5 N / 20 ms pulse at 2.5 s; simulated with scipy by
// tests/data/tfa/make_posture_trials.py, truth K(t) = K0 u(t) of eqs 52-54), noise-free and with
// 20 dB of white noise on the joint angles; and the bad-input errors of the pipeline.
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include "data/csv.hpp"
#include "data/error.hpp"
#include "estimators/tfa.hpp"

namespace est = stiffid::estimators;

namespace {

const Eigen::Matrix2d kK0 = (Eigen::Matrix2d() << 35, 5, 5, 20).finished();

double profile(const std::string& kind, double t) {
  if (t < 2.5 || kind == "constant") return 1.0;
  const double rate = kind == "sigmoid" ? 4.0 : 30.0;
  return 4.0 / (1.0 + std::exp(-rate * (t - 3.75))) + 1.0;
}

stiffid::data::Trial posture_trial(const std::string& kind, double snr_db, unsigned seed) {
  stiffid::data::Trial trial = stiffid::data::read_trial_csv(std::string(STIFFID_TEST_DATA_DIR) +
                                                             "/tfa/posture_" + kind + ".csv");
  if (std::isfinite(snr_db)) {
    // White Gaussian noise on each angle, RMS = RMS of its deviation after the onset / 10^(snr/20).
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    const int onset =
        static_cast<int>(std::lround((2.5 - trial.start_time_s) * trial.sample_rate_hz));
    for (int c = 0; c < 2; ++c) {
      const int col = trial.index(c == 0 ? "th1" : "th2");
      const Eigen::VectorXd after = trial.samples.col(col).tail(trial.sample_count() - onset);
      const double rms = std::sqrt((after.array() - trial.samples(0, col)).square().mean());
      const double sigma = rms / std::pow(10.0, snr_db / 20.0);
      for (int i = 0; i < trial.sample_count(); ++i) trial.samples(i, col) += sigma * normal(rng);
    }
  }
  return trial;
}

/// Percentage RMS error of coefficient (r, c) of K over [t0, t1]: 100 RMS(K^ - K) / RMS(K).
double percent_rms_error(const est::TfaResult& r, const std::string& kind, int row, int col,
                         double t0, double t1, bool damping = false) {
  double se = 0, st = 0;
  for (int m = 0; m < r.modal.time_s.size(); ++m) {
    const double t = r.modal.time_s(m);
    if (t < t0 || t > t1) continue;
    const double truth = (damping ? 0.01 : profile(kind, t)) * kK0(row, col);
    const double est =
        (damping ? r.modal.damping_nms_per_rad[m] : r.modal.stiffness_nm_per_rad[m])(row, col);
    se += (est - truth) * (est - truth);
    st += truth * truth;
  }
  return 100.0 * std::sqrt(se / st);
}

est::TfaOptions piovesan_options() {
  est::TfaOptions o;  // Kaiser beta 3, 0.75 s, 2.5 ms hop; SG order 3 over 0.25 s (the paper's)
  o.method = est::TfaMethod::spectrogram;  // this file tests the spectrogram pipeline
  o.deviation.angle_channels = {"th1", "th2"};
  o.deviation.force_channels = {"fx", "fy"};  // onset auto
  return o;
}

}  // namespace

std::string report(const est::TfaResult& r, const std::string& kind) {
  std::ostringstream line;
  for (const auto& [t0, t1] : {std::pair{2.5, 5.0}, {2.6, 3.175}, {2.6, 4.5}}) {
    line << " [" << t0 << "-" << t1 << " s] k11 " << percent_rms_error(r, kind, 0, 0, t0, t1)
         << " k12 " << percent_rms_error(r, kind, 0, 1, t0, t1) << " k22 "
         << percent_rms_error(r, kind, 1, 1, t0, t1) << " c11 "
         << percent_rms_error(r, kind, 0, 0, t0, t1, true) << " c12 "
         << percent_rms_error(r, kind, 0, 1, t0, t1, true) << " c22 "
         << percent_rms_error(r, kind, 1, 1, t0, t1, true) << " %;";
  }
  return line.str();
}

BOOST_AUTO_TEST_CASE(constant_stiffness_noise_free_is_recovered_to_one_percent) {
  const est::TfaResult r =
      est::identify_tfa(posture_trial("constant", HUGE_VAL, 7), piovesan_options());
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_CHECK_CLOSE(r.deviation.onset_s, 2.5, 1e-6);  // auto onset from fx, fy
  BOOST_TEST_MESSAGE("constant, noise-free:" << report(r, "constant"));
  // The nonlinear arm's free response is two damped modes up to the Coriolis terms, quadratic in
  // the ~0.01 rad deviations: the stiffness is recovered to well under 1 % (measured 0.04 % for
  // k11, 0.8 % for k12 with the default chirped frame fits), far inside issue 6's 10 % for k11.
  for (const auto& [row, col] : {std::pair{0, 0}, {0, 1}, {1, 1}}) {
    BOOST_CHECK_LT(percent_rms_error(r, "constant", row, col, 2.6, 4.5), 1.0);
  }
  BOOST_CHECK_LT(percent_rms_error(r, "constant", 0, 0, 2.5, 5.0), 1.0);
}

BOOST_AUTO_TEST_CASE(constant_stiffness_at_20_db_meets_issue_6s_k11_target) {
  // Issue 6: k11 within 10 % (percentage RMS over 2.6-4.5 s) at 20 dB. Measured 1.3 % (2.6-3.175 s:
  // 0.5 %) with the default chirped frame fits, 4.8 % with the stationary ones (--chirp false);
  // 29 % before degenerate frame fits were flagged and the chains started from a non-degenerate
  // frame (docs/tfa.md).
  const est::TfaResult r =
      est::identify_tfa(posture_trial("constant", 20.0, 7), piovesan_options());
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_TEST_MESSAGE("constant, SNR 20 dB: " << report(r, "constant"));
  BOOST_CHECK_LT(percent_rms_error(r, "constant", 0, 0, 2.6, 4.5), 10.0);
  BOOST_CHECK_LT(percent_rms_error(r, "constant", 0, 0, 2.6, 3.175), 10.0);
}

BOOST_AUTO_TEST_CASE(sigmoid_stiffness_meets_issue_6s_k11_target) {
  // Issue 6: k11 within 10 % over 2.6-4.5 s for sigmoid K too. The default chirped frame fits
  // follow the sweep: measured 2.8 % noise-free and 6.7 % at 20 dB (this seed; over the seeds
  // 1-12 of this generator 10 of 12 within 10 %, the other two 11.1 and 11.4 %: docs/tfa.md).
  // The stationary frame model lags it (13.1 % at 20 dB here, 1 of those 12 seeds within 10 %);
  // checked too, so that the comparison stays honest.
  for (const double snr : {HUGE_VAL, 20.0}) {
    const est::TfaResult r =
        est::identify_tfa(posture_trial("sigmoid", snr, 7), piovesan_options());
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    BOOST_TEST_MESSAGE("sigmoid, SNR " << snr << " dB:" << report(r, "sigmoid"));
    BOOST_CHECK_LT(percent_rms_error(r, "sigmoid", 0, 0, 2.6, 4.5), 10.0);
  }
  est::TfaOptions stationary = piovesan_options();
  stationary.ridges.fit_chirp = false;
  const est::TfaResult r = est::identify_tfa(posture_trial("sigmoid", 20.0, 7), stationary);
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_TEST_MESSAGE("sigmoid, SNR 20 dB, stationary frame fits:" << report(r, "sigmoid"));
  BOOST_CHECK_GT(percent_rms_error(r, "sigmoid", 0, 0, 2.6, 4.5), 10.0);
}

BOOST_AUTO_TEST_CASE(sharp_stiffness_is_reported) {
  // Issue 6 asks sharp K to be reported only (docs/tfa.md, "Limits": a linear chirp over a 0.75 s
  // window cannot follow a fivefold step within ~0.15 s). Measured over 2.6-4.5 s: k11 24 %
  // noise-free (7342 % before the amplitude-to-noise ratio had a floor for noise-free data: the
  // vanished slow mode's track was left valid; 125 % with the stationary frame fits) and 27 % at
  // 20 dB. The errors are printed (--log_level=message); the pipeline must succeed and give
  // finite errors.
  for (const double snr : {HUGE_VAL, 20.0}) {
    const est::TfaResult r = est::identify_tfa(posture_trial("sharp", snr, 7), piovesan_options());
    BOOST_TEST_MESSAGE("sharp, SNR " << snr << " dB: " << (r.status.ok ? "" : r.status.message)
                                     << report(r, "sharp"));
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    BOOST_CHECK(std::isfinite(percent_rms_error(r, "sharp", 0, 0, 2.6, 4.5)));
  }
}

BOOST_AUTO_TEST_CASE(missing_channels_short_trials_and_bad_onsets_are_input_errors) {
  const stiffid::data::Trial trial = posture_trial("constant", HUGE_VAL, 1);
  est::TfaOptions o = piovesan_options();
  o.deviation.angle_channels = {"th1", "elbow"};
  BOOST_CHECK_THROW(est::identify_tfa(trial, o), stiffid::InputError);
  o = piovesan_options();
  o.deviation.onset_s = 7.0;  // after the end of the trial
  BOOST_CHECK_THROW(est::identify_tfa(trial, o), stiffid::InputError);
  o.deviation.onset_s = 1.0;  // before its start (2.0 s)
  BOOST_CHECK_THROW(est::identify_tfa(trial, o), stiffid::InputError);
  o.deviation.onset_s = 4.6;  // 0.4 s of free response: shorter than one 0.75 s window
  try {
    est::identify_tfa(trial, o);
    BOOST_ERROR("expected an InputError");
  } catch (const stiffid::InputError& e) {
    BOOST_CHECK(std::string(e.what()).find("too short after the onset") != std::string::npos);
  }
  o = piovesan_options();
  o.deviation.force_channels = {};  // auto onset without forces
  BOOST_CHECK_THROW(est::identify_tfa(trial, o), stiffid::InputError);
}

// The movement check of the pre-onset posture (posture_drift): a joint that moves before the
// onset is named, one that rests (with or without white noise) is not.
BOOST_AUTO_TEST_CASE(a_joint_moving_before_the_onset_is_named_in_a_warning) {
  const double dt = 2.5e-4;  // 4 kHz
  const int p = 800;         // the default 0.2 s before the onset
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1e-4);
  Eigen::MatrixXd angles(p, 2);
  for (int i = 0; i < p; ++i) {
    angles(i, 0) = 0.7 + normal(rng);  // resting, noisy
    angles(i, 1) = 1.2;                // resting, noise-free
  }
  const Eigen::Vector2d peak(3e-3, 3e-3);  // rad
  const std::vector<std::string> names = {"th1", "th2"};
  BOOST_CHECK_EQUAL(est::posture_drift(angles, dt, 2.5, peak, names), "");
  // th2 moves at 0.5 rad/s (a reach): 1.25 rad over 2.5 s against a 3 mrad response.
  Eigen::MatrixXd moving = angles;
  for (int i = 0; i < p; ++i) moving(i, 1) += 0.5 * i * dt;
  const std::string w = est::posture_drift(moving, dt, 2.5, peak, names);
  BOOST_CHECK(w.find("'th2' 0.5 rad/s") != std::string::npos);
  BOOST_CHECK(w.find("'th1'") == std::string::npos);
  BOOST_CHECK(w.find("--baseline") != std::string::npos);
  // A drift 10 standard errors clear of zero but small against the response: no warning.
  // SE of the slope = sigma / sqrt(sum (t - mean t)^2) = 1e-4 / sqrt(p^3 dt^2 / 12) = 6.1e-5
  // rad/s at p = 800.
  Eigen::MatrixXd slow = angles;
  for (int i = 0; i < p; ++i) slow(i, 0) += 0.01 * i * dt;  // 160 SE; 0.025 rad over 2.5 s
  BOOST_CHECK(est::posture_drift(slow, dt, 2.5, Eigen::Vector2d(30.0, 3e-3), names).empty());
  BOOST_CHECK(!est::posture_drift(slow, dt, 2.5, peak, names).empty());
  // A drift large against the response (5e-4 rad over 2.5 s) but within the noise (about 3 SE):
  // no warning.
  Eigen::MatrixXd noisy = angles;
  for (int i = 0; i < p; ++i) noisy(i, 0) += 2e-4 * i * dt;
  BOOST_CHECK(est::posture_drift(noisy, dt, 2.5, peak, names).empty());
}

BOOST_AUTO_TEST_CASE(the_posture_trials_rest_before_the_onset_a_ramp_added_moves_them) {
  for (const double snr : {HUGE_VAL, 20.0, 0.0}) {
    const stiffid::data::Trial trial = posture_trial("sigmoid", snr, 3);
    BOOST_CHECK_EQUAL(est::joint_deviation(trial, piovesan_options().deviation).warning, "");
  }
  // The same trial on a slow reach: the elbow turns at 0.2 rad/s throughout.
  stiffid::data::Trial moving = posture_trial("sigmoid", 20.0, 3);
  const int col = moving.index("th2");
  for (int i = 0; i < moving.sample_count(); ++i)
    moving.samples(i, col) += 0.2 * i * moving.step_s();
  const std::string w = est::joint_deviation(moving, piovesan_options().deviation).warning;
  const std::size_t at = w.find("'th2' ");
  BOOST_REQUIRE(at != std::string::npos);
  BOOST_CHECK_CLOSE(std::stod(w.substr(at + 6)), 0.2, 0.1);  // rad/s, within 0.1 %
  BOOST_CHECK(w.find("'th1'") == std::string::npos);
}
