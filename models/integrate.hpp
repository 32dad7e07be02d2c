#pragma once
// Internal to models/: the segment-wise adaptive integration used by simulate(). The right-hand
// side of a trial is smooth between breakpoints (pulse edges, ramp corners, profile starts, the
// samples of a first-order-hold random force). Each segment [a, b] is integrated afresh from a by
// an error-controlled Boost.Odeint stepper:
// - a segment with sample times strictly inside it (a 4 kHz trial between pulse edges): Dormand-
//   Prince 5(4) with dense output; the system continues the segment's smooth pieces past b (via its
//   `branch` member, the segment midpoint), so steps that overshoot b stay accurate, and the state
//   at b and at the samples inside come from the dense output;
// - a segment without (IntegratorKind::adaptive; e.g. between the samples of a random force, the
//   segment then being one sample interval): Runge-Kutta-Fehlberg 7(8), whose last step is cut to
//   land exactly on b. Its higher order takes about one step per 20 ms segment where dopri5 took
//   six (60 s, 50 Hz stochastic arm trial: 3.5k steps instead of 19k, and a 10 times smaller
//   error against a 1e-14 tolerance reference).

#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "models/simulate.hpp"

namespace stiffid::models::detail {

template <class State>
bool all_finite(const State& x) {
  for (double v : x) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

/// Runs `stepper` (a Boost.Odeint dense-output stepper) segment by segment, and `controlled` (a
/// controlled stepper) on the segments without samples inside when `use_controlled`. `rhs` is
/// called as rhs(x, dxdt, t); `record(sample, state, branch)` receives the state at each sample.
template <class Stepper, class Controlled, class State, class Rhs, class SetBranch, class Record>
Status run_segments(Stepper& stepper, Controlled& controlled, bool use_controlled, Rhs&& rhs,
                    SetBranch&& set_branch, State& x, const std::vector<double>& bounds,
                    const Eigen::VectorXd& times, const IntegratorOptions& options, Record&& record,
                    long& steps) {
  const Eigen::Index samples = times.size();
  Eigen::Index next = 0;
  double dt = options.initial_step_s;
  State sample_state = x;
  double branch = 0.0;
  long rejected = 0;  // rejected steps of the controlled stepper
  for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
    const double a = bounds[k], b = bounds[k + 1];
    branch = 0.5 * (a + b);
    set_branch(branch);
    while (next < samples && times(next) <= a) record(static_cast<int>(next++), x, branch);
    if (use_controlled && (next >= samples || times(next) >= b)) {
      // No sample strictly inside: step from a to exactly b with the controlled stepper.
      double t = a;
      while (t < b) {
        double h = std::min(dt, b - t);
        const bool last = h == b - t;
        if (controlled.try_step(rhs, x, t, h) == boost::numeric::odeint::success) {
          if (++steps > options.max_steps) {
            return Status::failure("integrator gave up after " + std::to_string(options.max_steps) +
                                   " steps at t = " + std::to_string(t) + " s");
          }
          if (!all_finite(x)) {
            return Status::failure("the simulated state became non-finite at t = " +
                                   std::to_string(t) + " s (unstable model?)");
          }
          if (last) t = b;  // no round-off gap before b
          dt = last ? std::max(dt, h) : h;
        } else if (++rejected > options.max_steps || !(h > 0.0) || t + h == t) {
          return Status::failure("integrator made no progress at t = " + std::to_string(t) +
                                 " s: step size underflow or too many rejected steps "
                                 "(non-smooth or unstable model?)");
        } else {
          dt = h;
        }
      }
      continue;
    }
    stepper.initialize(x, a, dt);
    while (stepper.current_time() < b) {
      stepper.do_step(rhs);
      if (++steps > options.max_steps) {
        return Status::failure("integrator gave up after " + std::to_string(options.max_steps) +
                               " steps at t = " + std::to_string(stepper.current_time()) + " s");
      }
      if (!all_finite(stepper.current_state())) {
        return Status::failure("the simulated state became non-finite at t = " +
                               std::to_string(stepper.current_time()) + " s (unstable model?)");
      }
      const double reached = std::min(stepper.current_time(), b);
      while (next < samples && times(next) < b && times(next) <= reached) {
        stepper.calc_state(times(next), sample_state);
        record(static_cast<int>(next++), sample_state, branch);
      }
    }
    stepper.calc_state(b, x);
    dt = stepper.current_time_step();
  }
  while (next < samples) record(static_cast<int>(next++), x, branch);
  return Status::success();
}

}  // namespace stiffid::models::detail

namespace stiffid::models {

/// Integrates `system` (callable as system(x, dxdt, t), with a `double branch` member) over the
/// segments `bounds` with `method` (adaptive or dopri5, see IntegratorKind), recording every
/// sample.
/// State is any container of doubles with begin/end/size/operator[] that Odeint resizes.
template <class System, class State, class Record>
Status integrate_segments(IntegratorKind method, System& system, State x,
                          const std::vector<double>& bounds, const Eigen::VectorXd& times,
                          const IntegratorOptions& options, Record&& record, long& steps) {
  namespace odeint = boost::numeric::odeint;
  auto set_branch = [&](double b) { system.branch = b; };
  auto stepper = odeint::make_dense_output(options.absolute_tolerance, options.relative_tolerance,
                                           odeint::runge_kutta_dopri5<State>());
  auto controlled = odeint::make_controlled(options.absolute_tolerance, options.relative_tolerance,
                                            odeint::runge_kutta_fehlberg78<State>());
  return detail::run_segments(stepper, controlled, method == IntegratorKind::adaptive,
                              std::ref(system), set_branch, x, bounds, times, options, record,
                              steps);
}

}  // namespace stiffid::models
