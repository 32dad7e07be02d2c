#include "fitting/latin_hypercube.hpp"

#include <numeric>
#include <random>
#include <utility>
#include <vector>

namespace stiffid::fitting {

Eigen::MatrixXd latin_hypercube(int points, int dims, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  // 53 random bits -> a double uniform in [0, 1)
  auto uniform = [&gen]() { return static_cast<double>(gen() >> 11) * 0x1.0p-53; };
  Eigen::MatrixXd out(points, dims);
  std::vector<int> order(points);
  for (int d = 0; d < dims; ++d) {
    std::iota(order.begin(), order.end(), 0);
    for (int i = points - 1; i > 0; --i) {  // Fisher-Yates
      const int j = static_cast<int>(uniform() * (i + 1));
      std::swap(order[i], order[j]);
    }
    for (int p = 0; p < points; ++p) out(p, d) = (order[p] + uniform()) / points;
  }
  return out;
}

}  // namespace stiffid::fitting
