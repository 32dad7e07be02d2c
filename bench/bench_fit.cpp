// Benchmark of fitting/: 2-DOF Kelvin-Voigt, Poynting-Thomson and Duffing fits to 20 s, 1 kHz
// trials, and a full set of force-pulse regressions (8 directions x 5 estimation times). The peer
// is bench/peer_fit.py (scipy.optimize.least_squares with solve_ivp on the same residual), run on
// the same files.
//
//   bench_fit make DIR [duration_s=20] [rate_hz=1000]   write the trials (not timed)
//   bench_fit fit DIR [kv|pt|duffing|all] [segment_s=0] time the fits (single shooting by default,
//                                                        as the peer; > 0: multiple shooting)
//   bench_fit regress DIR                                time the regressions over DIR/reg/*.csv
//
// Both sides start from the same point: diagonals 1.3 x the truth, off-diagonals 0, one start,
// initial states from the data. Times are printed from std::chrono; time whole processes with
// /usr/bin/time for the side-by-side figures.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>

#include "data/allocator.hpp"
#include "data/csv.hpp"
#include "fitting/lumped_fit.hpp"
#include "fitting/regression.hpp"
#include "models/arm.hpp"

namespace sf = stiffid::fitting;
namespace fs = std::filesystem;

namespace {

struct Truth {
  sf::LumpedModel model;
  std::vector<Eigen::MatrixXd> matrices;
};

Eigen::MatrixXd m2(double a, double b, double c) {
  return (Eigen::MatrixXd(2, 2) << a, b, b, c).finished();
}

std::vector<std::pair<std::string, Truth>> truths() {
  const Eigen::MatrixXd inertia = m2(1.8, 0.3, 1.2), c = m2(15, 3, 10), k = m2(500, 100, 300);
  return {{"kv", {sf::LumpedModel::kelvin_voigt, {inertia, c, k}}},
          {"pt",
           {sf::LumpedModel::poynting_thomson,
            {inertia, m2(1750, 250, 1000), m2(350, 50, 200), m2(40, 6, 25)}}},
          {"duffing", {sf::LumpedModel::duffing, {inertia, c, k, m2(2e6, 0, 1e6)}}}};
}

// Band-limited random forces: white noise through two passes of a one-pole low-pass at 8 Hz,
// 5 N RMS per channel, from a seeded generator.
Eigen::MatrixXd forces(int samples, double rate_hz, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double a = std::exp(-2.0 * M_PI * 8.0 / rate_hz);
  Eigen::MatrixXd f(samples, 2);
  Eigen::Vector2d s1 = Eigen::Vector2d::Zero(), s2 = Eigen::Vector2d::Zero();
  for (int i = -2000; i < samples; ++i) {
    const Eigen::Vector2d w(normal(gen), normal(gen));
    s1 = a * s1 + (1 - a) * w;
    s2 = a * s2 + (1 - a) * s1;
    if (i >= 0) f.row(i) = s2.transpose();
  }
  for (int j = 0; j < 2; ++j) f.col(j) *= 5.0 / std::sqrt(f.col(j).squaredNorm() / samples);
  return f;
}

void write(const fs::path& path, const Eigen::MatrixXd& columns,
           const std::vector<std::string>& names, double rate_hz) {
  stiffid::data::Trial t;
  t.sample_rate_hz = rate_hz;
  t.source = path.string();
  for (std::size_t j = 0; j < names.size(); ++j) t.add_channel(names[j], "", columns.col(j));
  stiffid::data::write_trial_csv(path.string(), t);
}

void make(const fs::path& dir, double duration_s, double rate_hz) {
  fs::create_directories(dir / "reg");
  const int samples = static_cast<int>(duration_s * rate_hz) + 1;
  std::uint64_t seed = 11;
  for (const auto& [name, truth] : truths()) {
    const Eigen::MatrixXd f = forces(samples, rate_hz, seed++);
    const Eigen::VectorXd theta = sf::matrices_to_theta(truth.model, truth.matrices);
    Eigen::VectorXd z0 = Eigen::VectorXd::Zero(sf::state_size(truth.model, 2));
    const Eigen::MatrixXd x =
        sf::simulate_lumped(truth.model, theta, z0, f, rate_hz, sf::InputHold::first_order, 8);
    Eigen::MatrixXd cols(samples, 4);
    cols << f, x;
    write(dir / (name + ".csv"), cols, {"f1", "f2", "x1", "x2"}, rate_hz);
  }
  // Regression trials: endpoint KV model M = I, B = C, K = K above at hand (0.4, 0) m; 5 N,
  // 200 ms pulses in 8 directions at 2.5, 3.0, ..., 4.5 s; each trial 0.6 s around its onset.
  const auto all = truths();
  const Truth& kv = all[0].second;
  const Eigen::VectorXd theta = sf::matrices_to_theta(kv.model, kv.matrices);
  const stiffid::models::ArmParameters arm;
  for (int e = 0; e < 5; ++e) {
    const double onset = 2.5 + 0.5 * e;
    const int first = static_cast<int>(std::llround((onset - 0.25) * 1000.0));
    const int n = 601;
    for (int d = 0; d < 8; ++d) {
      const Eigen::Vector2d u(std::cos(d * M_PI / 4), std::sin(d * M_PI / 4));
      Eigen::MatrixXd f = Eigen::MatrixXd::Zero(n, 2);
      for (int i = 250; i < 450; ++i) f.row(i) = 5.0 * u.transpose();
      // the pulse is a step: simulate from the onset with the force held (ZOH) per piece
      Eigen::MatrixXd x = Eigen::MatrixXd::Zero(n, 2);
      x.bottomRows(n - 250) =
          sf::simulate_lumped(kv.model, theta, Eigen::VectorXd::Zero(4), f.bottomRows(n - 250),
                              1000.0, sf::InputHold::zero_order, 8);
      Eigen::MatrixXd cols(n, 7);
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector2d hand = Eigen::Vector2d(0.4, 0.0) + x.row(i).transpose();
        const Eigen::Vector2d th = stiffid::models::inverse_kinematics(arm, hand);
        cols.row(i) << (first + i) / 1000.0, th(0), th(1), hand(0), hand(1), f(i, 0), f(i, 1);
      }
      stiffid::data::Trial t;
      t.sample_rate_hz = 1000.0;
      t.start_time_s = first / 1000.0;
      const std::vector<std::string> names{"th1", "th2", "x", "y", "fx", "fy"};
      for (int j = 0; j < 6; ++j) t.add_channel(names[j], "", cols.col(j + 1));
      char file[64];
      std::snprintf(file, sizeof file, "pulse_%.1f_d%d.csv", onset, d);
      stiffid::data::write_trial_csv((dir / "reg" / file).string(), t);
    }
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int fit(const fs::path& dir, const std::string& which, double segment_s) {
  int failures = 0;
  for (const auto& [name, truth] : truths()) {
    if (which != "all" && which != name) continue;
    const auto t0 = std::chrono::steady_clock::now();
    const stiffid::data::Trial trial =
        stiffid::data::read_trial_csv((dir / (name + ".csv")).string());
    sf::LumpedFitOptions o;
    o.model = truth.model;
    o.starts = 1;
    o.segment_s = segment_s;
    const std::vector<sf::MatrixParameter> layout = sf::model_matrices(truth.model);
    for (std::size_t m = 0; m < layout.size(); ++m) {
      const double d = 1.3 * truth.matrices[m](0, 0);  // box centre 1.3 x truth (first diagonal)
      o.ranges[layout[m].name] =
          layout[m].diagonal ? sf::StartRange{0.0, 2.0 * d} : sf::StartRange{d / 2.0, d * 2.0};
    }
    const sf::LumpedFitResult r = sf::fit_lumped(trial, {"f1", "f2"}, {"x1", "x2"}, o);
    double worst = 0.0;
    for (std::size_t m = 0; m < layout.size(); ++m) {
      worst = std::max(worst, (r.parameters[m].value - truth.matrices[m]).cwiseAbs().maxCoeff() /
                                  truth.matrices[m].cwiseAbs().maxCoeff());
    }
    std::printf(
        "fit %-8s %6.3f s  iterations %3d  substeps %d  segments %d  max rel error %.2e  %s\n",
        name.c_str(), seconds_since(t0), r.iterations, r.substeps, r.segments, worst,
        r.status.ok ? "converged" : r.status.message.c_str());
    failures += r.status.ok ? 0 : 1;
  }
  return failures == 0 ? 0 : 1;
}

int regress(const fs::path& dir) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<stiffid::data::Trial> trials;
  for (const auto& entry : fs::directory_iterator(dir / "reg")) {
    trials.push_back(stiffid::data::read_trial_csv(entry.path().string()));
  }
  sf::RegressionOptions o;
  const sf::RegressionResult r = sf::regress(trials, nullptr, o);
  const Eigen::Matrix2d k = m2(500, 100, 300);
  double worst = 0.0;
  for (const auto& e : r.estimates) {
    worst = std::max(worst, (e.k_endpoint_n_per_m - k).cwiseAbs().maxCoeff() / 500.0);
  }
  std::printf("regress force-pulse %zu trials, %zu estimates  %6.3f s  max rel K error %.2e\n",
              trials.size(), r.estimates.size(), seconds_since(t0), worst);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();  // as the stiffid program does
  const std::string usage =
      "usage: bench_fit make DIR [duration_s] [rate_hz] | fit DIR [kv|pt|duffing|all] [segment_s]"
      " | regress DIR\n";
  if (argc < 3) {
    std::cerr << usage;
    return 2;
  }
  const std::string cmd = argv[1];
  const fs::path dir = argv[2];
  try {
    if (cmd == "make") {
      make(dir, argc > 3 ? std::stod(argv[3]) : 20.0, argc > 4 ? std::stod(argv[4]) : 1000.0);
      return 0;
    }
    if (cmd == "fit")
      return fit(dir, argc > 3 ? argv[3] : "all", argc > 4 ? std::stod(argv[4]) : 0.0);
    if (cmd == "regress") return regress(dir);
  } catch (const std::exception& e) {
    std::cerr << "bench_fit: " << e.what() << '\n';
    return 2;
  }
  std::cerr << usage;
  return 2;
}
