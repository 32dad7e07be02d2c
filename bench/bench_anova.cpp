// Repeated-measures ANOVA speed: a 3-way within design, 20 subjects x 4 x 4 x 3 levels (960 rows),
// deterministic synthetic data. Prints the median wall time of one full analysis (long table ->
// subject x cell means -> every effect with sphericity, GG/HF, effect sizes and Mauchly) over
// `repeats` runs (argument 1, default 200). Peer: bench_anova.py (numpy/scipy, same design).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "data/allocator.hpp"
#include "validation/anova.hpp"

namespace v = stiffid::validation;

namespace {

v::LongTable synthetic_design(std::mt19937_64& rng) {
  v::LongTable t;
  t.source = "synthetic";
  t.factor_names = {"id", "a", "b", "c"};
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int s = 0; s < 20; ++s) {
    const double subject = 2.0 * noise(rng);
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        for (int c = 0; c < 3; ++c) {
          t.labels.push_back({"s" + std::to_string(s), "a" + std::to_string(a),
                              "b" + std::to_string(b), "c" + std::to_string(c)});
          t.values.push_back(10.0 + subject + 0.3 * a + 0.2 * b * c + (0.5 + 0.2 * a) * noise(rng));
        }
      }
    }
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();  // as the stiffid program does
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 200;
  std::mt19937_64 rng(20120330);
  const v::LongTable table = synthetic_design(rng);
  v::RepeatedMeasuresOptions options;
  options.subject = "id";
  options.within = {"a", "b", "c"};
  std::vector<double> ms;
  double checksum = 0.0;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    const v::AnovaResult result = v::repeated_measures_anova(table, options);
    const auto stop = std::chrono::steady_clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(stop - start).count());
    checksum += result.effects.front().f;
  }
  std::sort(ms.begin(), ms.end());
  std::printf(
      "bench_anova: 3-way within 20 x 4 x 4 x 3 (960 rows), %d runs: median %.3f ms, "
      "min %.3f ms, max %.3f ms (checksum F_a %.6f)\n",
      repeats, ms[ms.size() / 2], ms.front(), ms.back(), checksum / repeats);
  return 0;
}
