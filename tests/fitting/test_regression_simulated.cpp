// The three classical regressions on stiffid's own simulated arm (nonlinear two-link arm of
// Piovesan eqs 50-54, posture at (0.4, 0) m, Kelvin-Voigt joints K0 = [35 5; 5 20] N m/rad under
// the sigmoid profile of eq 54 from 2.5 s, C0 = 0.01 K0 constant, no noise): 8 directions x 5
// estimation times (2.5 s then every 0.5 s), one perturbation per trial, as in the paper's
// comparison. Issue 8 asks the percentage RMS errors of the time profiles to be reported, with no
// target: they are printed (--log_level=message) for the note and docs/fitting.md. Checked only
// that every method gives five finite estimates.
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <random>
#include <sstream>

#include "fitting/regression.hpp"
#include "models/presets.hpp"
#include "models/simulate.hpp"

namespace sf = stiffid::fitting;
namespace m = stiffid::models;

namespace {

struct Run {
  sf::RegressionResult result;
  m::Truth truth;  // of the first trial (the profiles are the same in every trial)
  double rate_hz = 0.0;
};

Run run(sf::RegressionMethod method) {
  std::vector<stiffid::data::Trial> trials;
  Run out;
  for (const double onset : {2.5, 3.0, 3.5, 4.0, 4.5}) {
    for (int d = 0; d < 8; ++d) {
      const double direction = d * M_PI / 4.0;
      const m::TrialSpec spec =
          method == sf::RegressionMethod::force_pulse
              ? m::piovesan_pulse_trial(m::TaskKind::posture, m::ProfileKind::sigmoid,
                                        m::ProfileKind::constant, direction, onset)
              : m::piovesan_ramp_trial(m::TaskKind::posture, m::ProfileKind::sigmoid,
                                       m::ProfileKind::constant, direction, onset);
      std::mt19937_64 rng(d);
      m::SimulationResult sim = m::simulate(spec, rng);
      BOOST_REQUIRE(sim.status.ok);
      if (trials.empty()) {
        out.truth = sim.truth;
        out.rate_hz = sim.trial.sample_rate_hz;
      }
      trials.push_back(std::move(sim.trial));
    }
  }
  sf::RegressionOptions o;
  o.method = method;
  out.result = sf::regress(trials, nullptr, o);
  return out;
}

Eigen::Matrix2d truth_at(const Run& r, double t, bool damping) {
  const int sample = static_cast<int>(std::lround((t - r.truth.time_s(0)) * r.rate_hz));
  return m::matrix_at(damping ? r.truth.damping : r.truth.stiffness, sample, 2);
}

// 100 RMS(est - true) / RMS(true) of entry (i, j) of the joint K (or B) profile over its times.
double profile_error(const Run& r, int i, int j, bool damping) {
  const sf::RegressionProfile& p = r.result.profile;
  double se = 0.0, st = 0.0;
  for (Eigen::Index k = 0; k < p.t_s.size(); ++k) {
    const Eigen::Matrix2d est = damping ? p.b_joint_nms_per_rad[k] : p.k_joint_nm_per_rad[k];
    const Eigen::Matrix2d tru = truth_at(r, p.t_s(k), damping);
    se += std::pow(est(i, j) - tru(i, j), 2);
    st += std::pow(tru(i, j), 2);
  }
  return 100.0 * std::sqrt(se / st);
}

}  // namespace

BOOST_AUTO_TEST_CASE(sigmoid_stiffness_profiles_of_the_three_regressions) {
  for (const auto method :
       {sf::RegressionMethod::force_pulse, sf::RegressionMethod::displacement_full,
        sf::RegressionMethod::displacement_steady_state}) {
    const Run r = run(method);
    BOOST_REQUIRE_EQUAL(r.result.estimates.size(), 5u);
    std::ostringstream line;
    line << sf::regression_method_name(method) << ": % RMS error of the joint profile over "
         << r.result.profile.t_s(0) << "-" << r.result.profile.t_s(r.result.profile.t_s.size() - 1)
         << " s: k11 " << profile_error(r, 0, 0, false) << " k12 " << profile_error(r, 0, 1, false)
         << " k22 " << profile_error(r, 1, 1, false);
    if (method != sf::RegressionMethod::displacement_steady_state) {
      line << " b11 " << profile_error(r, 0, 0, true) << " b12 " << profile_error(r, 0, 1, true)
           << " b22 " << profile_error(r, 1, 1, true);
    }
    line << "; K at the estimation times:";
    for (const auto& e : r.result.estimates) {
      const Eigen::Matrix2d tru = truth_at(r, e.time_s, false);
      line << " [" << e.time_s << " s: k11 " << e.k_joint_nm_per_rad(0, 0) << " (" << tru(0, 0)
           << ") k22 " << e.k_joint_nm_per_rad(1, 1) << " (" << tru(1, 1) << ")]";
    }
    BOOST_TEST_MESSAGE(line.str());
    for (int k = 0; k < 5; ++k) BOOST_CHECK(r.result.estimates[k].k_joint_nm_per_rad.allFinite());
  }
}
