// Times the simulator (issue 4): one Piovesan 5 s, 4 kHz arm trial with a 5 N, 20 ms impulse
// (posture at (0.4, 0) m, constant profiles), one Perreault 60 s, 50 Hz stochastic trial of the
// nonlinear arm (position 1), and one 60 s, 50 Hz linear endpoint trial (exact discretization).
// Prints the median wall time of each over the repetitions (default 21; first argument overrides).
// The peer is bench/peer_simulate.py (scipy solve_ivp on the same arm trial).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <vector>

#include "data/allocator.hpp"
#include "models/presets.hpp"

namespace {

double median_ms(int repetitions, const std::function<void()>& run) {
  std::vector<double> times;
  for (int k = 0; k < repetitions; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    times.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(times.begin(), times.begin() + times.size() / 2, times.end());
  return times[times.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();  // as the stiffid program does
  using namespace stiffid::models;
  const int repetitions = argc > 1 ? std::max(1, std::atoi(argv[1])) : 21;
  const TrialSpec arm = piovesan_impulse_trial(TaskKind::posture, ProfileKind::constant,
                                               ProfileKind::constant, M_PI / 4);
  const TrialSpec stochastic = perreault_arm_trial(1);
  const TrialSpec endpoint = perreault_endpoint_trial(25.0, 20.0);
  long steps_arm = 0, steps_stochastic = 0;
  const double t_arm = median_ms(repetitions, [&] {
    std::mt19937_64 rng(1);
    steps_arm = simulate(arm, rng).steps;
  });
  const double t_stochastic = median_ms(repetitions, [&] {
    std::mt19937_64 rng(1);
    steps_stochastic = simulate(stochastic, rng).steps;
  });
  const double t_endpoint = median_ms(repetitions, [&] {
    std::mt19937_64 rng(1);
    simulate(endpoint, rng);
  });
  std::printf("piovesan_arm_impulse_5s_4khz  median %.3f ms  (%ld steps)\n", t_arm, steps_arm);
  std::printf("perreault_arm_stochastic_60s_50hz  median %.3f ms  (%ld steps)\n", t_stochastic,
              steps_stochastic);
  std::printf("perreault_endpoint_60s_50hz_exact  median %.3f ms\n", t_endpoint);
  return 0;
}
