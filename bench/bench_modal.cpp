// Benchmark of the parametric `modal` tfa core (issue 7): damped-mode fit (decimation, sliding
// matrix pencils, two variable-projection stages on Ceres, posterior SDs) and the eq 45-48 modal
// parameters, on a 5 s, 4 kHz two-channel free response of the paper's postural arm (Piovesan 2012
// eq 52, C = 0.01 K, hand at (0.4, 0) m, 5 N x 20 ms pulse at 2.5 s, 45 degrees), 20 dB noise.
//
// Usage: bench_modal [REPEATS [DECAY_TIE]]   (default 1 and the default decay tie, chosen from the
// data; 0 = none). Prints the median, minimum and maximum wall time of one fit over the repeats,
// the Levenberg-Marquardt iterations, roughness and tie chosen, and k11 as a sanity check. Time the
// whole process from outside as well (e.g. /usr/bin/time -v bench_modal 1).

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "data/allocator.hpp"
#include "estimators/damped_modes.hpp"
#include "estimators/modal_parameters.hpp"
#include "models/arm.hpp"

namespace {

Eigen::MatrixXd trial(const Eigen::Matrix2d& m, const Eigen::Matrix2d& k, const Eigen::Matrix2d& c,
                      const Eigen::Vector2d& v0, double rate_hz) {
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a.topRightCorner<2, 2>() = Eigen::Matrix2d::Identity();
  a.bottomLeftCorner<2, 2>() = -m.inverse() * k;
  a.bottomRightCorner<2, 2>() = -m.inverse() * c;
  const Eigen::EigenSolver<Eigen::Matrix4d> eig(a);
  Eigen::Vector4d x0;
  x0 << 0.0, 0.0, v0;
  const Eigen::Vector4cd coef = eig.eigenvectors().inverse() * x0.cast<std::complex<double>>();
  const int s = static_cast<int>(5.0 * rate_hz);
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(s, 2);
  for (int i = 0; i < s; ++i) {
    const double tau = i / rate_hz - 2.52;
    if (tau < 0.0) continue;
    q.row(i) =
        (eig.eigenvectors() * (eig.eigenvalues().array() * tau).exp().matrix().cwiseProduct(coef))
            .head<2>()
            .real()
            .transpose();
  }
  const double rms = std::sqrt(q.bottomRows(s / 2).squaredNorm() / double(s));
  std::mt19937_64 rng(42);
  std::normal_distribution<double> noise(0.0, rms / 10.0);
  for (Eigen::Index i = 0; i < q.size(); ++i) q.data()[i] += noise(rng);
  return q;
}

}  // namespace

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();  // as the stiffid program does
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 1;
  stiffid::estimators::DampedModesOptions options;
  if (argc > 2) options.decay_tie = std::atof(argv[2]);
  const double rate_hz = 4000.0;
  const stiffid::models::ArmParameters arm;
  const Eigen::Vector2d theta = stiffid::models::inverse_kinematics(arm, {0.4, 0.0});
  const Eigen::Matrix2d m = stiffid::models::inertia_matrix(arm, theta);
  Eigen::Matrix2d k;
  k << 35.0, 5.0, 5.0, 20.0;
  const Eigen::Matrix2d c = 0.01 * k;
  const Eigen::Vector2d v0 = m.inverse() * stiffid::models::jacobian(arm, theta).transpose() *
                             Eigen::Vector2d(std::sqrt(0.5), std::sqrt(0.5)) * 5.0 * 0.02;
  const Eigen::MatrixXd q = trial(m, k, c, v0, rate_hz);

  std::vector<double> seconds;
  double k11 = 0.0, roughness = 0.0, tie = 0.0;
  int iterations = 0;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    const auto modes = stiffid::estimators::fit_damped_modes(q, rate_hz, 0.0, 2.5, options);
    const auto params = stiffid::estimators::modal_parameters(modes, {m}, {});
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    const auto it = std::lower_bound(params.t_s.data(), params.t_s.data() + params.t_s.size(), 3.0);
    k11 = params.stiffness[it - params.t_s.data()](0, 0);
    iterations = modes.iterations;
    roughness = modes.track_roughness;
    tie = modes.decay_tie;
  }
  std::sort(seconds.begin(), seconds.end());
  std::printf(
      "bench_modal: %d repeats, median %.1f ms, min %.1f ms, max %.1f ms; %d iterations, "
      "roughness %g, decay tie %g; k11(3 s) = %.2f N m/rad (true 35)\n",
      repeats, 1e3 * seconds[seconds.size() / 2], 1e3 * seconds.front(), 1e3 * seconds.back(),
      iterations, roughness, tie, k11);
  return 0;
}
