#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <boost/numeric/odeint.hpp>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <cstdint>
#include <functional>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "data/error.hpp"
#include "estimators/cubic_bspline.hpp"
#include "estimators/damped_modes.hpp"

using stiffid::InputError;
using stiffid::estimators::DampedModesOptions;
using stiffid::estimators::DampedModesResult;
using stiffid::estimators::DecayTracks;
using stiffid::estimators::fit_damped_modes;
using stiffid::estimators::UniformCubicBspline;

namespace {

constexpr double kRateHz = 4000.0;  // as the paper's simulations: 5 s at 4 kHz, pulse at 2.5 s
constexpr double kOnsetS = 2.5;
constexpr double kFreeS = 2.52;  // end of the 20 ms pulse: the free response starts here

// A damped oscillation with closed-form phase integral: x_k(t) = Re(a_k exp(Phi(t - kFreeS))),
// Phi(tau) = int_0^tau alpha + i omega.
struct ClosedFormMode {
  std::function<double(double)> f_hz;               // f(tau)
  std::function<double(double)> alpha_per_s;        // alpha(tau)
  std::function<std::complex<double>(double)> phi;  // Phi(tau), closed form
  std::complex<double> a0, a1;
};

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
// int_0^tau sigmoid(k (s - c)) ds = (ln(1 + e^{k(tau - c)}) - ln(1 + e^{-k c})) / k
double sigmoid_integral(double tau, double k, double c) {
  return (std::log1p(std::exp(k * (tau - c))) - std::log1p(std::exp(-k * c))) / k;
}

Eigen::MatrixXd response(const std::vector<ClosedFormMode>& modes) {
  const int s = static_cast<int>(5.0 * kRateHz);
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(s, 2);
  for (int i = 0; i < s; ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau < 0.0) continue;
    for (const auto& m : modes) {
      const std::complex<double> e = std::exp(m.phi(tau));
      x(i, 0) += (m.a0 * e).real();
      x(i, 1) += (m.a1 * e).real();
    }
  }
  return x;
}

void add_noise(Eigen::MatrixXd& x, double snr_db, std::uint64_t seed) {
  // SNR relative to the RMS of the free response over both channels (paper: RMS of the signal).
  const int first = static_cast<int>(kOnsetS * kRateHz);
  const double rms = std::sqrt(x.bottomRows(x.rows() - first).squaredNorm() /
                               double((x.rows() - first) * x.cols()));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, rms * std::pow(10.0, -snr_db / 20.0));
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += noise(rng);
}

struct Errors {
  double f_rel = 0.0, alpha_rel = 0.0;  // RMS relative errors
  double alpha_z = 0.0;                 // RMS of alpha error / posterior SD
  int samples = 0, valid = 0;
};

// Over [from_s, to_s] s, the samples within (skip_from_s, skip_to_s) left out (none by default).
Errors track_errors(const DampedModesResult& r, int j, const ClosedFormMode& truth, double from_s,
                    double to_s, double skip_from_s = 0.0, double skip_to_s = 0.0) {
  Errors e;
  double sf = 0.0, sa = 0.0, sz = 0.0;
  for (Eigen::Index i = 0; i < r.t_s.size(); ++i) {
    if (r.t_s(i) < from_s || r.t_s(i) > to_s) continue;
    if (r.t_s(i) > skip_from_s && r.t_s(i) < skip_to_s) continue;
    const double tau = r.t_s(i) - kFreeS;
    ++e.samples;
    e.valid += r.modes[j].valid(i) ? 1 : 0;
    sf += std::pow(r.modes[j].frequency_hz(i) / truth.f_hz(tau) - 1.0, 2);
    sa += std::pow(r.modes[j].alpha_per_s(i) / truth.alpha_per_s(tau) - 1.0, 2);
    sz += std::pow(
        (r.modes[j].alpha_per_s(i) - truth.alpha_per_s(tau)) / r.modes[j].alpha_sd_per_s(i), 2);
  }
  e.alpha_z = std::sqrt(sz / e.samples);
  e.f_rel = std::sqrt(sf / e.samples);
  e.alpha_rel = std::sqrt(sa / e.samples);
  return e;
}

// How both decay rates double during the record: along a sigmoid in time (k = 4/s, centred 1 s
// into the response), as co-contraction would, or linearly over 2 s.
enum class DecayChange { sigmoid, linear };

// Two modes 1 Hz apart (2.4 and 3.4 Hz) whose decay rates double (DecayChange).
std::vector<ClosedFormMode> close_modes(double weak_amplitude,
                                        DecayChange change = DecayChange::sigmoid) {
  auto mode = [change](double f0, double alpha0, std::complex<double> a0, std::complex<double> a1) {
    ClosedFormMode m;
    m.f_hz = [f0](double) { return f0; };
    if (change == DecayChange::sigmoid) {
      m.alpha_per_s = [alpha0](double tau) { return alpha0 * (1.0 + sigmoid(4.0 * (tau - 1.0))); };
      m.phi = [f0, alpha0](double tau) {
        return std::complex<double>(alpha0 * (tau + sigmoid_integral(tau, 4.0, 1.0)),
                                    2.0 * M_PI * f0 * tau);
      };
    } else {
      m.alpha_per_s = [alpha0](double tau) { return alpha0 * (1.0 + 0.5 * tau); };
      m.phi = [f0, alpha0](double tau) {
        return std::complex<double>(alpha0 * (tau + 0.25 * tau * tau), 2.0 * M_PI * f0 * tau);
      };
    }
    m.a0 = a0;
    m.a1 = a1;
    return m;
  };
  return {mode(2.4, -1.0, {1.0, 0.0}, {0.45, 0.05}),
          mode(3.4, -1.3, {-0.4 * weak_amplitude, 0.1 * weak_amplitude}, {weak_amplitude, 0.0})};
}

double energy_fraction(const std::vector<ClosedFormMode>& modes, int j) {
  const Eigen::MatrixXd all = response(modes);
  const Eigen::MatrixXd one = response({modes[j]});
  return one.squaredNorm() / all.squaredNorm();
}

// Fit of `modes` with white noise at snr_db (noise seed `seed`); the fit must succeed.
DampedModesResult fit_noisy(const std::vector<ClosedFormMode>& modes, double snr_db,
                            std::uint64_t seed, const DampedModesOptions& options) {
  Eigen::MatrixXd x = response(modes);
  add_noise(x, snr_db, seed);
  DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, options);
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  return r;
}

// Two modes 1 Hz apart whose tracks the cubic splines represent exactly: omega_j constant,
// alpha_j linear in time.
std::pair<ClosedFormMode, ClosedFormMode> spline_exact_modes() {
  ClosedFormMode m1, m2;
  m1.f_hz = [](double) { return 2.4; };
  m1.alpha_per_s = [](double tau) { return -1.5 - 0.4 * tau; };
  m1.phi = [](double tau) {
    return std::complex<double>(-1.5 * tau - 0.2 * tau * tau, 2.0 * M_PI * 2.4 * tau);
  };
  m1.a0 = {1.0, 0.0};
  m1.a1 = std::polar(0.5, 0.3);
  m2.f_hz = [](double) { return 3.4; };
  m2.alpha_per_s = [](double tau) { return -2.0 + 0.3 * tau; };
  m2.phi = [](double tau) {
    return std::complex<double>(-2.0 * tau + 0.15 * tau * tau, 2.0 * M_PI * 3.4 * tau);
  };
  m2.a0 = {-0.1, 0.05};
  m2.a1 = {0.0, 0.2};
  return {m1, m2};
}

// The tolerances of an exact fit of spline_exact_modes() (first test), valid throughout.
void check_exact_tracks(const DampedModesResult& r, const ClosedFormMode& m1,
                        const ClosedFormMode& m2) {
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(r, j, j == 0 ? m1 : m2, 2.6, 4.9);
    BOOST_TEST_MESSAGE("mode " << j << ": f " << e.f_rel << ", alpha " << e.alpha_rel);
    BOOST_CHECK_SMALL(e.f_rel, 1e-5);
    BOOST_CHECK_SMALL(e.alpha_rel, 1e-3);
    BOOST_CHECK_EQUAL(e.valid, e.samples);
  }
}

}  // namespace

BOOST_AUTO_TEST_CASE(noise_free_tracks_are_exact_when_the_spline_can_represent_them) {
  // alpha_j linear in time and omega_j constant lie in the cubic spline space: the only errors
  // are the decimation filter's action on a non-stationary envelope (relative O(alpha' s_h^2) with
  // s_h ~ 3 ms the filter's RMS width: ~1e-5) and the solver's tolerance.
  const auto [m1, m2] = spline_exact_modes();
  const Eigen::MatrixXd x = response({m1, m2});
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_REQUIRE_EQUAL(r.modes.size(), 2u);
  // The default fits both decay models; only the alpha splines represent these tracks, and the
  // BIC keeps them (the gamma fit's residual is far above: measured BIC -41051 against -40602).
  BOOST_TEST((r.decay_tracks == DecayTracks::alpha));
  BOOST_TEST(r.alpha_bic < r.gamma_bic);
  check_exact_tracks(r, m1, m2);
  // The amplitude-to-noise ratio follows each mode's envelope: over 1 s it changes by
  // 20 log10(e) (Re Phi(t2) - Re Phi(t1)) dB (the noise level cancels). The tracks are exact to
  // ~1e-6, so 1e-3 dB.
  const Eigen::Index i1 = 20, i2 = i1 + static_cast<Eigen::Index>(r.rate_hz);
  for (int j = 0; j < 2; ++j) {
    const auto& phi = (j == 0 ? m1 : m2).phi;
    const double expected =
        20.0 / std::log(10.0) * (phi(r.t_s(i2) - kFreeS).real() - phi(r.t_s(i1) - kFreeS).real());
    BOOST_CHECK_SMALL(r.modes[j].anr_db(i2) - r.modes[j].anr_db(i1) - expected, 1e-3);
  }
  // Mode shapes: amplitude ratio and relative phase of each mode (eqs 37-42), constant here. The
  // filter's pass-band gain (ripple <= 1e-3 at 60 dB) cancels in the ratio.
  for (Eigen::Index i = 0; i < r.t_s.size(); i += 50) {
    const std::complex<double> ratio1 = r.modes[0].shape(i, 1) / r.modes[0].shape(i, 0);
    const std::complex<double> ratio2 = r.modes[1].shape(i, 1) / r.modes[1].shape(i, 0);
    BOOST_CHECK_SMALL(std::abs(ratio1 - m1.a1 / m1.a0), 1e-4);
    BOOST_CHECK_SMALL(std::abs(ratio2 - m2.a1 / m2.a0), 1e-4);
  }
}

BOOST_AUTO_TEST_CASE(a_constant_offset_is_fitted_not_absorbed_by_the_tracks) {
  // The deviations are taken from a posture estimated before the onset: its error is a constant
  // offset of every sample. Fitted as such (one linear parameter per channel), the spline-exact
  // tracks stay exact and the offset comes back; without it the tracks bend to absorb it.
  const auto [m1, m2] = spline_exact_modes();
  Eigen::MatrixXd x = response({m1, m2});
  const Eigen::RowVector2d offset(0.004, -0.003);  // ~0.4 % of the response's peak
  x.rowwise() += offset;
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  check_exact_tracks(r, m1, m2);
  BOOST_REQUIRE_EQUAL(r.offset_rad.size(), 2);
  // Exact to the solver's tolerance (relative steps 1e-10) and the filter's pass-band gain (1e-4).
  BOOST_CHECK_SMALL(r.offset_rad(0) - offset(0), 1e-6);
  BOOST_CHECK_SMALL(r.offset_rad(1) - offset(1), 1e-6);
  BOOST_CHECK_SMALL((r.fitted - r.data).norm() / r.data.norm(), 1e-4);
  DampedModesOptions without;
  without.offsets = false;
  const DampedModesResult biased = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, without);
  BOOST_REQUIRE_MESSAGE(biased.status.ok, biased.status.message);
  BOOST_CHECK_EQUAL(biased.offset_rad.norm(), 0.0);
  double worst = 0.0;
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(biased, j, j == 0 ? m1 : m2, 2.6, 4.9);
    BOOST_TEST_MESSAGE("without offsets, mode " << j << ": f " << e.f_rel << ", alpha "
                                                << e.alpha_rel);
    worst = std::max(worst, e.alpha_rel);
  }
  BOOST_CHECK_GT(worst, 1e-2);  // ten times the tolerance the offsets keep
}

BOOST_AUTO_TEST_CASE(the_strongest_modes_quadratic_distortion_is_fitted) {
  // A quadratic nonlinearity (the arm's Coriolis and centripetal terms) adds to the response the
  // square of its strongest mode: a slow part exp(2 Re Phi_1) and a second harmonic exp(2 Phi_1).
  // Fitted as such, the spline-exact tracks stay exact; without it they bend to absorb it.
  const auto [m1, m2] = spline_exact_modes();
  Eigen::MatrixXd x = response({m1, m2});
  const std::complex<double> harmonic[2] = {{0.004, -0.002}, {-0.001, 0.003}};
  const double slow[2] = {-0.003, 0.005};  // ~0.5 % of the strongest mode's amplitude
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau < 0.0) continue;
    const std::complex<double> e = std::exp(m1.phi(tau));
    for (int k = 0; k < 2; ++k) x(i, k) += slow[k] * std::norm(e) + (harmonic[k] * e * e).real();
  }
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_CHECK_EQUAL(r.second_order_mode, 0);  // the 2.4 Hz mode, the strongest
  check_exact_tracks(r, m1, m2);
  BOOST_CHECK_SMALL((r.fitted - r.data).norm() / r.data.norm(), 1e-4);
  DampedModesOptions without;
  without.second_order = false;
  const DampedModesResult biased = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, without);
  BOOST_REQUIRE_MESSAGE(biased.status.ok, biased.status.message);
  BOOST_CHECK_EQUAL(biased.second_order_mode, -1);
  double worst = 0.0;
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(biased, j, j == 0 ? m1 : m2, 2.6, 4.9);
    BOOST_TEST_MESSAGE("without the second-order terms, mode " << j << ": f " << e.f_rel
                                                               << ", alpha " << e.alpha_rel);
    worst = std::max(worst, e.alpha_rel);
  }
  BOOST_CHECK_GT(worst, 1e-2);  // ten times the tolerance the terms keep
}

BOOST_AUTO_TEST_CASE(mode_shapes_that_rotate_are_fitted_as_shapes_not_as_rough_tracks) {
  // Both mode shapes of spline_exact_modes() turn by a real rotation R(phi), phi = 0.25 rad/s
  // tau (0.6 rad over the fit), as the eigenvectors of a stiffness ellipse that rotates or
  // changes shape do: |a_j| stays constant, so the tracks are those of the closed form. Stage 1
  // (constant shapes) can follow the change only with rough tracks, which trade with it; the
  // shape refit explains it by the shapes, with the smoothest tracks. 20 dB.
  const auto [m1, m2] = spline_exact_modes();
  const int s = static_cast<int>(5.0 * kRateHz);
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(s, 2);
  for (int i = 0; i < s; ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau < 0.0) continue;
    const double phi = 0.25 * tau;
    for (const ClosedFormMode* m : {&m1, &m2}) {
      const std::complex<double> e = std::exp(m->phi(tau));
      x(i, 0) += ((std::cos(phi) * m->a0 - std::sin(phi) * m->a1) * e).real();
      x(i, 1) += ((std::sin(phi) * m->a0 + std::cos(phi) * m->a1) * e).real();
    }
  }
  add_noise(x, 20.0, 7);
  // The closed form's alpha_j are splines, which the alpha model represents and the gamma model
  // (alpha_j = -Gamma_j - omega_j'/(2 omega_j)) only nearly: the tolerances below are the alpha
  // model's. The default (best) keeps gamma here, by 3 fewer effective parameters for a 0.6 %
  // higher residual, and gets 0.6 / 0.7 % (f) and 2.2 / 6.4 % (alpha).
  DampedModesOptions alpha_model;
  alpha_model.decay_tracks = DecayTracks::alpha;
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, alpha_model);
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  DampedModesOptions without = alpha_model;  // constant shapes, one roughness for the record
  without.shape_refit = false;
  without.local_roughness_dof = 0.0;
  const DampedModesResult rough = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, without);
  BOOST_REQUIRE_MESSAGE(rough.status.ok, rough.status.message);
  BOOST_CHECK(r.shape_refit);
  BOOST_CHECK(!rough.shape_refit);
  BOOST_CHECK_LT(r.track_roughness, rough.track_roughness);
  BOOST_CHECK_LT(r.shape_weight, 1.0);  // the shapes vary
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(r, j, j == 0 ? m1 : m2, 2.6, 4.5);
    const Errors w = track_errors(rough, j, j == 0 ? m1 : m2, 2.6, 4.5);
    BOOST_TEST_MESSAGE("mode " << j << ", refit (roughness " << r.track_roughness << ", weight "
                               << r.shape_weight << "): f " << e.f_rel << ", alpha " << e.alpha_rel
                               << "; constant shapes (roughness " << rough.track_roughness
                               << "): f " << w.f_rel << ", alpha " << w.alpha_rel);
    // Measured 0.6 / 0.8 % (f) and 2.1 / 4.8 % (alpha): the shapes' freedom costs precision
    // (the weak mode's orthogonal component trades with its track), but the constant-shape fit
    // is off by 2 / 13 % and 9 / 114 %.
    BOOST_CHECK_LE(e.f_rel, 0.01);
    BOOST_CHECK_LE(e.alpha_rel, 0.06);
    BOOST_CHECK_EQUAL(e.valid, e.samples);
    BOOST_CHECK_GT(w.alpha_rel, 2.0 * e.alpha_rel);
  }
  // With the ties asked for (opt-in), the untied refit is still offered, and taken: the shapes'
  // change is no common factor. It drops the ties, and the result is the default's.
  DampedModesOptions tied = alpha_model;
  tied.decay_tie = tied.frequency_tie = -1.0;
  const DampedModesResult t = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, tied);
  BOOST_REQUIRE_MESSAGE(t.status.ok, t.status.message);
  BOOST_TEST_MESSAGE("ties asked for: refit " << t.shape_refit << ", decay tie " << t.decay_tie
                                              << ", frequency tie " << t.frequency_tie);
  BOOST_CHECK(t.shape_refit);
  BOOST_CHECK_EQUAL(t.decay_tie, 0.0);
  BOOST_CHECK_EQUAL(t.frequency_tie, 0.0);
  BOOST_CHECK_EQUAL(t.modes[1].decay_ratio, 1.0);
  BOOST_CHECK_EQUAL(t.modes[1].frequency_ratio, 1.0);
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(t, j, j == 0 ? m1 : m2, 2.6, 4.5);
    BOOST_TEST_MESSAGE("ties asked for, mode " << j << ": f " << e.f_rel << ", alpha "
                                               << e.alpha_rel);
    BOOST_CHECK_LE(e.f_rel, 0.01);
    BOOST_CHECK_LE(e.alpha_rel, 0.06);
  }
}

BOOST_AUTO_TEST_CASE(a_shape_turning_in_the_mass_metric_keeps_its_modal_decay_and_frequency) {
  // The tracks of spline_exact_modes() with real mode shapes that turn as an arm's eigenvectors
  // do: a_j(tau) = M^-1/2 R(phi) M^1/2 a_j(0), phi = 0.25 rad/s tau, so that the modal amplitude
  // |a_j|_M stays constant for M = [2 0.6; 0.6 0.5] (kg m^2, say) while the Euclidean one does
  // not. The fit holds each mode's amplitude along its constant shape fixed, the varying part
  // orthogonal in the whitened channels: the amplitude change along the constant shape goes into
  // alpha_j unless the decay and frequency are read as the modal coordinate's in the mass metric
  // (DampedModesOptions::mass_metric). 20 dB, 8 noise draws; medians over the draws (a draw whose
  // fit keeps constant shapes, which the metric does not change, counts as it comes).
  auto [m1, m2] = spline_exact_modes();
  m1.a0 = 1.0, m1.a1 = 0.5;
  m2.a0 = -0.3, m2.a1 = 0.6;
  Eigen::Matrix2d mass;
  mass << 2.0, 0.6, 0.6, 0.5;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(mass);
  const Eigen::Matrix2d root = eig.operatorSqrt(), inverse_root = eig.operatorInverseSqrt();
  const int s = static_cast<int>(5.0 * kRateHz);
  Eigen::MatrixXd clean = Eigen::MatrixXd::Zero(s, 2);
  for (int i = 0; i < s; ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau < 0.0) continue;
    const Eigen::Matrix2d turn =
        inverse_root * Eigen::Rotation2Dd(0.25 * tau).toRotationMatrix() * root;
    for (const ClosedFormMode* m : {&m1, &m2}) {
      const Eigen::Vector2d shape = turn * Eigen::Vector2d(m->a0.real(), m->a1.real());
      clean.row(i) += std::exp(m->phi(tau)).real() * shape.transpose();
    }
  }
  DampedModesOptions with_mass;
  with_mass.mass_metric = [&mass](const Eigen::VectorXd& t_s) {
    return std::vector<Eigen::MatrixXd>(t_s.size(), mass);
  };
  // errors[j][k]: mode j, k = 0 alpha with the metric, 1 alpha without, 2 f with, 3 f without.
  std::vector<double> errors[2][4];
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    Eigen::MatrixXd x = clean;
    add_noise(x, 20.0, seed);
    const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, with_mass);
    const DampedModesResult plain = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, {});
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    BOOST_REQUIRE_MESSAGE(plain.status.ok, plain.status.message);
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(r, j, j == 0 ? m1 : m2, 2.6, 4.5);
      const Errors w = track_errors(plain, j, j == 0 ? m1 : m2, 2.6, 4.5);
      BOOST_TEST_MESSAGE("draw " << seed << ", mode " << j << ": alpha " << e.alpha_rel
                                 << " with the mass metric, " << w.alpha_rel << " without; f "
                                 << e.f_rel << ", " << w.f_rel);
      for (const auto& [k, value] :
           {std::pair{0, e.alpha_rel}, {1, w.alpha_rel}, {2, e.f_rel}, {3, w.f_rel}})
        errors[j][k].push_back(value);
    }
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return 0.5 * (v[(v.size() - 1) / 2] + v[v.size() / 2]);
  };
  // Measured medians: strong mode alpha 2.7 % (9.5 % without), f 0.2 % (0.7 %); weak mode alpha
  // 7.9 % (9.3 % without), f 0.6 % (0.4 %): the correction carries the slope of the weak mode's
  // shape splines, noisiest at the record's ends where that mode has decayed. (Draw 2 loses the
  // weak mode with either reading: its fit keeps constant shapes.)
  BOOST_CHECK_LE(median(errors[0][0]), 0.05);
  BOOST_CHECK_LE(median(errors[0][0]), 0.5 * median(errors[0][1]));
  BOOST_CHECK_LE(median(errors[0][2]), 0.005);
  BOOST_CHECK_LE(median(errors[1][0]), 0.1);
  BOOST_CHECK_LE(median(errors[1][0]), median(errors[1][1]));
  BOOST_CHECK_LE(median(errors[1][2]), 0.01);
  // A metric of the wrong size is refused before the fit.
  DampedModesOptions wrong;
  wrong.mass_metric = [](const Eigen::VectorXd& t_s) {
    return std::vector<Eigen::MatrixXd>(t_s.size(), Eigen::MatrixXd::Identity(3, 3));
  };
  BOOST_CHECK_THROW(fit_damped_modes(clean, kRateHz, 0.0, kOnsetS, wrong), std::invalid_argument);
}

BOOST_AUTO_TEST_CASE(close_modes_with_a_weak_one_at_20_db_within_one_percent) {
  const std::vector<ClosedFormMode> modes = close_modes(0.26);
  const double weak = energy_fraction(modes, 1);
  BOOST_TEST_MESSAGE("weak mode energy fraction " << weak);
  BOOST_REQUIRE(weak > 0.04 && weak < 0.06);  // the case asked for: 5 % of the energy
  Eigen::MatrixXd x = response(modes);
  add_noise(x, 20.0, 7);
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  for (int j = 0; j < 2; ++j) {
    // Issue 7 target for the frequencies: 1 % (RMS relative error over 2.6-4.5 s). The decay rates
    // are held to their posterior SD instead (RMS of error / SD <= 2.5; 1 when calibrated, the
    // margin for the noise covariance from 0.155 s of pre-onset data, +-20 % in variance): the
    // 1 % target is NOT met (docs/tfa_modal.md). On this draw the weak mode's decay is off by
    // 3.6 % (the strong one's 1.0 %); with the opt-in decay tie (next test but one) both by
    // 1.9 %. For the weak mode the 1 % is below the Cramer-Rao bound of any decay track that
    // changes at all (1.9 % for a linear one: next test, and scripts/tfa_crb_tracks.py).
    const Errors e = track_errors(r, j, modes[j], 2.6, 4.5);
    BOOST_TEST_MESSAGE("mode " << j << ": f " << e.f_rel << ", alpha " << e.alpha_rel
                               << ", alpha error / SD " << e.alpha_z << ", valid " << e.valid << "/"
                               << e.samples);
    BOOST_CHECK_SMALL(e.f_rel, 0.01);
    BOOST_CHECK_SMALL(e.alpha_z, 2.5);
    // Both modes are well above the noise for the first 1.5 s (ANR > 15 dB): all valid there.
    const Errors early = track_errors(r, j, modes[j], 2.6, 4.0);
    BOOST_CHECK_EQUAL(early.valid, early.samples);
  }
  // Same seed, same bits (deterministic fit).
  const DampedModesResult again = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_CHECK(again.modes[1].alpha_per_s == r.modes[1].alpha_per_s);
}

BOOST_AUTO_TEST_CASE(decay_rates_of_close_modes_at_20_db_are_near_their_cramer_rao_bound) {
  // The 1 % for the decay rates at 20 dB is below the information in the data for the
  // weak mode whenever its decay changes at all: scripts/tfa_crb_tracks.py (numpy/scipy, an
  // independent computation) gives the Cramer-Rao bound of any unbiased estimator of decay
  // tracks linear in time, frequencies linear, constant shapes, RMS over 2.6-4.5 s of SD /
  // |alpha|: 0.42 % (strong) and 1.95 % (weak) on this case (linear change; constant decay:
  // 0.18 / 0.68 %). The default fit is held to twice the bound, RMS over eight noise draws.
  const double bound[2] = {0.0042, 0.0195};
  const std::vector<ClosedFormMode> modes = close_modes(0.26, DecayChange::linear);
  const double weak = energy_fraction(modes, 1);
  BOOST_REQUIRE(weak > 0.04 && weak < 0.06);
  double sum[2] = {0.0, 0.0};
  const int draws = 8;
  for (int seed = 1; seed <= draws; ++seed) {
    const DampedModesResult r =
        fit_noisy(modes, 20.0, static_cast<std::uint64_t>(seed), DampedModesOptions{});
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(r, j, modes[j], 2.6, 4.5);
      BOOST_TEST_MESSAGE("seed " << seed << ", mode " << j << ": f " << e.f_rel << ", alpha "
                                 << e.alpha_rel);
      BOOST_CHECK_SMALL(e.f_rel, 0.01);  // the frequencies meet the 1 %
      sum[j] += e.alpha_rel * e.alpha_rel;
    }
  }
  for (int j = 0; j < 2; ++j) {
    const double rms = std::sqrt(sum[j] / draws);
    BOOST_TEST_MESSAGE("mode " << j << ": RMS alpha error " << rms << ", bound " << bound[j]);
    BOOST_CHECK_LE(rms, 2.0 * bound[j]);
  }
}

BOOST_AUTO_TEST_CASE(decay_tie_is_taken_for_a_common_factor_and_refused_otherwise) {
  // The decay tie is opt-in (decay_tie < 0: its SD from the data).
  DampedModesOptions from_data;
  from_data.decay_tie = -1.0;
  // Tied truth: both decays follow the same sigmoid, alpha_2 / alpha_1 = 1.3 throughout (the
  // case above). The tie is taken and its ratio recovered; it must not cost the frequencies.
  {
    const std::vector<ClosedFormMode> modes = close_modes(0.26);
    Eigen::MatrixXd x = response(modes);
    add_noise(x, 20.0, 7);
    const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, from_data);
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    BOOST_TEST_MESSAGE("tied truth: tie SD " << r.decay_tie << ", ratio "
                                             << r.modes[1].decay_ratio);
    BOOST_CHECK_GT(r.decay_tie, 0.0);
    BOOST_CHECK_EQUAL(r.modes[0].decay_ratio, 1.0);
    BOOST_CHECK_CLOSE(r.modes[1].decay_ratio, 1.3, 3.0);  // percent
    for (int j = 0; j < 2; ++j) {
      BOOST_CHECK_SMALL(track_errors(r, j, modes[j], 2.6, 4.5).f_rel, 0.01);
    }
    // By default there is no tie.
    const DampedModesResult u = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
    BOOST_CHECK_EQUAL(u.decay_tie, 0.0);
    BOOST_CHECK_EQUAL(u.modes[1].decay_ratio, 1.0);
  }
  // Untied truth: the 3.4 Hz mode (a quarter of the energy) keeps its decay while the 2.4 Hz
  // mode's doubles. The data contradict any tie: it is refused, or so loose that each decay
  // stays within its posterior SD of the truth.
  {
    std::vector<ClosedFormMode> modes = close_modes(0.8);
    modes[1].alpha_per_s = [](double) { return -1.3; };
    modes[1].phi = [](double tau) {
      return std::complex<double>(-1.3 * tau, 2.0 * M_PI * 3.4 * tau);
    };
    const DampedModesResult r = fit_noisy(modes, 20.0, 11, from_data);
    BOOST_TEST_MESSAGE("untied truth: energy of mode 2 " << energy_fraction(modes, 1) << ", tie SD "
                                                         << r.decay_tie);
    BOOST_CHECK(r.decay_tie == 0.0 || r.decay_tie >= 0.1);
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(r, j, modes[j], 2.6, 4.5);
      BOOST_TEST_MESSAGE("mode " << j << ": alpha " << e.alpha_rel << ", error / SD " << e.alpha_z);
      BOOST_CHECK_SMALL(e.alpha_z, 2.5);
    }
  }
}

// Two modes (2.4 and 3.4 Hz at the onset, constant decays -1 and -1.3 1/s) whose frequencies
// are f0_j (1 + rise_j sigmoid(5 (tau - 0.8))): with equal rises, the common factor of a
// stiffness that scales as a whole (co-contraction).
std::vector<ClosedFormMode> rising_modes(double weak_amplitude, double rise0, double rise1) {
  auto mode = [](double f0, double alpha, double rise, std::complex<double> a0,
                 std::complex<double> a1) {
    ClosedFormMode m;
    m.f_hz = [f0, rise](double tau) { return f0 * (1.0 + rise * sigmoid(5.0 * (tau - 0.8))); };
    m.alpha_per_s = [alpha](double) { return alpha; };
    m.phi = [f0, alpha, rise](double tau) {
      return std::complex<double>(alpha * tau,
                                  2.0 * M_PI * f0 * (tau + rise * sigmoid_integral(tau, 5.0, 0.8)));
    };
    m.a0 = a0;
    m.a1 = a1;
    return m;
  };
  return {
      mode(2.4, -1.0, rise0, {1.0, 0.0}, {0.45, 0.05}),
      mode(3.4, -1.3, rise1, {-0.4 * weak_amplitude, 0.1 * weak_amplitude}, {weak_amplitude, 0.0})};
}

BOOST_AUTO_TEST_CASE(frequency_tie_is_taken_for_a_common_factor_and_refused_otherwise) {
  // The frequency tie is opt-in (frequency_tie < 0: its SD from the data).
  DampedModesOptions from_data;
  from_data.frequency_tie = -1.0;
  // Tied truth: both frequencies rise by 50 % along one sigmoid, the 3.4 Hz mode with 5 % of
  // the energy. The tie is taken and its ratio, 3.4 / 2.4, recovered.
  {
    const std::vector<ClosedFormMode> modes = rising_modes(0.26, 0.5, 0.5);
    const double weak = energy_fraction(modes, 1);
    BOOST_REQUIRE(weak > 0.04 && weak < 0.06);
    Eigen::MatrixXd x = response(modes);
    add_noise(x, 20.0, 7);
    const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, from_data);
    BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
    BOOST_TEST_MESSAGE("tied truth: tie SD " << r.frequency_tie << ", ratio "
                                             << r.modes[1].frequency_ratio << ", roughness "
                                             << r.track_roughness);
    BOOST_CHECK_GT(r.frequency_tie, 0.0);
    BOOST_CHECK_EQUAL(r.decay_tie, 0.0);  // not asked for
    BOOST_CHECK_EQUAL(r.modes[0].frequency_ratio, 1.0);
    BOOST_CHECK_CLOSE(r.modes[1].frequency_ratio, 3.4 / 2.4, 0.5);  // percent
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(r, j, modes[j], 2.6, 4.5);
      BOOST_TEST_MESSAGE("mode " << j << ": f " << e.f_rel << ", alpha " << e.alpha_rel);
      BOOST_CHECK_SMALL(e.f_rel, 0.01);
    }
    // By default there is no tie.
    const DampedModesResult u = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
    BOOST_CHECK_EQUAL(u.frequency_tie, 0.0);
    BOOST_CHECK_EQUAL(u.modes[1].frequency_ratio, 1.0);
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(u, j, modes[j], 2.6, 4.5);
      BOOST_TEST_MESSAGE("no tie, mode " << j << ": f " << e.f_rel << ", alpha " << e.alpha_rel);
    }
  }
  // Untied truth: the 3.4 Hz mode (a quarter of the energy) rises by 40 % while the 2.4 Hz mode
  // keeps its frequency. The data contradict any tie: it is refused, or so loose that both
  // frequencies stay within 1 %.
  {
    const std::vector<ClosedFormMode> modes = rising_modes(0.8, 0.0, 0.4);
    const DampedModesResult r = fit_noisy(modes, 20.0, 11, from_data);
    BOOST_TEST_MESSAGE("untied truth: energy of mode 2 " << energy_fraction(modes, 1) << ", tie SD "
                                                         << r.frequency_tie);
    BOOST_CHECK(r.frequency_tie == 0.0 || r.frequency_tie >= 0.1);
    for (int j = 0; j < 2; ++j) {
      const Errors e = track_errors(r, j, modes[j], 2.6, 4.5);
      BOOST_TEST_MESSAGE("mode " << j << ": f " << e.f_rel);
      BOOST_CHECK_SMALL(e.f_rel, 0.01);
    }
  }
}

BOOST_AUTO_TEST_CASE(a_real_exponential_beside_the_modes_is_a_real_term) {
  // The two modes of the first test plus b_k exp(beta tau), beta = -2 1/s, about half their
  // amplitude (a Poynting-Thomson element's fibre creep: its real poles). Noise-free the fit is
  // exact to the tolerances of the first test; the rate and amplitudes to 1e-4.
  const auto [m1, m2] = spline_exact_modes();
  const double beta = -2.0;
  const Eigen::Vector2d b(0.35, -0.45);  // at the free response's start, tau = 0
  Eigen::MatrixXd x = response({m1, m2});
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const double tau = i / kRateHz - kFreeS;
    if (tau >= 0.0) x.row(i) += std::exp(beta * tau) * b.transpose();
  }
  // By default (real_terms < 0) the start adds the fewest real terms with which its pencil finds
  // both oscillations.
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_REQUIRE_EQUAL(r.real_terms.size(), 1u);
  const double tau0 = r.t_s(0) - kFreeS;  // the term's amplitude is at the first fitted sample
  BOOST_TEST_MESSAGE("real term: rate " << r.real_terms[0].rate_per_s << " +- "
                                        << r.real_terms[0].rate_sd_per_s << " 1/s");
  BOOST_CHECK_CLOSE(r.real_terms[0].rate_per_s, beta, 1e-4 * 100);
  BOOST_CHECK_SMALL((r.real_terms[0].amplitude - std::exp(beta * tau0) * b).norm(),
                    1e-4 * b.norm());
  check_exact_tracks(r, m1, m2);
  // The model includes the term: it reproduces the (filtered) data.
  BOOST_CHECK_SMALL((r.fitted - r.data).norm() / r.data.norm(), 1e-4);
  // Without it the start finds no second oscillation, and says so.
  DampedModesOptions none;
  none.real_terms = 0;
  const DampedModesResult without = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, none);
  BOOST_TEST_MESSAGE("real_terms 0: " << without.status.message);
  BOOST_CHECK(!without.status.ok);
  // At 20 dB the rate is within 3 posterior SDs of the truth.
  add_noise(x, 20.0, 5);
  const DampedModesResult noisy = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(noisy.status.ok, noisy.status.message);
  BOOST_REQUIRE_EQUAL(noisy.real_terms.size(), 1u);
  BOOST_TEST_MESSAGE("20 dB: rate " << noisy.real_terms[0].rate_per_s << " +- "
                                    << noisy.real_terms[0].rate_sd_per_s << " 1/s");
  BOOST_CHECK_SMALL(noisy.real_terms[0].rate_per_s - beta, 3.0 * noisy.real_terms[0].rate_sd_per_s);
}

BOOST_AUTO_TEST_CASE(the_sliding_design_is_exact_on_locally_linear_tracks) {
  // Design (a): omega_j constant and alpha_j linear in time are exactly what each window's model
  // holds, so noise-free every window recovers them (to the decimation filter's effect, as in
  // the first test); its estimates start half a window after the whole-record fit's and end half
  // a window before.
  const auto [m1, m2] = spline_exact_modes();
  const Eigen::MatrixXd x = response({m1, m2});
  DampedModesOptions sliding;
  sliding.design = stiffid::estimators::ModalDesign::sliding;
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, sliding);
  const DampedModesResult whole = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_CHECK(r.converged);
  const Eigen::Index half = std::lround(0.25 * r.rate_hz);
  BOOST_CHECK_EQUAL(r.t_s.size(), whole.t_s.size() - 2 * half);
  BOOST_CHECK_SMALL(r.t_s(0) - whole.t_s(half), 1e-12);
  for (int j = 0; j < 2; ++j) {
    const Errors e = track_errors(r, j, j == 0 ? m1 : m2, 2.6, 4.6);
    BOOST_TEST_MESSAGE("sliding, mode " << j << ": f " << e.f_rel << ", alpha " << e.alpha_rel);
    BOOST_CHECK_SMALL(e.f_rel, 1e-5);
    BOOST_CHECK_SMALL(e.alpha_rel, 1e-3);
    // Valid while a 0.5 s window pins the frequency to the 0.1 Hz SD of the validity rule (at the
    // 40 dB floor of noise-free data, until the weak mode's ANR falls below ~27 dB, 3.3 s): the
    // window's posterior is that of half a second of data, the whole-record fit's of all of it.
    const Errors early = track_errors(r, j, j == 0 ? m1 : m2, 2.6, 3.2);
    BOOST_CHECK_EQUAL(early.valid, early.samples);
    // The slopes are the tracks' derivatives: d alpha / dt = -0.4 and 0.3 1/s^2.
    const double slope = j == 0 ? -0.4 : 0.3;
    BOOST_CHECK_SMALL(r.modes[j].alpha_dot_per_s2(r.t_s.size() / 2) - slope, 1e-3);
    BOOST_CHECK_SMALL(r.modes[j].omega_dot_rad_per_s2(r.t_s.size() / 2), 1e-3);
  }
  // The mode shapes of the truth (eqs 37-42).
  for (Eigen::Index i = 0; i < r.t_s.size(); i += 50) {
    BOOST_CHECK_SMALL(std::abs(r.modes[0].shape(i, 1) / r.modes[0].shape(i, 0) - m1.a1 / m1.a0),
                      1e-4);
    BOOST_CHECK_SMALL(std::abs(r.modes[1].shape(i, 1) / r.modes[1].shape(i, 0) - m2.a1 / m2.a0),
                      1e-4);
  }
  // The model reproduces the data at the window centres.
  BOOST_CHECK_SMALL((r.fitted - r.data).norm() / r.data.norm(), 1e-4);
  DampedModesOptions bad = sliding;
  bad.sliding_window_s = 0.0;
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, kOnsetS, bad), InputError);
  bad.sliding_window_s = 10.0;  // longer than the free response
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, kOnsetS, bad), InputError);
  BOOST_CHECK_THROW(stiffid::estimators::parse_modal_design("windows"), InputError);
}

BOOST_AUTO_TEST_CASE(a_mode_sinking_into_the_noise_is_flagged_invalid) {
  // The weak mode decays fast (alpha -6 1/s) and is lost in the 10 dB noise within ~0.5 s: its
  // track must be flagged invalid there, and wherever it is flagged valid it must be right.
  std::vector<ClosedFormMode> modes = close_modes(0.3);
  modes[1].alpha_per_s = [](double) { return -6.0; };
  modes[1].phi = [](double tau) {
    return std::complex<double>(-6.0 * tau, 2.0 * M_PI * 3.4 * tau);
  };
  Eigen::MatrixXd x = response(modes);
  add_noise(x, 10.0, 11);
  const DampedModesResult r = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE(!r.modes.empty());
  const auto& weak = r.modes[1];
  int valid_late = 0, valid_wrong = 0;
  for (Eigen::Index i = 0; i < r.t_s.size(); ++i) {
    if (!weak.valid(i)) continue;
    if (r.t_s(i) > 4.0) ++valid_late;  // 1.5 s in: the mode is 80 dB below its start
    // Valid samples: within 3 % (a few posterior SDs at the validity limit of 0.1 Hz).
    if (std::abs(weak.frequency_hz(i) / 3.4 - 1.0) > 0.03) ++valid_wrong;
  }
  BOOST_CHECK_EQUAL(valid_late, 0);
  BOOST_CHECK_EQUAL(valid_wrong, 0);
}

// The weak mode of close_modes() decaying fast (alpha -5 1/s) while its frequency rises by 30 %
// along a sigmoid (k = 4/s, centred 0.6 s into the response): it sinks into the 20 dB noise while
// the change is under way.
std::vector<ClosedFormMode> sinking_while_rising_modes() {
  constexpr double k = 4.0, centre = 0.6, rise = 0.3, f0 = 3.4, alpha = -5.0;
  std::vector<ClosedFormMode> modes = close_modes(0.3);
  modes[1].f_hz = [](double tau) { return f0 * (1.0 + rise * sigmoid(k * (tau - centre))); };
  modes[1].alpha_per_s = [](double) { return alpha; };
  modes[1].phi = [](double tau) {
    return std::complex<double>(alpha * tau,
                                2.0 * M_PI * f0 * (tau + rise * sigmoid_integral(tau, k, centre)));
  };
  return modes;
}

// Two modes whose frequencies double within 0.15 s (10-90 %) along a steep sigmoid (k = 30/s)
// 1.2 s into the response, as with a stiffness that quadruples (sharp K, docs/tfa_modal.md), the
// decay rates constant.
std::vector<ClosedFormMode> stepping_modes() {
  constexpr double k = 30.0, centre = 1.2;
  auto mode = [](double f0, double alpha, std::complex<double> a0, std::complex<double> a1) {
    ClosedFormMode m;
    m.f_hz = [f0](double tau) { return f0 * (1.0 + sigmoid(k * (tau - centre))); };
    m.alpha_per_s = [alpha](double) { return alpha; };
    m.phi = [f0, alpha](double tau) {
      return std::complex<double>(alpha * tau,
                                  2.0 * M_PI * f0 * (tau + sigmoid_integral(tau, k, centre)));
    };
    m.a0 = a0;
    m.a1 = a1;
    return m;
  };
  return {mode(2.4, -1.0, {1.0, 0.0}, {0.45, 0.05}), mode(3.4, -1.3, {-0.3, 0.1}, {0.7, 0.0})};
}

BOOST_AUTO_TEST_CASE(a_step_in_the_tracks_gets_a_local_roughness_and_the_rest_stays_smooth) {
  // One roughness for the whole record must be as rough as the step, and then lets the tracks
  // wobble everywhere else. The local roughness (Student-t prior, local_roughness_dof) is rough
  // only at the step. 20 dB, fixed seed.
  const std::vector<ClosedFormMode> modes = stepping_modes();
  const DampedModesResult local = fit_noisy(modes, 20.0, 3, DampedModesOptions{});
  DampedModesOptions uniform_options;
  uniform_options.local_roughness_dof = 0.0;
  const DampedModesResult uniform = fit_noisy(modes, 20.0, 3, uniform_options);
  BOOST_REQUIRE(uniform.roughness_sd.size() == 0);  // one roughness: no profile
  BOOST_REQUIRE(local.roughness_sd.size() > 0);
  BOOST_REQUIRE_EQUAL(local.roughness_sd.size(), local.roughness_t_s.size());
  BOOST_TEST_MESSAGE("roughness: uniform " << uniform.track_roughness << ", local scale "
                                           << local.track_roughness << ", local max "
                                           << local.roughness_sd.maxCoeff());
  // The roughness peaks at the step (knots 0.1 s apart) and is far lower elsewhere.
  const double step_s = kFreeS + 1.2;
  Eigen::Index peak = 0;
  local.roughness_sd.maxCoeff(&peak);
  BOOST_CHECK_SMALL(local.roughness_t_s(peak) - step_s, 0.15);
  for (Eigen::Index i = 0; i < local.roughness_sd.size(); ++i)
    if (std::abs(local.roughness_t_s(i) - step_s) > 0.35)
      BOOST_CHECK_LT(local.roughness_sd(i), 0.1 * local.roughness_sd(peak));
  for (int j = 0; j < 2; ++j) {
    // Away from the step (|t - step| >= 0.3 s, where the splines need not follow a 0.15 s
    // change).
    const Errors away = track_errors(local, j, modes[j], 2.6, 4.5, step_s - 0.3, step_s + 0.3);
    const Errors away_uniform =
        track_errors(uniform, j, modes[j], 2.6, 4.5, step_s - 0.3, step_s + 0.3);
    const double local_f = away.f_rel, uniform_f = away_uniform.f_rel;
    const double local_a = away.alpha_rel, uniform_a = away_uniform.alpha_rel;
    BOOST_TEST_MESSAGE("mode " << j << " away from the step: f " << local_f << " (uniform "
                               << uniform_f << "), alpha " << local_a << " (uniform " << uniform_a
                               << ")");
    // Measured (seed 3): f 0.075 / 0.049 % (uniform 2.8 / 1.7 %), alpha 1.1 / 0.9 % (uniform 55
    // / 36 %, the wobble of tracks as rough as the step: 3, the grid's roughest).
    BOOST_CHECK_SMALL(local_f, 0.003);
    BOOST_CHECK_SMALL(local_a, 0.05);
    BOOST_CHECK_GT(uniform_a, 5.0 * local_a);
    // Over the whole record, the step included: the 1 % on the frequencies (measured
    // 0.43 / 0.44 %; alpha 1.2 / 1.7 %).
    const Errors whole = track_errors(local, j, modes[j], 2.6, 4.5);
    BOOST_TEST_MESSAGE("mode " << j << " 2.6-4.5 s: f " << whole.f_rel << ", alpha "
                               << whole.alpha_rel << ", valid " << whole.valid << "/"
                               << whole.samples);
    BOOST_CHECK_SMALL(whole.f_rel, 0.01);
    BOOST_CHECK_SMALL(whole.alpha_rel, 0.05);
  }
}

// Two uncoupled oscillators q_j'' + 2 Gamma_j q_j' + eta_j(t)^2 q_j = 0 with constant damping
// rates Gamma_j and eta_j^2 x 5 along a sigmoid of k = 30/s centred 1.2 s into the free response
// (K x 5 within 0.15 s at a constant C, as the sharp posture profile), started at kFreeS from
// q = 0, q' = 1 (an impulse), seen in two channels through constant shapes. Integrated by odeint
// (Dormand-Prince 5, tolerances 1e-12), independent of the fit.
constexpr double kSharpGamma[2] = {1.2, 2.3};  // 1/s
double sharp_eta2(int j, double tau) {         // rad^2/s^2
  const double f0 = j == 0 ? 2.4 : 3.4;
  return std::pow(2.0 * M_PI * f0, 2) * (1.0 + 4.0 * sigmoid(30.0 * (tau - 1.2)));
}
Eigen::MatrixXd sharp_oscillators() {
  namespace odeint = boost::numeric::odeint;
  using State = std::array<double, 4>;  // q_0, q_0', q_1, q_1'
  auto rhs = [](const State& x, State& dx, double tau) {
    for (int j = 0; j < 2; ++j) {
      dx[2 * j] = x[2 * j + 1];
      dx[2 * j + 1] = -2.0 * kSharpGamma[j] * x[2 * j + 1] - sharp_eta2(j, tau) * x[2 * j];
    }
  };
  const int s = static_cast<int>(5.0 * kRateHz);
  const int first = static_cast<int>(std::lround(kFreeS * kRateHz));
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(s, 2);
  State q = {0.0, 1.0, 0.0, 0.6};
  auto stepper = odeint::make_dense_output(1e-12, 1e-12, odeint::runge_kutta_dopri5<State>());
  std::vector<double> times;
  for (int i = first; i < s; ++i) times.push_back((i - first) / kRateHz);
  int i = first;
  odeint::integrate_times(stepper, rhs, q, times.begin(), times.end(), 1e-4,
                          [&](const State& state, double) {
                            x(i, 0) = state[0] + 0.5 * state[2];
                            x(i, 1) = 0.4 * state[0] - state[2];
                            ++i;
                          });
  return x;
}

BOOST_AUTO_TEST_CASE(effective_parameters_count_the_free_coefficients_under_the_prior) {
  // Constant shapes, no offsets, second-order or real terms, a fixed track roughness: the fit has
  // 2 modes x 2 tracks x m spline coefficients and 2 modes x 2 channels complex amplitudes. With
  // a stiff prior on the second differences only each track's straight line is free: 4 x 2 + 8 =
  // 16 effective parameters, whatever m. The count grows with the roughness and never exceeds
  // 4 m + 8 (all free; a loose prior comes within 5 %: the end knots, which the data hardly
  // determine, count less). Both decay models have these counts. And BIC = N ln(RSS) + ln(N) dof,
  // N = T x C whitened values. (A prior 1e4 times stiffer than the one below falls under the
  // trace's 1e-10 relative eigenvalue floor and loses the straight lines' directions too.)
  const auto [m1, m2] = spline_exact_modes();
  Eigen::MatrixXd x = response({m1, m2});
  add_noise(x, 20.0, 11);
  DampedModesOptions o;
  o.shape_knot_spacing_s = 0.0;
  o.offsets = false;
  o.second_order = false;
  o.real_terms = 0;
  for (const DecayTracks model : {DecayTracks::alpha, DecayTracks::gamma}) {
    o.decay_tracks = model;
    std::vector<DampedModesResult> fits;
    // Prior SD of the second differences, rad/s and 1/s: straight lines .. no constraint.
    for (const double roughness : {1e-4, 1e-2, 1.0, 1e3}) {
      o.track_roughness = roughness;
      fits.push_back(fit_damped_modes(x, kRateHz, 0.0, kOnsetS, o));
      BOOST_REQUIRE_MESSAGE(fits.back().status.ok, fits.back().status.message);
    }
    const DampedModesResult &stiff = fits.front(), &loose = fits.back();
    const double length_s = loose.t_s(loose.t_s.size() - 1) - loose.t_s(0);
    const int m = UniformCubicBspline(length_s, o.knot_spacing_s).size();
    BOOST_TEST_MESSAGE(to_string(model)
                       << ": m = " << m << ", effective parameters " << fits[0].effective_parameters
                       << ", " << fits[1].effective_parameters << ", "
                       << fits[2].effective_parameters << ", " << fits[3].effective_parameters);
    // Measured 16.004, 20.8, 51.6, 113.6 (alpha; m = 27).
    BOOST_CHECK_CLOSE(stiff.effective_parameters, 16.0, 0.1);
    for (std::size_t k = 1; k < fits.size(); ++k)
      BOOST_CHECK_GT(fits[k].effective_parameters, fits[k - 1].effective_parameters + 1.0);
    BOOST_CHECK_LE(loose.effective_parameters, 4.0 * m + 8.0 + 1e-6);
    BOOST_CHECK_GE(loose.effective_parameters, 0.95 * (4.0 * m + 8.0));
    const double n = static_cast<double>(loose.t_s.size() * 2);
    const double rss = n * loose.residual_rms_whitened * loose.residual_rms_whitened;
    BOOST_CHECK_CLOSE(loose.bic, n * std::log(rss) + std::log(n) * loose.effective_parameters,
                      1e-9);
    BOOST_TEST(std::isnan(loose.alpha_bic));  // one model asked for: no comparison
  }
  // best keeps the lower BIC of the two, alpha on a tie, and reports both.
  o.decay_tracks = DecayTracks::best;
  o.track_roughness = 0.03;
  const DampedModesResult best = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, o);
  BOOST_REQUIRE_MESSAGE(best.status.ok, best.status.message);
  BOOST_TEST(best.bic == std::min(best.alpha_bic, best.gamma_bic));
  BOOST_TEST((best.decay_tracks ==
              (best.gamma_bic < best.alpha_bic ? DecayTracks::gamma : DecayTracks::alpha)));
}

BOOST_AUTO_TEST_CASE(damping_tracks_keep_gamma_through_a_sharp_stiffness_change) {
  // Eq 45's Gamma_j = -alpha_j - omega_j' / (2 omega_j) is constant here while alpha_j dips by
  // omega_j' / (2 omega_j) (up to ~6 1/s) during the change. With the decay splines the modal
  // damping (DecayTracks::gamma), the dip follows from the frequency track; with alpha_j splines
  // it must be fitted, and Gamma_j takes the difference of two fitted transients. 20 dB, fixed
  // seed. DecayTracks::best (the default) keeps the gamma fit, whose residual and effective
  // number of parameters are both the lower (measured 1.013 / 28.1 against 1.019 / 38.0).
  Eigen::MatrixXd x = sharp_oscillators();
  add_noise(x, 20.0, 5);
  DampedModesOptions gamma_options, alpha_options;
  gamma_options.decay_tracks = DecayTracks::gamma;
  alpha_options.decay_tracks = DecayTracks::alpha;
  const DampedModesResult gamma = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, gamma_options);
  const DampedModesResult alpha = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, alpha_options);
  const DampedModesResult best = fit_damped_modes(x, kRateHz, 0.0, kOnsetS, DampedModesOptions{});
  BOOST_REQUIRE_MESSAGE(best.status.ok, best.status.message);
  BOOST_TEST((gamma.decay_tracks == DecayTracks::gamma));
  BOOST_TEST((alpha.decay_tracks == DecayTracks::alpha));
  BOOST_TEST(std::isnan(gamma.alpha_residual_rms_whitened));
  // best: both fits, bit-identical to the single ones, the lower BIC kept.
  BOOST_TEST(best.alpha_residual_rms_whitened == alpha.residual_rms_whitened);
  BOOST_TEST(best.gamma_residual_rms_whitened == gamma.residual_rms_whitened);
  BOOST_TEST(best.alpha_bic == alpha.bic);
  BOOST_TEST(best.gamma_bic == gamma.bic);
  BOOST_TEST(gamma.bic < alpha.bic);
  BOOST_TEST(gamma.effective_parameters < alpha.effective_parameters);
  BOOST_TEST_MESSAGE("whitened residual RMS: alpha " << alpha.residual_rms_whitened << ", gamma "
                                                     << gamma.residual_rms_whitened);
  BOOST_TEST(gamma.residual_rms_whitened < alpha.residual_rms_whitened);
  BOOST_TEST((best.decay_tracks == DecayTracks::gamma));
  BOOST_TEST(best.iterations == alpha.iterations + gamma.iterations);
  BOOST_TEST((best.modes[0].alpha_per_s.array() == gamma.modes[0].alpha_per_s.array()).all());
  BOOST_REQUIRE_MESSAGE(gamma.status.ok, gamma.status.message);
  BOOST_REQUIRE_MESSAGE(alpha.status.ok, alpha.status.message);
  // RMS relative errors over 2.6-4.5 s of Gamma_j (eq 45) and of eta_j^2 (eq 46).
  auto errors = [](const DampedModesResult& r, int j) {
    double sg = 0.0, se = 0.0;
    int count = 0;
    for (Eigen::Index i = 0; i < r.t_s.size(); ++i) {
      if (r.t_s(i) < 2.6 || r.t_s(i) > 4.5) continue;
      const auto& mt = r.modes[j];
      const double w = mt.omega_rad_per_s(i), a = mt.alpha_per_s(i);
      const double w_dot = mt.omega_dot_rad_per_s2(i), a_dot = mt.alpha_dot_per_s2(i);
      const double g = -a - w_dot / (2.0 * w);
      const double eta2 = w * w + a * a + a * w_dot / w - a_dot;
      sg += std::pow(g / kSharpGamma[j] - 1.0, 2);
      se += std::pow(eta2 / sharp_eta2(j, r.t_s(i) - kFreeS) - 1.0, 2);
      ++count;
    }
    return std::make_pair(std::sqrt(sg / count), std::sqrt(se / count));
  };
  for (int j = 0; j < 2; ++j) {
    const auto [gamma_g, gamma_e] = errors(gamma, j);
    const auto [alpha_g, alpha_e] = errors(alpha, j);
    BOOST_TEST_MESSAGE("mode " << j << ": Gamma " << gamma_g << " (alpha splines " << alpha_g
                               << "), eta^2 " << gamma_e << " (alpha splines " << alpha_e << ")");
    // Measured: Gamma 3.0 / 8.6 % (alpha splines 18.0 / 14.9 %), eta^2 1.4 / 1.0 % (1.2 / 1.1 %).
    BOOST_CHECK_LT(gamma_g, 0.10);
    BOOST_CHECK_LT(gamma_g, 0.7 * alpha_g);
    BOOST_CHECK_LT(gamma_e, 0.03);
  }
}

// A frequency-SD limit that flags the weak mode of sinking_while_rising_modes() well before its
// ANR sinks below the threshold (the default 0.1 Hz flags it at the same sample), Hz.
constexpr double kStrictSdHz = 0.02;

BOOST_AUTO_TEST_CASE(a_lost_modes_tracks_go_on_as_a_damped_trend_not_a_straight_line) {
  // Once the weak mode has sunk below the ANR threshold for good, the data no longer determine
  // its tracks. The splines' prior would continue them in a straight line without bound; from
  // its last sample at or above the threshold they are continued as a damped trend
  // (lost_track_time_s), held with 0, and stay flagged. Only a mode that sank below the ANR
  // threshold is continued.
  const std::vector<ClosedFormMode> modes = sinking_while_rising_modes();
  auto fit = [&](double time_s, double anr_threshold_db = DampedModesOptions{}.anr_threshold_db) {
    DampedModesOptions o;
    o.lost_track_time_s = time_s;
    o.anr_threshold_db = anr_threshold_db;
    return fit_noisy(modes, 20.0, 5, o);
  };
  const DampedModesResult line = fit(-1.0), held = fit(0.0), trend = fit(0.3);
  const auto& weak = trend.modes[1];
  const double threshold_db = DampedModesOptions{}.anr_threshold_db;
  Eigen::Index last = weak.valid.size() - 1, last_valid = last;
  while (last >= 0 && !(weak.anr_db(last) >= threshold_db)) --last;
  while (last_valid >= 0 && !weak.valid(last_valid)) --last_valid;
  BOOST_REQUIRE(last > 0);
  BOOST_REQUIRE(last_valid > 0 && last_valid <= last);
  const double lost_s = trend.t_s(last);
  BOOST_TEST_MESSAGE("weak mode last valid at "
                     << trend.t_s(last_valid) << " s, last at or above the ANR threshold at "
                     << lost_s << " s (" << lost_s - kFreeS << " s into the response)");
  BOOST_REQUIRE(lost_s < kFreeS + 1.0);  // lost while the sigmoid still rises
  const double f0 = weak.frequency_hz(last), slope = weak.omega_dot_rad_per_s2(last) / (2 * M_PI);
  double line_error = 0.0, trend_error = 0.0;
  int lost = 0;
  for (Eigen::Index i = 0; i < trend.t_s.size(); ++i) {
    // Up to the last sample above the threshold the continuation changes nothing (samples the
    // frequency-SD test flagged before it keep the splines' tracks).
    if (i <= last) {
      BOOST_CHECK_EQUAL(trend.modes[1].frequency_hz(i), line.modes[1].frequency_hz(i));
      BOOST_CHECK_EQUAL(trend.modes[1].alpha_per_s(i), line.modes[1].alpha_per_s(i));
      continue;
    }
    ++lost;
    BOOST_CHECK(!weak.valid(i) && !held.modes[1].valid(i) && !line.modes[1].valid(i));
    // Held: the value at the last sample above the threshold, slopes zero.
    BOOST_CHECK_EQUAL(held.modes[1].frequency_hz(i), held.modes[1].frequency_hz(last));
    BOOST_CHECK_EQUAL(held.modes[1].alpha_per_s(i), held.modes[1].alpha_per_s(last));
    BOOST_CHECK_EQUAL(held.modes[1].omega_dot_rad_per_s2(i), 0.0);
    // The damped trend stays between the held value and slope x 0.3 s beyond it.
    const double change = weak.frequency_hz(i) - f0;
    BOOST_CHECK_LE(std::abs(change), std::abs(slope) * 0.3 * (1.0 + 1e-12));
    BOOST_CHECK_GE(change * slope, 0.0);
    const double truth = modes[1].f_hz(trend.t_s(i) - kFreeS);
    line_error += std::pow(line.modes[1].frequency_hz(i) / truth - 1.0, 2);
    trend_error += std::pow(weak.frequency_hz(i) / truth - 1.0, 2);
  }
  BOOST_REQUIRE(lost > 0);
  line_error = std::sqrt(line_error / lost);
  trend_error = std::sqrt(trend_error / lost);
  BOOST_TEST_MESSAGE("after the loss: f RMS relative error, straight line "
                     << line_error << ", damped trend " << trend_error);
  // The strong mode is never lost: unchanged.
  BOOST_CHECK(trend.modes[0].frequency_hz == line.modes[0].frequency_hz);
  BOOST_CHECK_LT(trend_error, line_error);
  // A mode the frequency-SD test flags before its ANR sinks below the threshold (here with a
  // stricter SD limit) keeps the splines' tracks down to its last sample at or above the
  // threshold, and the trend starts there, not at its last valid sample.
  DampedModesOptions strict_options;
  strict_options.max_frequency_sd_hz = kStrictSdHz;
  const DampedModesResult strict = fit_noisy(modes, 20.0, 5, strict_options);
  strict_options.lost_track_time_s = -1.0;
  const DampedModesResult strict_line = fit_noisy(modes, 20.0, 5, strict_options);
  const auto& sw = strict.modes[1];
  Eigen::Index s_last = sw.valid.size() - 1, s_valid = s_last;
  while (s_last >= 0 && !(sw.anr_db(s_last) >= threshold_db)) --s_last;
  while (s_valid >= 0 && !sw.valid(s_valid)) --s_valid;
  BOOST_TEST_MESSAGE("strict SD: last valid at " << strict.t_s(s_valid) << " s, last above the "
                                                 << "threshold at " << strict.t_s(s_last) << " s");
  BOOST_REQUIRE(s_valid > 0 && s_valid + 10 < s_last && s_last + 1 < sw.valid.size());
  for (Eigen::Index i = 0; i <= s_last; ++i)
    BOOST_CHECK_EQUAL(sw.frequency_hz(i), strict_line.modes[1].frequency_hz(i));
  for (Eigen::Index i = s_last + 1; i < sw.valid.size(); ++i) {
    const double decay = std::exp(-(strict.t_s(i) - strict.t_s(s_last)) / 0.3);
    BOOST_CHECK_CLOSE(sw.omega_dot_rad_per_s2(i), sw.omega_dot_rad_per_s2(s_last) * decay, 1e-9);
  }
  // A mode flagged while its ANR has not sunk below the threshold (here -300 dB: only the
  // frequency-SD test flags it) keeps the splines' tracks.
  const DampedModesResult kept = fit(0.3, -300.0), kept_line = fit(-1.0, -300.0);
  BOOST_REQUIRE(!kept.modes[1].valid(kept.t_s.size() - 1));
  BOOST_CHECK(kept.modes[1].frequency_hz == kept_line.modes[1].frequency_hz);
  BOOST_CHECK(kept.modes[1].alpha_per_s == kept_line.modes[1].alpha_per_s);
}

BOOST_AUTO_TEST_CASE(rejects_records_without_noise_window_or_free_response) {
  const Eigen::MatrixXd x = response(close_modes(0.2));
  DampedModesOptions o;
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, 0.05, o), InputError);  // no pre-onset
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, 4.8, o), InputError);   // 0.2 s after
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, 6.0, o), InputError);   // outside
  o.knot_spacing_s = 0.0;
  BOOST_CHECK_THROW(fit_damped_modes(x, kRateHz, 0.0, kOnsetS, o), InputError);
}
