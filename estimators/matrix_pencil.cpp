#include "estimators/matrix_pencil.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "estimators/decimate.hpp"

namespace stiffid::estimators {
namespace {

void check_inputs(const Eigen::Ref<const Eigen::MatrixXd>& samples, double sample_rate_hz,
                  const MatrixPencilOptions& options) {
  if (!(sample_rate_hz > 0.0) || !std::isfinite(sample_rate_hz))
    throw InputError("matrix pencil: sample rate must be positive and finite, got " +
                     std::to_string(sample_rate_hz) + " Hz");
  if (options.modes < 1)
    throw InputError("matrix pencil: modes must be at least 1, got " +
                     std::to_string(options.modes));
  if (!(options.pencil_fraction > 0.0 && options.pencil_fraction <= 0.5))
    throw InputError("matrix pencil: pencil_fraction must be in (0, 0.5], got " +
                     std::to_string(options.pencil_fraction));
  if (options.real_poles < 0)
    throw InputError("matrix pencil: real_poles must be at least 0, got " +
                     std::to_string(options.real_poles));
  if (samples.cols() < 1) throw InputError("matrix pencil: no channels");
  const int needed = matrix_pencil_min_samples(options.modes, options.real_poles);
  if (samples.rows() < needed)
    throw InputError("matrix pencil: " + std::to_string(samples.rows()) + " samples cannot give " +
                     std::to_string(options.modes) + " modes and " +
                     std::to_string(options.real_poles) + " real poles; need at least " +
                     std::to_string(needed));
  if (!samples.allFinite()) throw InputError("matrix pencil: samples contain NaN or infinity");
}

// Real least-squares basis of sum_j Re(a_j exp(lambda_j t)) + sum_r b_r exp(beta_r t): columns
// Re(e), -Im(e) per complex pole, so that the coefficients are [Re a_j, Im a_j], then one column
// exp(beta_r t) per real pole.
Eigen::MatrixXd damped_basis(const Eigen::VectorXcd& lambda, const Eigen::VectorXd& beta,
                             const Eigen::Ref<const Eigen::VectorXd>& t_s) {
  const Eigen::Index n = lambda.size();
  Eigen::MatrixXd basis(t_s.size(), 2 * n + beta.size());
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < t_s.size(); ++i) {
      const std::complex<double> e = std::exp(lambda(j) * t_s(i));
      basis(i, 2 * j) = e.real();
      basis(i, 2 * j + 1) = -e.imag();
    }
  for (Eigen::Index r = 0; r < beta.size(); ++r)
    basis.col(2 * n + r) = (beta(r) * t_s.array()).exp().matrix();
  return basis;
}

// Eigenvalues (ascending) of the symmetric matrix `a` and an orthonormal basis of the eigenvectors
// of its `count` largest, columns in descending eigenvalue order: Householder tridiagonalization
// (Eigen), the eigenvalues of the tridiagonal matrix T by implicit QL without vectors, the wanted
// eigenvectors of T by inverse iteration (Gaussian elimination with partial pivoting on the
// tridiagonal T - mu I, each vector orthogonalized against the ones before it, which also keeps
// a cluster of close eigenvalues spanning its subspace), then Q y. For L = 160 about 3x cheaper
// than the full eigendecomposition, whose n^3 vector updates are what the pencil does not need.
void top_eigenvectors(const Eigen::MatrixXd& a, int count, Eigen::VectorXd& eigenvalues,
                      Eigen::MatrixXd& vectors) {
  const int n = static_cast<int>(a.rows());
  const Eigen::Tridiagonalization<Eigen::MatrixXd> tri(a);
  const Eigen::VectorXd diag = tri.diagonal();
  const Eigen::VectorXd sub = tri.subDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> values;
  values.computeFromTridiagonal(diag, sub, Eigen::EigenvaluesOnly);
  eigenvalues = values.eigenvalues();
  const double scale = std::max(eigenvalues.cwiseAbs().maxCoeff(), 1e-300);
  Eigen::MatrixXd y(n, count);
  // Solves (T - mu I) x = b in place (b -> x): elimination with row interchanges, U with two
  // superdiagonals; a zero pivot is replaced by a tiny one (the solve then amplifies the wanted
  // eigenvector, as inverse iteration intends).
  Eigen::VectorXd u0(n), u1(n), u2(n), lower(n);
  std::vector<char> swapped(n);
  auto factor = [&](double mu) {
    const double tiny = std::numeric_limits<double>::epsilon() * scale;
    double d = diag(0) - mu, e = n > 1 ? sub(0) : 0.0;
    for (int i = 0; i < n; ++i) {
      if (i == n - 1) {
        u0(i) = std::abs(d) > tiny ? d : tiny;
        u1(i) = u2(i) = 0.0;
        break;
      }
      const double below = sub(i), next_d = diag(i + 1) - mu;
      const double next_e = i + 2 < n ? sub(i + 1) : 0.0;
      if (std::abs(below) > std::abs(d)) {  // swap rows i and i + 1
        swapped[i] = 1;
        u0(i) = below;
        u1(i) = next_d;
        u2(i) = next_e;
        lower(i) = d / below;
        d = e - lower(i) * next_d;
        e = -lower(i) * next_e;
      } else {
        swapped[i] = 0;
        const double pivot = std::abs(d) > tiny ? d : tiny;
        u0(i) = pivot;
        u1(i) = e;
        u2(i) = 0.0;
        lower(i) = below / pivot;
        d = next_d - lower(i) * e;
        e = next_e;
      }
    }
  };
  auto solve = [&](Eigen::Ref<Eigen::VectorXd> b) {
    for (int i = 0; i + 1 < n; ++i) {
      if (swapped[i]) std::swap(b(i), b(i + 1));
      b(i + 1) -= lower(i) * b(i);
    }
    for (int i = n - 1; i >= 0; --i) {
      double v = b(i);
      if (i + 1 < n) v -= u1(i) * b(i + 1);
      if (i + 2 < n) v -= u2(i) * b(i + 2);
      b(i) = v / u0(i);
    }
  };
  for (int k = 0; k < count; ++k) {
    const double lambda = eigenvalues(n - 1 - k);
    // A shift just off the eigenvalue (relative 1e-10 of the largest) keeps T - mu I regular.
    factor(lambda + 1e-10 * scale);
    Eigen::Ref<Eigen::VectorXd> x = y.col(k);
    for (int i = 0; i < n; ++i) x(i) = 1.0 + 0.5 * std::sin(1.0 + i);  // deterministic start
    for (int it = 0; it < 3; ++it) {
      solve(x);
      for (int q = 0; q < k; ++q) x -= y.col(q).dot(x) * y.col(q);
      x.normalize();
    }
  }
  vectors = tri.matrixQ() * y;
}

}  // namespace

MatrixPencilResult estimate_matrix_pencil(const Eigen::Ref<const Eigen::MatrixXd>& samples,
                                          double sample_rate_hz,
                                          const MatrixPencilOptions& options) {
  check_inputs(samples, sample_rate_hz, options);
  if (options.max_rate_hz > 0.0 && sample_rate_hz > options.max_rate_hz) {
    // The zero-phase FIR of the modal fit's own decimation; output sample i is input sample
    // i D, so the amplitudes stay those at the first sample.
    const DecimationResult slow =
        decimate(samples, sample_rate_hz,
                 short_filter_decimation(
                     static_cast<int>(std::ceil(sample_rate_hz / options.max_rate_hz - 1e-9))));
    if (slow.samples.rows() >= matrix_pencil_min_samples(options.modes, options.real_poles)) {
      MatrixPencilOptions at_rate = options;
      at_rate.max_rate_hz = 0.0;
      return estimate_matrix_pencil(slow.samples, slow.sample_rate_hz, at_rate);
    }
  }
  const int s = static_cast<int>(samples.rows());
  const int c = static_cast<int>(samples.cols());
  const int n = options.modes;
  const int real_poles = options.real_poles;
  const int order = 2 * n + real_poles;
  const int pencil = std::clamp(static_cast<int>(options.pencil_fraction * s), order + 1,
                                std::max(order + 1, options.max_pencil));
  const int rows = s - pencil;

  MatrixPencilResult result;
  result.pencil = pencil;
  result.rate_hz = sample_rate_hz;
  // Right singular vectors of the stacked Hankel matrix H of all channels, (C (S - L)) x (L + 1)
  // with H(k (S - L) + i, a) = x_k(i + a), as the eigenvectors of its Gram matrix H^T H: an
  // (L + 1)-square symmetric eigenproblem, several times cheaper than an SVD of the tall H. The
  // signal subspace is as accurate (its singular values are far above the rest); singular values
  // below ~1e-8 of the largest lose their relative accuracy. The Hankel structure gives the Gram
  // matrix in O(C L^2): G(a, b) = sum_k sum_{i < S - L} x_k(i + a) x_k(i + b), so
  // G(a + 1, b + 1) = G(a, b) + sum_k x_k(S - L + a) x_k(S - L + b) - x_k(a) x_k(b).
  Eigen::MatrixXd gram(pencil + 1, pencil + 1);
  for (int b = 0; b <= pencil; ++b) {
    double sum = 0.0;
    for (int k = 0; k < c; ++k)
      sum += samples.col(k).segment(0, rows).dot(samples.col(k).segment(b, rows));
    gram(b, 0) = sum;
  }
  for (int a = 0; a < pencil; ++a)
    for (int b = a; b < pencil; ++b) {
      double step = 0.0;
      for (int k = 0; k < c; ++k)
        step += samples(rows + a, k) * samples(rows + b, k) - samples(a, k) * samples(b, k);
      gram(b + 1, a + 1) = gram(b, a) + step;
    }
  Eigen::VectorXd eigenvalues;  // ascending
  Eigen::MatrixXd v;            // the signal subspace: eigenvectors of the `order` largest
  top_eigenvectors(gram, order, eigenvalues, v);
  result.singular_values = eigenvalues.reverse().cwiseMax(0.0).cwiseSqrt();
  if (!(result.singular_values(0) > 0.0)) {
    result.status = Status::failure("matrix pencil: the signals are identically zero");
    return result;
  }
  const Eigen::MatrixXd v1 = v.topRows(pencil);
  const Eigen::MatrixXd v2 = v.bottomRows(pencil);
  const Eigen::MatrixXd z_matrix = v1.colPivHouseholderQr().solve(v2);  // (2n x 2n), Hua eq 23
  const Eigen::VectorXcd z = Eigen::EigenSolver<Eigen::MatrixXd>(z_matrix, false).eigenvalues();

  // Keep the poles in the upper half plane (their conjugates carry no new information) and the
  // real ones (positive z: a negative real z is an oscillation at the Nyquist rate).
  std::vector<std::complex<double>> lambda_up;
  std::vector<double> real_up;
  for (Eigen::Index j = 0; j < z.size(); ++j) {
    if (std::abs(z(j)) == 0.0) continue;
    const std::complex<double> lambda = std::log(z(j)) * sample_rate_hz;
    if (lambda.imag() > 1e-9 * sample_rate_hz) lambda_up.push_back(lambda);
    if (z(j).imag() == 0.0 && z(j).real() > 0.0) real_up.push_back(lambda.real());
  }
  if (static_cast<int>(lambda_up.size()) < n) {
    result.status = Status::failure("matrix pencil: found " + std::to_string(lambda_up.size()) +
                                    " oscillatory poles of " + std::to_string(n) +
                                    " (the others are real: overdamped modes or too much noise)");
    return result;
  }
  if (static_cast<int>(real_up.size()) < real_poles) {
    result.status = Status::failure("matrix pencil: found " + std::to_string(real_up.size()) +
                                    " real poles of " + std::to_string(real_poles) +
                                    " (the model order went to further oscillations)");
    return result;
  }
  std::sort(lambda_up.begin(), lambda_up.end(), [](auto a, auto b) { return a.imag() < b.imag(); });
  Eigen::VectorXcd lambda(n);
  for (int j = 0; j < n; ++j) lambda(j) = lambda_up[j];
  result.omega_rad_per_s = lambda.imag();
  result.frequency_hz = result.omega_rad_per_s / (2.0 * M_PI);
  result.alpha_per_s = lambda.real();
  std::sort(real_up.begin(), real_up.end(),
            [](double a, double b) { return std::abs(a) < std::abs(b); });
  result.real_rate_per_s = Eigen::Map<const Eigen::VectorXd>(real_up.data(), real_poles);

  const Eigen::VectorXd t_s = Eigen::VectorXd::LinSpaced(s, 0.0, (s - 1) / sample_rate_hz);
  const Eigen::MatrixXd basis = damped_basis(lambda, result.real_rate_per_s, t_s);
  const Eigen::MatrixXd coefficients = basis.colPivHouseholderQr().solve(samples);
  result.amplitude.resize(n, c);
  for (int j = 0; j < n; ++j)
    for (int k = 0; k < c; ++k)
      result.amplitude(j, k) = {coefficients(2 * j, k), coefficients(2 * j + 1, k)};
  result.real_amplitude = coefficients.bottomRows(real_poles);
  result.residual_rms = std::sqrt((samples - basis * coefficients).squaredNorm() / (double(s) * c));
  return result;
}

Eigen::MatrixXd evaluate_damped_exponentials(const MatrixPencilResult& result,
                                             const Eigen::Ref<const Eigen::VectorXd>& t_s) {
  const Eigen::VectorXcd lambda =
      result.alpha_per_s.cast<std::complex<double>>() +
      std::complex<double>(0.0, 1.0) * result.omega_rad_per_s.cast<std::complex<double>>();
  const Eigen::MatrixXd basis = damped_basis(lambda, result.real_rate_per_s, t_s);
  const Eigen::Index n = lambda.size();
  Eigen::MatrixXd coefficients(2 * n + result.real_rate_per_s.size(), result.amplitude.cols());
  for (Eigen::Index j = 0; j < n; ++j) {
    coefficients.row(2 * j) = result.amplitude.row(j).real();
    coefficients.row(2 * j + 1) = result.amplitude.row(j).imag();
  }
  coefficients.bottomRows(result.real_rate_per_s.size()) = result.real_amplitude;
  return basis * coefficients;
}

}  // namespace stiffid::estimators
