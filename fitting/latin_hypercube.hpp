#pragma once
// Seeded Latin hypercube sampling on the unit cube, reproducible on every platform: the generator
// is std::mt19937_64 (fully specified by the standard) and the uniform draws and the shuffle are
// written here rather than taken from std::uniform_real_distribution / std::shuffle, whose
// algorithms the standard leaves to the library.

#include <Eigen/Core>
#include <cstdint>

namespace stiffid::fitting {

/// (points x dims) matrix in [0, 1): for every dimension the points fall one in each of `points`
/// equal strata, in an order and at positions within the strata drawn from `seed`.
Eigen::MatrixXd latin_hypercube(int points, int dims, std::uint64_t seed);

}  // namespace stiffid::fitting
