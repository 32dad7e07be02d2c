// Simulator (models/simulate.hpp) against closed forms and an independent integrator (scipy
// solve_ivp fixtures made by tests/data/models/make_fixtures.py).

#include <Eigen/Dense>
#include <boost/numeric/odeint.hpp>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <random>
#include <thread>

#include "data/csv.hpp"
#include "models/butterworth.hpp"
#include "models/linear_endpoint.hpp"
#include "models/presets.hpp"
#include "models/simulate.hpp"

namespace m = stiffid::models;

namespace {

const std::string kData = std::string(STIFFID_TEST_DATA_DIR) + "/models/";

double max_abs(const Eigen::MatrixXd& a) { return a.cwiseAbs().maxCoeff(); }

m::TrialSpec fixture_spec(double fs, double duration) {
  m::TrialSpec spec;
  spec.sample_rate_hz = fs;
  spec.duration_s = duration;
  spec.joint = m::piovesan_kelvin_voigt();
  // Tighter than the defaults so the comparison measures the models, not the tolerances.
  spec.integrator.absolute_tolerance = 1e-12;
  spec.integrator.relative_tolerance = 1e-11;
  return spec;
}

// Joint angles of a simulated trial against a scipy fixture (columns t, fx, fy, th1, th2).
void check_against_fixture(const m::TrialSpec& spec, const std::string& file) {
  const stiffid::data::Trial ref = stiffid::data::read_trial_csv(kData + file);
  std::mt19937_64 rng(1);
  const m::SimulationResult r = m::simulate(spec, rng);
  BOOST_REQUIRE(r.status.ok);
  BOOST_REQUIRE_EQUAL(r.trial.sample_count(), ref.sample_count());
  const Eigen::MatrixXd angles = r.trial.columns({"th1", "th2"});
  const Eigen::MatrixXd ref_angles = ref.columns({"th1", "th2"});
  // Issue 4 asks for 1e-6 rad; both integrators run at ~1e-11 relative tolerance, so the observed
  // difference is ~1e-9 rad and 1e-6 rad leaves room only for a modelling difference to fail.
  BOOST_TEST_MESSAGE(file << ": max |dtheta| = " << max_abs(angles - ref_angles) << " rad");
  BOOST_CHECK_LT(max_abs(angles - ref_angles), 1e-6);
  // Forces: identical definitions, only the angle-dependent servo force can differ (by K_servo *
  // hand error ~ 2e4 N/m * 1e-9 m).
  BOOST_CHECK_LT(max_abs(r.trial.columns({"fx", "fy"}) - ref.columns({"fx", "fy"})), 1e-4);
}

}  // namespace

BOOST_AUTO_TEST_CASE(kelvin_voigt_1dof_free_decay_matches_closed_form) {
  // m x'' + c x' + k x = 0, x(0) = x0, x'(0) = 0: underdamped closed form.
  const double mass = 2.0, k = 200.0, c = 4.0, x0 = 0.01;
  m::TrialSpec spec;
  spec.model = m::ModelKind::endpoint;
  spec.duration_s = 2.0;
  spec.sample_rate_hz = 1000.0;
  spec.endpoint.inertia_kg = Eigen::MatrixXd::Constant(1, 1, mass);
  spec.endpoint.element.kind = m::ElementKind::kelvin_voigt;
  spec.endpoint.element.stiffness = Eigen::MatrixXd::Constant(1, 1, k);
  spec.endpoint.element.damping = Eigen::MatrixXd::Constant(1, 1, c);
  spec.initial_deviation = Eigen::VectorXd::Constant(1, x0);
  spec.integrator.kind = m::IntegratorKind::dopri5;
  std::mt19937_64 rng(3);
  const m::SimulationResult r = m::simulate(spec, rng);
  BOOST_REQUIRE(r.status.ok);
  const double wn = std::sqrt(k / mass), zeta = c / (2.0 * std::sqrt(k * mass));
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  double worst = 0.0;
  for (int s = 0; s < r.trial.sample_count(); ++s) {
    const double t = r.truth.time_s(s);
    const double x =
        std::exp(-zeta * wn * t) * (x0 * std::cos(wd * t) + zeta * wn * x0 / wd * std::sin(wd * t));
    worst = std::max(worst, std::abs(r.trial.samples(s, r.trial.index("x")) - x));
  }
  // Local error per step <= 1e-10 m + 1e-9 * |x|; over ~1e3 steps the global error stays below
  // 1e-8 m (0.0001 % of x0).
  BOOST_TEST_MESSAGE("free decay max error " << worst << " m");
  BOOST_CHECK_LT(worst, 1e-8);
  // The exact method is exact for this linear time-invariant system.
  spec.integrator.kind = m::IntegratorKind::exact;
  const m::SimulationResult e = m::simulate(spec, rng);
  double worst_exact = 0.0;
  for (int s = 0; s < e.trial.sample_count(); ++s) {
    const double t = e.truth.time_s(s);
    const double x =
        std::exp(-zeta * wn * t) * (x0 * std::cos(wd * t) + zeta * wn * x0 / wd * std::sin(wd * t));
    worst_exact = std::max(worst_exact, std::abs(e.trial.samples(s, 1) - x));
  }
  // Round-off of 2000 products by a matrix exponential computed to ~1e-15: ~1e-14 relative.
  BOOST_CHECK_LT(worst_exact, 1e-12);
}

BOOST_AUTO_TEST_CASE(linear_endpoint_matches_scipy_lsim_and_zoh) {
  const stiffid::data::Trial ref = stiffid::data::read_trial_csv(kData + "endpoint_lsim.csv");
  const Eigen::MatrixXd u = ref.columns({"fx", "fy"});
  const m::EndpointModel model = m::reference_endpoint_model();
  const Eigen::Vector2d x0(0.002, -0.001), v0(0.01, 0.0);
  const m::LinearResponse foh =
      m::simulate_linear_endpoint(model.inertia_kg, model.element.damping, model.element.stiffness,
                                  u, 50.0, m::InputHold::first_order, x0, v0);
  const m::LinearResponse zoh =
      m::simulate_linear_endpoint(model.inertia_kg, model.element.damping, model.element.stiffness,
                                  u, 50.0, m::InputHold::zero_order, x0, v0);
  // Both sides are matrix-exponential discretizations of the same system: agreement to round-off
  // (~1e-16 relative on displacements of ~1e-2 m); 1e-12 m allows for different expm algorithms.
  BOOST_CHECK_LT(max_abs(foh.position - ref.columns({"x_foh", "y_foh"})), 1e-12);
  BOOST_CHECK_LT(max_abs(zoh.position - ref.columns({"x_zoh", "y_zoh"})), 1e-12);
}

BOOST_AUTO_TEST_CASE(endpoint_ode_integration_agrees_with_exact_discretization) {
  // Both adaptive paths against the matrix exponential: dopri5 with dense output on every
  // segment, and the default (Fehlberg 7(8) landing on each segment end, the segments here being
  // the sample intervals of the first-order-hold random force).
  m::TrialSpec spec = m::perreault_endpoint_trial(25.0, std::numeric_limits<double>::infinity());
  spec.duration_s = 10.0;
  std::mt19937_64 rng_exact(11);
  const m::SimulationResult exact = m::simulate(spec, rng_exact);
  BOOST_CHECK(exact.integrator == m::IntegratorKind::exact);
  for (const m::IntegratorKind kind : {m::IntegratorKind::dopri5, m::IntegratorKind::adaptive}) {
    spec.integrator.kind = kind;
    std::mt19937_64 rng(11);
    const m::SimulationResult ode = m::simulate(spec, rng);
    BOOST_REQUIRE(ode.status.ok);
    BOOST_CHECK(ode.integrator == kind);
    BOOST_TEST_MESSAGE(m::integrator_kind_name(kind)
                       << ": " << ode.steps << " steps, max |dx| = "
                       << max_abs(exact.trial.columns({"x", "y"}) - ode.trial.columns({"x", "y"}))
                       << " m");
    // Same forces (same seed), up to the round-off of evaluating the linear interpolation at its
    // knots (~1e-16 relative of ~0.5 N). Displacements ~5e-4 m; 1e-10 m absolute tolerance per
    // step, ~500 segments: well below 1e-9 m.
    BOOST_CHECK_LT(max_abs(exact.trial.columns({"fx", "fy"}) - ode.trial.columns({"fx", "fy"})),
                   1e-12);
    BOOST_CHECK_LT(max_abs(exact.trial.columns({"x", "y"}) - ode.trial.columns({"x", "y"})), 1e-9);
  }
}

BOOST_AUTO_TEST_CASE(undamped_free_arm_conserves_kinetic_energy) {
  m::TrialSpec spec;
  spec.duration_s = 2.0;
  spec.sample_rate_hz = 500.0;
  spec.joint.kind = m::ElementKind::none;
  spec.initial_deviation_rate = Eigen::Vector2d(1.0, -1.5);
  spec.integrator.absolute_tolerance = 1e-12;
  spec.integrator.relative_tolerance = 1e-12;
  std::mt19937_64 rng(1);
  const m::SimulationResult r = m::simulate(spec, rng);
  BOOST_REQUIRE(r.status.ok);
  const m::ArmParameters arm;
  auto energy = [&](int s) {
    const Eigen::Vector2d th = r.truth.position.row(s).transpose();
    const Eigen::Vector2d w = r.truth.velocity.row(s).transpose();
    return 0.5 * w.dot(m::inertia_matrix(arm, th) * w);
  };
  const double e0 = energy(0);
  double worst = 0.0;
  for (int s = 0; s < r.trial.sample_count(); ++s)
    worst = std::max(worst, std::abs(energy(s) - e0));
  // The arm moves (by ~1 rad): the check is not vacuous.
  BOOST_CHECK_GT(std::abs(r.truth.position(r.trial.sample_count() - 1, 1) - r.truth.position(0, 1)),
                 0.1);
  // Error control at 1e-12 relative per step over ~1e3 steps: relative drift well below 1e-8.
  BOOST_TEST_MESSAGE("kinetic energy drift " << worst / e0);
  BOOST_CHECK_LT(worst / e0, 1e-8);
}

BOOST_AUTO_TEST_CASE(unperturbed_reach_follows_eqs_50_51) {
  m::TrialSpec spec = m::piovesan_impulse_trial(m::TaskKind::reach, m::ProfileKind::sigmoid,
                                                m::ProfileKind::constant, 0.0);
  spec.perturbations.pulses.clear();
  std::mt19937_64 rng(1);
  const m::SimulationResult r = m::simulate(spec, rng);
  BOOST_REQUIRE(r.status.ok);
  double worst = 0.0;
  for (int s = 0; s < r.trial.sample_count(); s += 7) {
    const double t = r.truth.time_s(s);
    // Eqs 50-51: G = 0.3 m, B = 4, Q = 1, D = 0.25 m, E = T/2 = 2.5 s; y = 0.
    const double x = 0.3 / (1.0 + std::exp(-4.0 * (t - 2.5))) + 0.25;
    worst = std::max(worst, std::abs(r.trial.samples(s, r.trial.index("x")) - x));
    worst = std::max(worst, std::abs(r.trial.samples(s, r.trial.index("y"))));
  }
  BOOST_CHECK_LT(worst, 1e-9);
}

BOOST_AUTO_TEST_CASE(feedforward_torque_drives_the_free_arm_along_eqs_50_51) {
  // Integrate the arm in absolute angles with only the feedforward torque (no viscoelasticity):
  // if tau_ff is the exact inverse dynamics, the hand follows eq 50 (up to integration error).
  const m::ArmParameters arm;
  m::ArmTask task;
  task.kind = m::TaskKind::reach;
  using State = std::array<double, 4>;
  auto rhs = [&](const State& x, State& dx, double t) {
    const m::ReferencePoint ref = m::arm_reference(arm, task, 5.0, t);
    const Eigen::Vector2d th(x[0], x[1]), w(x[2], x[3]);
    const Eigen::Vector2d acc = m::inertia_matrix(arm, th).llt().solve(
        m::feedforward_torque(arm, ref) - m::coriolis_matrix(arm, th, w) * w);
    dx = {w(0), w(1), acc(0), acc(1)};
  };
  const m::ReferencePoint r0 = m::arm_reference(arm, task, 5.0, 0.0);
  State x{r0.theta_rad(0), r0.theta_rad(1), r0.theta_dot_rad_per_s(0), r0.theta_dot_rad_per_s(1)};
  namespace odeint = boost::numeric::odeint;
  double worst = 0.0;
  auto observe = [&](const State& s, double t) {
    const Eigen::Vector2d hand = m::hand_position(arm, Eigen::Vector2d(s[0], s[1]));
    const double xe = 0.3 / (1.0 + std::exp(-4.0 * (t - 2.5))) + 0.25;
    worst = std::max({worst, std::abs(hand(0) - xe), std::abs(hand(1))});
  };
  odeint::integrate_const(
      odeint::make_dense_output(1e-13, 1e-13, odeint::runge_kutta_dopri5<State>()), rhs, x, 0.0,
      5.0, 0.01, observe);
  // The free arm is unstable about the path (no stiffness), so integration error grows; at 1e-13
  // tolerances it stays far below the 1e-9 m asked by issue 4.
  BOOST_TEST_MESSAGE("open-loop reach error " << worst << " m");
  BOOST_CHECK_LT(worst, 1e-9);
}

BOOST_AUTO_TEST_CASE(posture_impulse_with_sigmoid_stiffness_matches_scipy) {
  m::TrialSpec spec = fixture_spec(1000.0, 1.0);
  spec.joint.stiffness_profile = {m::ProfileKind::sigmoid, 0.2, 1.0, {}, {}};
  spec.perturbations.pulses = {m::force_impulse(0.2, M_PI / 4)};
  check_against_fixture(spec, "arm_posture_impulse_sigmoid.csv");
}

BOOST_AUTO_TEST_CASE(reach_pulse_with_sharp_profiles_matches_scipy) {
  m::TrialSpec spec = fixture_spec(1000.0, 2.0);
  spec.task.kind = m::TaskKind::reach;
  spec.task.reach_midpoint_s = 1.0;
  spec.joint.stiffness_profile = {m::ProfileKind::sharp, 1.0, 2.0, {}, {}};
  spec.joint.damping_profile = {m::ProfileKind::sharp, 1.0, 2.0, {}, {}};
  spec.perturbations.pulses = {m::force_pulse(1.0, 3 * M_PI / 4)};
  check_against_fixture(spec, "arm_reach_pulse_sharp.csv");
}

BOOST_AUTO_TEST_CASE(ramp_and_hold_servo_matches_scipy) {
  m::TrialSpec spec = fixture_spec(1000.0, 0.8);
  m::DisplacementRamp ramp;
  ramp.onset_s = 0.1;
  ramp.direction_rad = M_PI / 2;
  spec.perturbations.ramps = {ramp};
  check_against_fixture(spec, "arm_posture_ramp.csv");
}

BOOST_AUTO_TEST_CASE(duffing_and_poynting_thomson_match_scipy) {
  m::TrialSpec duffing = fixture_spec(1000.0, 0.6);
  duffing.joint = m::piovesan_duffing();
  duffing.perturbations.pulses = {m::force_impulse(0.1, M_PI)};
  duffing.integrator.absolute_tolerance = 1e-12;
  check_against_fixture(duffing, "arm_posture_duffing.csv");
  m::TrialSpec pt = fixture_spec(1000.0, 0.6);
  pt.joint = m::piovesan_poynting_thomson();
  pt.perturbations.pulses = {m::force_impulse(0.1, -M_PI / 2)};
  check_against_fixture(pt, "arm_posture_poynting_thomson.csv");
}

BOOST_AUTO_TEST_CASE(butterworth_matches_scipy) {
  const stiffid::data::Trial ref = stiffid::data::read_trial_csv(
      kData + "butterworth.csv", stiffid::data::TrialCsvOptions{"", 1.0});
  const Eigen::VectorXd x = ref.columns({"x"});
  const struct {
    int order;
    double fc, fs;
    const char* column;
  } cases[] = {{4, 9.0, 50.0, "y_4_9_50"},
               {3, 100.0, 4000.0, "y_3_100_4000"},
               {5, 20.0, 1000.0, "y_5_20_1000"}};
  for (const auto& c : cases) {
    const Eigen::VectorXd y = m::sos_filter(m::butterworth_lowpass_sos(c.order, c.fc, c.fs), x);
    // Same filter, sections paired differently: round-off only (signal ~1, 400 samples).
    BOOST_CHECK_LT(max_abs(y - ref.columns({c.column})), 1e-11);
  }
}

BOOST_AUTO_TEST_CASE(coupling_and_snr_give_the_requested_statistics) {
  const m::TrialSpec spec = m::perreault_endpoint_trial(25.0, 20.0);
  std::mt19937_64 rng(5);
  const m::SimulationResult r = m::simulate(spec, rng);
  const Eigen::MatrixXd f = r.trial.columns({"fx", "fy"});
  const Eigen::VectorXd f1 = f.col(0).array() - f.col(0).mean();
  const Eigen::VectorXd f2 = f.col(1).array() - f.col(1).mean();
  const double r2 = std::pow(f1.dot(f2), 2) / (f1.squaredNorm() * f2.squaredNorm());
  // Coupling is imposed on the sample (Gram-Schmidt): exact up to round-off.
  BOOST_CHECK_CLOSE(r2, 0.25, 1e-9);
  BOOST_CHECK_CLOSE(f.col(0).maxCoeff() - f.col(0).minCoeff(), 1.0, 1e-9);
  // Output noise: the realized noise RMS over the signal RMS is 10^(-20/20) = 0.1 within the
  // sampling error of an RMS from N = 3000 independent draws (relative sd 1/sqrt(2N) = 1.3 %):
  // 5 % is ~4 sd.
  for (int c = 0; c < 2; ++c) {
    const Eigen::VectorXd noise = r.trial.samples.col(2 + c) - r.truth.position.col(c);
    const double ratio = std::sqrt(noise.squaredNorm() / r.truth.position.col(c).squaredNorm());
    BOOST_CHECK_CLOSE(ratio, 0.1, 5.0);
  }
}

namespace {
// Welch power (Hann, 10 s segments, no overlap) of x at fs, averaged over the bins in [low, high]
// Hz, by direct DFT of those bins only.
double band_power(const Eigen::VectorXd& x, double fs, double low, double high) {
  const int n = static_cast<int>(std::lround(10.0 * fs));
  double sum = 0.0;
  int count = 0;
  for (int bin = static_cast<int>(std::ceil(low * n / fs)); bin * fs / n <= high; ++bin) {
    for (Eigen::Index start = 0; start + n <= x.size(); start += n) {
      std::complex<double> acc = 0.0;
      for (int t = 0; t < n; ++t) {
        const double window = 0.5 - 0.5 * std::cos(2.0 * M_PI * t / n);
        acc += window * x(start + t) * std::polar(1.0, -2.0 * M_PI * bin * t / n);
      }
      sum += std::norm(acc);
      ++count;
    }
  }
  return sum / count;
}

// |H(f)|^2 of the second-order sections at fs (z = exp(2 pi i f / fs)).
double sos_power(const Eigen::MatrixXd& sos, double f, double fs) {
  const std::complex<double> z1 = std::polar(1.0, -2.0 * M_PI * f / fs);
  std::complex<double> h = 1.0;
  for (Eigen::Index k = 0; k < sos.rows(); ++k) {
    h *= (sos(k, 0) + sos(k, 1) * z1 + sos(k, 2) * z1 * z1) /
         (sos(k, 3) + sos(k, 4) * z1 + sos(k, 5) * z1 * z1);
  }
  return std::norm(h);
}
}  // namespace

BOOST_AUTO_TEST_CASE(oversampled_random_forces_keep_the_analog_roll_off_above_the_band) {
  // 9 Hz 4th-order forces at 50 Hz, 20 min. Filtered at the trial rate (oversample 1) the
  // bilinear zero at 25 Hz empties 22-25 Hz (the IRF solve then has cond(Psi) ~1e12); filtered at
  // 10 x 50 Hz and read every 10th sample, the power there is the roll-off of the filter at 500 Hz
  // plus its aliases about 50 Hz: sum_k |H(f + 50 k)|^2, k = -5..4, relative to the 1-5 Hz band.
  m::RandomForce options;
  const double fs = 50.0;
  const int samples = 60000;
  auto ratio = [&](int oversample) {
    options.oversample = oversample;
    std::mt19937_64 rng(17);
    const Eigen::MatrixXd f = m::random_forces(options, samples, 1, fs, rng);
    return band_power(f.col(0), fs, 22.0, 25.0) / band_power(f.col(0), fs, 1.0, 5.0);
  };
  const double digital = ratio(1);
  const double analog = ratio(10);
  const Eigen::MatrixXd sos = m::butterworth_lowpass_sos(4, 9.0, 500.0);
  auto aliased = [&](double low, double high) {
    double sum = 0.0;
    int count = 0;
    for (double f = low; f <= high + 1e-9; f += 0.1, ++count)
      for (int k = -5; k <= 4; ++k) sum += sos_power(sos, f + 50.0 * k, 500.0);
    return sum / count;
  };
  const double expected = aliased(22.0, 25.0) / aliased(1.0, 5.0);
  BOOST_TEST_MESSAGE("22-25 Hz / 1-5 Hz power: oversample 1 "
                     << digital << ", oversample 10 " << analog << ", expected " << expected);
  BOOST_CHECK_LT(digital, 1e-6);
  // 120 segments x 31 bins: the band averages have a relative sd of ~2 %; 15 % is generous.
  BOOST_CHECK_CLOSE(analog, expected, 15.0);
}

BOOST_AUTO_TEST_CASE(same_seed_gives_identical_trials_on_any_thread) {
  std::vector<m::TrialSpec> specs = {
      m::perreault_endpoint_trial(50.0, 10.0), m::perreault_arm_trial(2),
      m::piovesan_impulse_trial(m::TaskKind::reach, m::ProfileKind::sharp, m::ProfileKind::constant,
                                0.0)};
  specs[1].duration_s = 10.0;
  specs[2].perturbations.pulses[0].random_octant = true;
  specs[2].noise.signal_dependent = true;
  std::vector<Eigen::MatrixXd> serial;
  for (const auto& s : specs) {
    std::mt19937_64 rng(42);
    serial.push_back(m::simulate(s, rng).trial.samples);
  }
  std::vector<Eigen::MatrixXd> parallel(specs.size());
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < specs.size(); ++k) {
    threads.emplace_back([&, k] {
      std::mt19937_64 rng(42);
      parallel[k] = m::simulate(specs[k], rng).trial.samples;
    });
  }
  for (auto& t : threads) t.join();
  for (std::size_t k = 0; k < specs.size(); ++k) {
    BOOST_CHECK(serial[k].cwiseEqual(parallel[k]).all());
  }
  std::mt19937_64 other(43);
  BOOST_CHECK(!serial[0].cwiseEqual(m::simulate(specs[0], other).trial.samples).all());
}
