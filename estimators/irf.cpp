#include "estimators/irf.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <sstream>
#include <vector>

#include "estimators/block_toeplitz.hpp"
#include "estimators/correlation.hpp"
#include "estimators/spectral_projection.hpp"

namespace stiffid::estimators {
namespace {

// Below this reciprocal condition number (1-norm estimate) the Cholesky solution of Psi H = Phi
// carries no correct digit worth reporting (relative error ~ eps / rcond > 1e-4): perfectly coupled
// inputs or inputs without power over part of the band.
constexpr double kMinReciprocalCondition = 1e-12;

void validate(const Eigen::Ref<const Eigen::MatrixXd>& inputs,
              const Eigen::Ref<const Eigen::MatrixXd>& outputs, double sample_rate_hz,
              const IrfOptions& options) {
  if (inputs.cols() < 1 || outputs.cols() < 1) {
    throw InputError("IRF: need at least one input and one output channel");
  }
  if (inputs.rows() != outputs.rows()) {
    throw InputError("IRF: inputs have " + std::to_string(inputs.rows()) + " samples, outputs " +
                     std::to_string(outputs.rows()));
  }
  if (!(sample_rate_hz > 0.0) || !std::isfinite(sample_rate_hz)) {
    throw InputError("IRF: sample rate must be a positive number of Hz");
  }
  if (options.first_lag > options.last_lag) {
    throw InputError("IRF lags: first lag " + std::to_string(options.first_lag) +
                     " samples is after the last lag " + std::to_string(options.last_lag));
  }
  const long span = static_cast<long>(options.last_lag) - options.first_lag;
  if (inputs.rows() <= span) {
    throw InputError("IRF: " + std::to_string(inputs.rows()) + " samples, need more than the " +
                     std::to_string(span + 1) + " lags of the IRF");
  }
  if (options.inverse == IrfInverse::rank) {
    const long full = inputs.cols() * (span + 1);
    if (options.rank < 1 || options.rank > full) {
      throw InputError("IRF pseudo-inverse: rank must be in 1.." + std::to_string(full) +
                       " (inputs x lags), got " + std::to_string(options.rank));
    }
  }
}

// Psi (N*L x N*L), eq 10-11: block (i, k) holds phi_{x_i x_k}(tau - s) at (tau - A, s - A).
Eigen::MatrixXd assemble_psi(const Eigen::MatrixXd& phi_inputs, int inputs, int lags, int max_lag) {
  Eigen::MatrixXd psi(static_cast<Eigen::Index>(inputs) * lags,
                      static_cast<Eigen::Index>(inputs) * lags);
  int pair = 0;
  for (int i = 0; i < inputs; ++i) {
    for (int k = i; k < inputs; ++k, ++pair) {
      const auto r = phi_inputs.col(pair);
      for (int b = 0; b < lags; ++b) {
        // Column s = A + b holds lags tau - s = a - b for rows a = 0..L-1.
        psi.block(static_cast<Eigen::Index>(i) * lags, static_cast<Eigen::Index>(k) * lags + b,
                  lags, 1) = r.segment(max_lag - b, lags);
      }
      if (k != i) {
        psi.block(static_cast<Eigen::Index>(k) * lags, static_cast<Eigen::Index>(i) * lags, lags,
                  lags) =
            psi.block(static_cast<Eigen::Index>(i) * lags, static_cast<Eigen::Index>(k) * lags,
                      lags, lags)
                .transpose();
      }
    }
  }
  return psi;
}

// Psi of the exact least-squares problem (IrfOptions::least_squares): Z^T Z / S for the lagged
// matrix Z of the zero-padded, mean-removed inputs c (S x N), i.e. the Toeplitz Psi minus the
// products that fall outside the record. Block (i, k) at lags (tau, s):
//   Z^T Z / S = phi_ik(tau - s) - (1/S) [ sum_{u=S-tau}^{S-1} c_i(u) c_k(u + tau - s)   (tau > 0)
//                                       + sum_{u=0}^{-tau-1} c_i(u) c_k(u + tau - s) ]  (tau < 0)
// Each sum grows by one product per step along a diagonal (tau - s fixed) away from tau = 0:
//   end(tau, s) = end(tau - 1, s - 1) + c_i(S - tau) c_k(S - s),
//   start(tau, s) = start(tau + 1, s + 1) + c_i(-tau - 1) c_k(-s - 1),
// with c zero outside [0, S); O(L (|A| + B)) per block.
void remove_edge_products(Eigen::MatrixXd& psi, const Eigen::MatrixXd& centred, int first_lag,
                          int lags) {
  const Eigen::Index samples = centred.rows();
  const int inputs = static_cast<int>(centred.cols());
  const int last_lag = first_lag + lags - 1;
  auto value = [&](int channel, Eigen::Index t) {
    return t >= 0 && t < samples ? centred(t, channel) : 0.0;
  };
  for (int i = 0; i < inputs; ++i) {
    for (int k = 0; k < inputs; ++k) {
      for (int d = -(lags - 1); d <= lags - 1; ++d) {  // d = tau - s
        double sum = 0.0;
        for (int tau = 1; tau <= last_lag; ++tau) {
          const int s = tau - d;
          sum += value(i, samples - tau) * value(k, samples - s);
          if (tau >= first_lag && s >= first_lag && s <= last_lag) {
            psi(static_cast<Eigen::Index>(i) * lags + (tau - first_lag),
                static_cast<Eigen::Index>(k) * lags + (s - first_lag)) -=
                sum / static_cast<double>(samples);
          }
        }
        sum = 0.0;
        for (int tau = -1; tau >= first_lag; --tau) {
          const int s = tau - d;
          sum += value(i, -tau - 1) * value(k, -s - 1);
          if (tau <= last_lag && s >= first_lag && s <= last_lag) {
            psi(static_cast<Eigen::Index>(i) * lags + (tau - first_lag),
                static_cast<Eigen::Index>(k) * lags + (s - first_lag)) -=
                sum / static_cast<double>(samples);
          }
        }
      }
    }
  }
}

struct Solution {
  Status status;
  Eigen::MatrixXd coefficients;  // H = dt h, (N*L x M)
  int rank = 0;
  double condition_number = 0.0;
  Eigen::VectorXd mdl;
};

Status singular_psi(double rcond) {
  std::ostringstream msg;
  msg << "IRF: the input correlation matrix Psi (eq 11) is singular to working precision "
      << "(reciprocal condition number " << rcond
      << "): inputs perfectly coupled or without power over part of the band; "
      << "use the pseudo-inverse (--pinv)";
  return Status::failure(msg.str());
}

Solution solve_full(const Eigen::MatrixXd& psi, const Eigen::MatrixXd& phi) {
  Solution s;
  const Eigen::LLT<Eigen::MatrixXd> llt(psi);
  const double rcond = llt.info() == Eigen::Success ? llt.rcond() : 0.0;
  s.condition_number = rcond > 0.0 ? 1.0 / rcond : std::numeric_limits<double>::infinity();
  if (llt.info() != Eigen::Success || rcond < kMinReciprocalCondition) {
    s.status = singular_psi(rcond);
    return s;
  }
  s.coefficients = llt.solve(phi);
  s.rank = static_cast<int>(psi.rows());
  return s;
}

// The plain solve of eq 11 through Psi's block-Toeplitz structure: in lag-major order (row a N + i
// for input i at lag index a) Psi is block-Toeplitz with N x N blocks S_{b-a}, S_d(i, k) =
// phi_ik(-d), factorized by the generalized Schur algorithm (block_toeplitz.hpp) in O(N^3 L^2).
// Same acceptance rule as the dense Cholesky of solve_full.
Solution solve_block_toeplitz(const Eigen::MatrixXd& phi_inputs, int inputs, int lags, int max_lag,
                              const Eigen::MatrixXd& phi) {
  // phi_ik(d) from the pairs i <= k (column `pair`), phi_ik(d) = phi_ki(-d) otherwise.
  std::vector<int> pair_of(static_cast<std::size_t>(inputs) * inputs);
  for (int i = 0, pair = 0; i < inputs; ++i) {
    for (int k = i; k < inputs; ++k, ++pair) pair_of[i * inputs + k] = pair;
  }
  auto correlation = [&](int i, int k, int d) {
    return i <= k ? phi_inputs(d + max_lag, pair_of[i * inputs + k])
                  : phi_inputs(-d + max_lag, pair_of[k * inputs + i]);
  };
  Eigen::MatrixXd first_row(inputs, static_cast<Eigen::Index>(inputs) * lags);
  for (int d = 0; d < lags; ++d) {
    for (int i = 0; i < inputs; ++i) {
      for (int k = 0; k < inputs; ++k) first_row(i, d * inputs + k) = correlation(i, k, -d);
    }
  }
  // ||Psi||_1: column (k, b) sums |phi_ik(d)| over inputs i and d = a - b, a = 0..L-1, i.e. over
  // d = -b..L-1-b: a window of prefix sums of |phi_ik| over d = -(L-1)..L-1.
  Eigen::VectorXd column_sums = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(inputs) * lags);
  Eigen::VectorXd prefix(2 * lags);  // prefix(m) = sum_{d < m - (L-1)} |phi_ik(d)|
  for (int k = 0; k < inputs; ++k) {
    for (int i = 0; i < inputs; ++i) {
      prefix(0) = 0.0;
      for (int m = 0; m < 2 * lags - 1; ++m) {
        prefix(m + 1) = prefix(m) + std::abs(correlation(i, k, m - (lags - 1)));
      }
      for (int b = 0; b < lags; ++b) {
        // d from -b to L-1-b: m = d + L - 1 from L-1-b to 2L-2-b.
        column_sums(static_cast<Eigen::Index>(k) * lags + b) +=
            prefix(2 * lags - 1 - b) - prefix(lags - 1 - b);
      }
    }
  }
  const double l1_norm = column_sums.maxCoeff();
  Solution s;
  const BlockToeplitzCholesky factor(first_row);
  if (!factor.ok()) {
    s.condition_number = std::numeric_limits<double>::infinity();
    s.status = singular_psi(0.0);
    return s;
  }
  // The right-hand sides in lag-major order, with the condition estimate's two start vectors:
  // one pass over the factor solves them all.
  const Eigen::Index n = first_row.cols();
  const Eigen::Index m = phi.cols();
  Eigen::MatrixXd lag_major(n, m + 2);
  for (int i = 0; i < inputs; ++i) {
    for (int a = 0; a < lags; ++a) {
      lag_major.row(static_cast<Eigen::Index>(a) * inputs + i).head(m) =
          phi.row(static_cast<Eigen::Index>(i) * lags + a);
    }
  }
  lag_major.rightCols(2) = factor.rcond_start();
  const Eigen::MatrixXd x = factor.solve(lag_major);
  const double rcond = factor.rcond(l1_norm, x.rightCols(2));
  s.condition_number = rcond > 0.0 ? 1.0 / rcond : std::numeric_limits<double>::infinity();
  if (rcond < kMinReciprocalCondition) {
    s.status = singular_psi(rcond);
    return s;
  }
  s.coefficients.resize(n, m);
  for (int i = 0; i < inputs; ++i) {
    for (int a = 0; a < lags; ++a) {
      s.coefficients.row(static_cast<Eigen::Index>(i) * lags + a) =
          x.row(static_cast<Eigen::Index>(a) * inputs + i).head(m);
    }
  }
  s.rank = static_cast<int>(n);
  return s;
}

Solution solve_pseudo_inverse(const Eigen::MatrixXd& psi, const Eigen::MatrixXd& phi,
                              const Eigen::VectorXd& output_power, int samples,
                              const IrfOptions& options) {
  Solution s;
  // Eigenvalues and the projections v_k^T phi without forming the eigenvectors (an O(n^3) step
  // with a large constant: 1.3 s at 1202 lags x inputs, against ~0.2 s).
  const SpectralProjection eig(psi, phi);
  if (!eig.status().ok) {
    s.status = Status::failure("IRF: eigendecomposition of Psi did not converge");
    return s;
  }
  const Eigen::VectorXd& w = eig.eigenvalues();  // ascending
  const int size = static_cast<int>(w.size());
  const int outputs = static_cast<int>(phi.cols());
  const double largest = w(size - 1);
  s.condition_number = w(0) > 0.0 ? largest / w(0) : std::numeric_limits<double>::infinity();
  const double floor = size * std::numeric_limits<double>::epsilon() * largest;

  const Eigen::MatrixXd& projection = eig.projections();  // V^T phi, (N*L x M)
  std::vector<int> usable;
  Eigen::MatrixXd contribution = Eigen::MatrixXd::Zero(size, outputs);  // fraction of var(y_j)
  for (int k = 0; k < size; ++k) {
    if (!(w(k) > floor)) continue;
    usable.push_back(k);
    contribution.row(k) =
        projection.row(k).array().square() / w(k) / output_power.transpose().array();
  }
  if (usable.empty()) {
    s.status = Status::failure("IRF: the input correlation matrix Psi is zero: no input power");
    return s;
  }
  const Eigen::VectorXd total = contribution.rowwise().sum();
  // Decreasing contribution (ties broken by the larger eigenvalue, so the order is deterministic),
  // or decreasing eigenvalue for the truncated eigen-decomposition.
  const bool by_eigenvalue = options.inverse == IrfInverse::tsvd;
  std::stable_sort(usable.begin(), usable.end(), [&](int a, int b) {
    if (by_eigenvalue || total(a) == total(b)) return w(a) > w(b);
    return total(a) > total(b);
  });
  const int count = static_cast<int>(usable.size());

  int keep = count;
  if (options.inverse == IrfInverse::rank) {
    keep = std::min(options.rank, count);
  } else {
    const double n = static_cast<double>(samples) * outputs;
    s.mdl.resize(count);
    double residual = static_cast<double>(outputs);  // sum_j (1 - VAF_j) with no vector kept
    for (int m = 1; m <= count; ++m) {
      residual -= total(usable[m - 1]);
      s.mdl(m - 1) =
          (1.0 + static_cast<double>(m) * outputs * std::log(n) / n) * std::max(residual, 0.0);
    }
    Eigen::Index best = 0;
    s.mdl.minCoeff(&best);
    keep = static_cast<int>(best) + 1;
  }
  Eigen::MatrixXd filtered = Eigen::MatrixXd::Zero(psi.rows(), outputs);  // Lambda^+ V^T phi
  for (int m = 0; m < keep; ++m) {
    const int k = usable[m];
    filtered.row(k) = projection.row(k) / w(k);
  }
  s.coefficients = eig.apply(filtered);
  s.rank = keep;
  return s;
}

// Predicted outputs (S x M): dt * sum_i h_ji * x_i, the blocked convolution of the mean-removed
// inputs (the first `inputs` channels of `signals`) with the kernels dt h_ji over lags A..B.
Eigen::MatrixXd predict(const BlockedSignals& signals, const Eigen::MatrixXd& coefficients,
                        int inputs, int outputs, int first_lag, int lags) {
  Eigen::MatrixXd kernels(lags, static_cast<Eigen::Index>(inputs) * outputs);
  for (int j = 0; j < outputs; ++j) {
    for (int i = 0; i < inputs; ++i) {
      kernels.col(i + inputs * j) =
          coefficients.col(j).segment(static_cast<Eigen::Index>(i) * lags, lags);
    }
  }
  return signals.convolve(kernels, first_lag, outputs);
}

}  // namespace

Eigen::VectorXd IrfResult::irf(int output, int input) const {
  const int lags = static_cast<int>(lag_s.size());
  return h.col(output).segment(static_cast<Eigen::Index>(input) * lags, lags);
}

IrfResult estimate_irf(const Eigen::Ref<const Eigen::MatrixXd>& inputs,
                       const Eigen::Ref<const Eigen::MatrixXd>& outputs, double sample_rate_hz,
                       const IrfOptions& options) {
  validate(inputs, outputs, sample_rate_hz, options);
  const int samples = static_cast<int>(inputs.rows());
  const int n_in = static_cast<int>(inputs.cols());
  const int n_out = static_cast<int>(outputs.cols());
  const int first = options.first_lag;
  const int lags = options.last_lag - first + 1;
  const int max_lag = std::max({lags - 1, std::abs(first), std::abs(options.last_lag)});

  IrfResult result;
  result.sample_rate_hz = sample_rate_hz;
  result.first_lag = first;
  result.last_lag = options.last_lag;
  result.inputs = n_in;
  result.outputs = n_out;
  result.full_rank = n_in * lags;
  result.lag_s = Eigen::VectorXd::LinSpaced(lags, first, options.last_lag) / sample_rate_hz;

  const BlockedSignals spectra(inputs, outputs, max_lag, /*remove_mean=*/true);
  std::vector<ChannelPair> pairs;
  for (int i = 0; i < n_in; ++i) {
    for (int k = i; k < n_in; ++k) pairs.push_back({i, k});
  }
  const int input_pairs = static_cast<int>(pairs.size());
  for (int j = 0; j < n_out; ++j) {
    for (int i = 0; i < n_in; ++i) pairs.push_back({i, n_in + j});
  }
  const Eigen::MatrixXd phi_all = spectra.correlate(pairs);

  // The plain Toeplitz solve needs only the correlations; the other solves need Psi itself.
  const bool toeplitz_solve = options.inverse == IrfInverse::full && !options.least_squares;
  Eigen::MatrixXd psi;
  if (!toeplitz_solve) {
    psi = assemble_psi(phi_all.leftCols(input_pairs), n_in, lags, max_lag);
    if (options.least_squares) {
      remove_edge_products(psi, inputs.rowwise() - spectra.means().head(n_in), first, lags);
    }
  }
  Eigen::MatrixXd phi_xy(static_cast<Eigen::Index>(n_in) * lags, n_out);
  for (int j = 0; j < n_out; ++j) {
    for (int i = 0; i < n_in; ++i) {
      phi_xy.col(j).segment(static_cast<Eigen::Index>(i) * lags, lags) =
          phi_all.col(input_pairs + i + n_in * j).segment(first + max_lag, lags);
    }
  }
  Eigen::VectorXd output_power(n_out);  // variance of each output
  for (int j = 0; j < n_out; ++j) {
    output_power(j) = spectra.centred(n_in + j).squaredNorm() / samples;
  }
  for (int j = 0; j < n_out; ++j) {
    if (!(output_power(j) > 0.0)) {
      result.status = Status::failure("IRF: output " + std::to_string(j) +
                                      " has zero variance; VAF is undefined");
      return result;
    }
  }

  Solution solution = toeplitz_solve ? solve_block_toeplitz(phi_all.leftCols(input_pairs), n_in,
                                                            lags, max_lag, phi_xy)
                      : options.inverse == IrfInverse::full
                          ? solve_full(psi, phi_xy)
                          : solve_pseudo_inverse(psi, phi_xy, output_power, samples, options);
  result.condition_number = solution.condition_number;
  result.mdl = std::move(solution.mdl);
  if (!solution.status.ok) {
    result.status = solution.status;
    return result;
  }
  result.rank = solution.rank;
  const Eigen::MatrixXd& coefficients = solution.coefficients;  // dt * h
  result.h = coefficients * sample_rate_hz;

  // Eqs 12-13 with phi_xy(+tau) (see irf.hpp): sum_tau (dt h)(tau) phi_xy(tau) = E[yhat^2].
  const Eigen::VectorXd explained =
      (phi_xy.array() * coefficients.array()).colwise().sum().transpose();
  result.vaf_correlation_percent = 100.0 * explained.cwiseQuotient(output_power);
  result.r2_correlation_percent = 100.0 * explained.sum() / output_power.sum();

  result.predicted = predict(spectra, coefficients, n_in, n_out, first, lags);
  result.vaf_percent.resize(n_out);
  double residual_energy = 0.0;
  for (int j = 0; j < n_out; ++j) {
    const auto residual = spectra.centred(n_in + j) - result.predicted.col(j);
    const double mean = residual.mean();
    const double spread = (residual.array() - mean).square().sum();  // S x residual variance
    result.vaf_percent(j) = 100.0 * (1.0 - spread / samples / output_power(j));
    residual_energy += spread + samples * mean * mean;  // sum of residual^2
  }
  result.r2_percent = 100.0 * (1.0 - residual_energy / (output_power.sum() * samples));
  return result;
}

}  // namespace stiffid::estimators
