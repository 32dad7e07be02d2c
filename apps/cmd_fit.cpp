// `stiffid fit kv|pt|duffing TRIAL.csv --inputs f1,f2 --outputs x1,x2 [--hold foh|zoh]
//  [--starts 16] [--seed S] [--bounds FILE] [-o OUT.json]`: lumped-model fit to a time-series trial
// (fitting/lumped_fit.hpp);
// `stiffid fit kv|pt --frf FRF.json [--band LO:HI] [--min-coherence 0.5] [...]`: fit to the
// compliance estimated by `stiffid frf` (fitting/frf_fit.hpp);
// `stiffid fit kv|duffing --tfa TFA.json [--interval A:B]`: constant joint-space Kelvin-Voigt
// matrices (I, C, K in kg m^2, N m s/rad, N m/rad), or Duffing's with the diagonal cubic stiffness
// B (N m/rad^3) from the amplitude dependence of the modal frequencies, from the K(t), C(t), M(t)
// tracks and modal amplitudes of `stiffid tfa` over the valid frames between A and B s
// (fitting/tfa_fit.hpp). A fit that does not converge writes no file and exits 1.

#include <cmath>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "fitting/frf_fit.hpp"
#include "fitting/lumped_fit.hpp"
#include "fitting/tfa_fit.hpp"

namespace stiffid::apps {
namespace {

struct FitArgs {
  std::string model;
  std::string trial;
  std::string inputs;
  std::string outputs;
  std::string hold = "foh";
  int starts = 16;
  std::uint64_t seed = 0;
  std::string bounds;
  std::string frf;
  std::string tfa;
  std::string band;
  std::string interval;
  double min_coherence = 0.5;
  double segment_s = 1.0;
  int max_iterations = 200;
  std::string out;
};

// LO:HI of `flag` (--band in Hz with 0 <= LO, --interval in s), LO < HI.
std::pair<double, double> parse_range(const std::string& text, const std::string& flag,
                                      const std::string& unit, bool non_negative) {
  const auto colon = text.find(':');
  try {
    if (colon == std::string::npos) throw std::invalid_argument("no colon");
    std::size_t used_lo = 0, used_hi = 0;
    const std::string lo = text.substr(0, colon), hi = text.substr(colon + 1);
    const double a = std::stod(lo, &used_lo), b = std::stod(hi, &used_hi);
    if (used_lo != lo.size() || used_hi != hi.size() || !std::isfinite(a) || !std::isfinite(b) ||
        (non_negative && !(a >= 0.0)) || !(b > a)) {
      throw std::invalid_argument("range");
    }
    return {a, b};
  } catch (const std::exception&) {
    throw InputError(flag + ": '" + text + "': expected LO:HI in " + unit + " with " +
                     (non_negative ? "0 <= " : "") + "LO < HI");
  }
}

void run_frf_fit(const FitArgs& a) {
  if (!a.trial.empty() || !a.inputs.empty() || !a.outputs.empty()) {
    throw InputError("--frf: give either TRIAL.csv with --inputs/--outputs or --frf, not both");
  }
  fitting::FrfFitOptions o;
  o.model = fitting::parse_lumped_model(a.model, "fit MODEL");
  o.starts = a.starts;
  o.seed = a.seed;
  o.max_iterations = a.max_iterations;
  o.min_coherence = a.min_coherence;
  if (!a.band.empty()) {
    std::tie(o.band_low_hz, o.band_high_hz) = parse_range(a.band, "--band", "Hz", true);
  }
  if (!a.bounds.empty()) o.ranges = fitting::read_ranges_json(a.bounds, o.model);
  const fitting::FrfTarget target = fitting::read_frf_json(a.frf);
  const fitting::LumpedFitResult r = fitting::fit_frf(target, o);
  if (!r.status.ok) throw NumericalFailure(a.frf + ": " + r.status.message);
  data::write_json(a.out, fitting::to_json(r));
}

void run_tfa_fit(const FitArgs& a) {
  if (!a.trial.empty() || !a.inputs.empty() || !a.outputs.empty() || !a.frf.empty()) {
    throw InputError(
        "--tfa: give either TRIAL.csv with --inputs/--outputs, --frf or --tfa, "
        "not several");
  }
  fitting::TfaFitOptions o;
  o.model = fitting::parse_lumped_model(a.model, "fit MODEL");
  if (!a.interval.empty()) {
    std::tie(o.from_s, o.to_s) = parse_range(a.interval, "--interval", "s", false);
  }
  const fitting::TfaTarget target = fitting::read_tfa_json(a.tfa);
  if (o.model == fitting::LumpedModel::duffing && target.chirped_frames) {
    std::cerr << "stiffid fit: warning: " << a.tfa
              << " comes from the spectrogram's chirped frame fits (the default of tfa "
                 "--method spectrogram); the Duffing backbone was validated on its stationary "
                 "ones (tfa --chirp false), and on the simulator's Duffing trial B moved by "
                 "33-39 % with chirps (docs/fitting.md)\n";
  }
  const fitting::TfaFitResult r = fitting::fit_tfa(target, o);
  if (!r.fit.status.ok) throw NumericalFailure(a.tfa + ": " + r.fit.status.message);
  data::write_json(a.out, fitting::to_json(r));
}

void run_fit(const FitArgs& a) {
  if (!a.tfa.empty()) {
    run_tfa_fit(a);
    return;
  }
  if (!a.interval.empty()) throw InputError("--interval: only with --tfa");
  if (!a.frf.empty()) {
    run_frf_fit(a);
    return;
  }
  if (a.trial.empty()) throw InputError("fit: expected TRIAL.csv (or --frf / --tfa)");
  if (a.inputs.empty()) throw InputError("--inputs: expected the force channels, e.g. fx,fy");
  if (a.outputs.empty())
    throw InputError("--outputs: expected the displacement channels, e.g. x,y");
  fitting::LumpedFitOptions o;
  o.model = fitting::parse_lumped_model(a.model, "fit MODEL");
  o.hold = fitting::parse_input_hold(a.hold);
  o.starts = a.starts;
  o.seed = a.seed;
  o.segment_s = a.segment_s;
  o.max_iterations = a.max_iterations;
  if (!a.bounds.empty()) o.ranges = fitting::read_ranges_json(a.bounds, o.model);
  const data::Trial trial = data::read_trial_csv(a.trial);
  const fitting::LumpedFitResult r = fitting::fit_lumped(
      trial, data::split_list(a.inputs, "--inputs"), data::split_list(a.outputs, "--outputs"), o);
  if (!r.status.ok) throw NumericalFailure(r.status.message);
  data::write_json(a.out, fitting::to_json(r));
}

}  // namespace

void add_fit_command(CLI::App& app) {
  auto args = std::make_shared<FitArgs>();
  CLI::App* cmd = app.add_subcommand(
      "fit", "Fit a lumped model (kv, pt, duffing) to a trial: forces in, displacements out");
  cmd->add_option("model", args->model, "kv | pt | duffing")->required();
  cmd->add_option("trial", args->trial, "trial CSV (t column and channels)");
  cmd->add_option("--inputs", args->inputs, "force channels (N), comma separated");
  cmd->add_option("--outputs", args->outputs, "displacement channels (m), comma separated");
  cmd->add_option("--hold", args->hold, "inputs between samples: foh (linear) or zoh (held)");
  cmd->add_option("--starts", args->starts,
                  "multi-start local solves (box centre + Latin hypercube)");
  cmd->add_option("--seed", args->seed, "seed of the Latin hypercube");
  cmd->add_option("--bounds", args->bounds, "JSON {NAME: [lower, upper]} start box per matrix");
  cmd->add_option("--segment", args->segment_s, "multiple-shooting segment length, s (0: single)");
  cmd->add_option("--max-iterations", args->max_iterations, "iterations per local solve stage");
  cmd->add_option("--frf", args->frf, "fit kv or pt to the compliance in a `stiffid frf` JSON");
  cmd->add_option("--band", args->band, "with --frf: frequencies used, LO:HI in Hz (default all)");
  cmd->add_option("--min-coherence", args->min_coherence,
                  "with --frf: leave out frequencies where an output's multiple coherence is lower")
      ->capture_default_str();
  cmd->add_option("--tfa", args->tfa,
                  "fit kv (joint-space I, C, K) or duffing (and the diagonal B, N m/rad^3, from "
                  "the modal amplitudes) to the K(t), C(t), M(t) tracks of a `stiffid tfa` JSON");
  cmd->add_option("--interval", args->interval,
                  "with --tfa: frame times used, A:B in s (default all valid frames)");
  cmd->add_option("-o,--output", args->out, "output JSON (stdout when absent)");
  cmd->callback([args]() { run_fit(*args); });
}

}  // namespace stiffid::apps
