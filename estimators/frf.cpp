#include "estimators/frf.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <sstream>

#include "data/parallel.hpp"

namespace stiffid::estimators {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Fixed groups of consecutive frequency bins computed in parallel.
constexpr int kBinGroups = 16;

double clamp_unit(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

// |a|^2 / (b c) for a coherence, 0 when a denominator vanishes (no power: no linear relation).
double coherence(std::complex<double> cross, double auto_a, double auto_b) {
  const double denominator = auto_a * auto_b;
  return denominator > 0.0 ? clamp_unit(std::norm(cross) / denominator) : 0.0;
}

// Bendat & Piersol partial coherences of every input i with every output j (outputs are channels
// n..n+m-1 of the spectral matrix g, inputs 0..n-1), each conditioned on the other inputs r: with
// the conditioned spectra S = G_{[i,Y][i,Y]} - G_{[i,Y] r} G_rr^-1 G_{r [i,Y]} (Y all outputs,
// one factorization of G_rr per input), gamma^2_ij = |S_{i y_j}|^2 / (S_ii S_{y_j y_j}).
// Returns (m x n).
Eigen::MatrixXd partial_coherences(const Eigen::MatrixXcd& g, int n, int m) {
  Eigen::MatrixXd out(m, n);
  std::vector<int> keep(static_cast<std::size_t>(m) + 1);
  std::vector<int> rest;
  for (int i = 0; i < n; ++i) {
    keep[0] = i;
    for (int j = 0; j < m; ++j) keep[j + 1] = n + j;
    rest.clear();
    for (int k = 0; k < n; ++k)
      if (k != i) rest.push_back(k);
    Eigen::MatrixXcd s(m + 1, m + 1);
    for (int a = 0; a <= m; ++a)
      for (int b = 0; b <= m; ++b) s(a, b) = g(keep[a], keep[b]);
    if (!rest.empty()) {
      const int r = static_cast<int>(rest.size());
      Eigen::MatrixXcd grr(r, r), grk(r, m + 1);
      for (int a = 0; a < r; ++a) {
        for (int b = 0; b < r; ++b) grr(a, b) = g(rest[a], rest[b]);
        for (int b = 0; b <= m; ++b) grk(a, b) = g(rest[a], keep[b]);
      }
      s -= grk.adjoint() * grr.ldlt().solve(grk);
    }
    for (int j = 0; j < m; ++j) {
      out(j, i) = coherence(s(0, j + 1), s(0, 0).real(), s(j + 1, j + 1).real());
    }
  }
  return out;
}

// eps = factor (1 - g2)^power / (|g| sqrt(dof)): power 1/2, factor 1/sqrt(2) for |H|; power 1,
// factor sqrt(2) for coherences. +inf when g2 = 0 or dof <= 0.
double normalized_error(double g2, double dof, double factor, double power) {
  if (!(g2 > 0.0) || !(dof > 0.0)) return kInf;
  return factor * std::pow(std::max(0.0, 1.0 - g2), power) / (std::sqrt(g2) * std::sqrt(dof));
}

void resize_band(ErrorBand& band, int bins, int rows, int cols) {
  for (auto* v : {&band.eps, &band.lower, &band.upper})
    v->assign(bins, Eigen::MatrixXd(rows, cols));
}

void set_band(ErrorBand& band, int f, int r, int c, double value, double eps, double c_factor,
              double cap) {
  band.eps[f](r, c) = eps;
  if (!std::isfinite(eps) || !std::isfinite(value)) {
    band.lower[f](r, c) = 0.0;
    band.upper[f](r, c) = cap;
    return;
  }
  band.lower[f](r, c) = std::max(0.0, value * (1.0 - c_factor * eps));
  band.upper[f](r, c) = std::min(cap, value * (1.0 + c_factor * eps));
}

std::string number(double v) {
  std::ostringstream out;
  out.precision(3);
  out << v;
  return out.str();
}

}  // namespace

FrfResult estimate_frf(const CrossSpectra& spectra, int inputs, const FrfOptions& options) {
  const int n = inputs;
  const int m = spectra.channels() - n;
  const int bins = spectra.bins();
  assert(n >= 1 && m >= 1);
  FrfResult out;
  out.sample_rate_hz = spectra.sample_rate_hz;
  out.segments = spectra.segments;
  out.segment_length = spectra.segment_length;
  out.overlap_samples = spectra.overlap_samples;
  out.frequency_hz = spectra.frequency_hz;
  out.h.assign(bins, Eigen::MatrixXcd(m, n));
  out.ordinary_coherence.assign(bins, Eigen::MatrixXd(m, n));
  out.partial_coherence.assign(bins, Eigen::MatrixXd(m, n));
  out.multiple_coherence.resize(bins, m);
  out.condition_number.resize(bins);
  out.coupling_reciprocal_condition.resize(bins);
  out.in_band.resize(bins);

  // Band with input power: every input within band_power_fraction of its own peak.
  Eigen::MatrixXd input_power(bins, n);
  for (int f = 0; f < bins; ++f) input_power.row(f) = spectra.g[f].diagonal().head(n).real();
  const Eigen::RowVectorXd peak = input_power.colwise().maxCoeff();
  for (int f = 0; f < bins; ++f) {
    out.in_band[f] = (input_power.row(f).array() >= options.band_power_fraction * peak.array() &&
                      peak.array() > 0.0)
                         .all();
  }

  FrfRandomError& err = out.random_error;
  err.equivalent_independent_segments = equivalent_independent_segments(
      spectra.segments, spectra.segment_length, spectra.overlap_samples, options.welch.window);
  err.averages = options.correct_for_overlap ? err.equivalent_independent_segments
                                             : static_cast<double>(spectra.segments);
  err.confidence_factor = options.confidence_factor;
  resize_band(err.frf_magnitude, bins, m, n);
  resize_band(err.ordinary_coherence, bins, m, n);
  resize_band(err.partial_coherence, bins, m, n);
  resize_band(err.multiple_coherence, bins, m, 1);
  const double nd = err.averages;
  const double nd_conditioned = nd - n + 1;
  const double c = options.confidence_factor;

  // Bins are independent: fixed groups of consecutive bins run in parallel, each bin written only
  // by its own iteration (the same values at any thread count).
  auto one_bin = [&](int f) {
    const Eigen::MatrixXcd& g = spectra.g[f];
    const Eigen::MatrixXcd gxx = g.topLeftCorner(n, n);
    const Eigen::MatrixXcd gxy = g.topRightCorner(n, m);

    const Eigen::VectorXd lambda =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(gxx, Eigen::EigenvaluesOnly).eigenvalues();
    out.condition_number[f] = lambda[0] > 0.0 ? lambda[n - 1] / lambda[0] : kInf;
    const Eigen::VectorXd d = gxx.diagonal().real();
    if ((d.array() > 0.0).all()) {
      const Eigen::VectorXd scale = d.cwiseSqrt().cwiseInverse();
      const Eigen::MatrixXcd normalized = scale.asDiagonal() * gxx * scale.asDiagonal();
      const Eigen::VectorXd mu =
          Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(normalized, Eigen::EigenvaluesOnly)
              .eigenvalues();
      out.coupling_reciprocal_condition[f] = std::max(0.0, mu[0]) / mu[n - 1];
    } else {
      out.coupling_reciprocal_condition[f] = 0.0;
    }

    // Eq 2: column j of Gxx^-1 Gxy holds H(j, :).
    if (gxx.isZero(0.0)) {
      out.h[f].setConstant(std::complex<double>(kNaN, kNaN));
    } else {
      out.h[f] = gxx.ldlt().solve(gxy).transpose();
    }

    const Eigen::MatrixXd partial_all = n == 1 ? Eigen::MatrixXd() : partial_coherences(g, n, m);
    for (int j = 0; j < m; ++j) {
      const double gyy = g(n + j, n + j).real();
      // Eq 5: sum_i conj(H_ji) G_{x_i y_j} / G_yy, real up to round-off.
      const std::complex<double> explained =
          (out.h[f].row(j).transpose().array().conjugate() * gxy.col(j).array()).sum();
      const double multiple = gyy > 0.0 ? clamp_unit(explained.real() / gyy) : 0.0;
      out.multiple_coherence(f, j) = multiple;
      set_band(err.multiple_coherence, f, j, 0, multiple,
               normalized_error(multiple, nd_conditioned, std::sqrt(2.0), 1.0), c, 1.0);
      for (int i = 0; i < n; ++i) {
        const double ordinary = coherence(gxy(i, j), d[i], gyy);
        const double partial = n == 1 ? ordinary : partial_all(j, i);
        out.ordinary_coherence[f](j, i) = ordinary;
        out.partial_coherence[f](j, i) = partial;
        set_band(err.ordinary_coherence, f, j, i, ordinary,
                 normalized_error(ordinary, nd, std::sqrt(2.0), 1.0), c, 1.0);
        set_band(err.partial_coherence, f, j, i, partial,
                 normalized_error(partial, nd_conditioned, std::sqrt(2.0), 1.0), c, 1.0);
        set_band(err.frf_magnitude, f, j, i, std::abs(out.h[f](j, i)),
                 normalized_error(partial, 2.0 * nd_conditioned, 1.0, 0.5), c, kInf);
      }
    }
  };
  const int groups = std::min(bins, kBinGroups);
  data::parallel_for_groups(bins, groups, [&](std::size_t, int begin, int end) {
    for (int f = begin; f < end; ++f) one_bin(f);
  });
  int coupled_bins = 0;
  int first_coupled = -1;
  for (int f = 0; f < bins; ++f) {
    if (out.in_band[f] && out.coupling_reciprocal_condition[f] < options.min_reciprocal_condition) {
      if (coupled_bins++ == 0) first_coupled = f;
    }
  }

  for (int i = 0; i < n; ++i) {
    if (!(peak[i] > 0.0)) {
      out.status = Status::failure("input " + std::to_string(i + 1) +
                                   " has no power at any frequency (a constant signal?): the FRF "
                                   "is not identifiable");
      return out;
    }
  }
  if (coupled_bins > 0) {
    const int band = static_cast<int>(out.in_band.sum());
    out.status = Status::failure(
        "inputs perfectly coupled: the input spectral matrix Gxx is numerically singular at " +
        std::to_string(coupled_bins) + " of " + std::to_string(band) +
        " frequencies with input power (first at " + number(out.frequency_hz[first_coupled]) +
        " Hz, reciprocal condition of the input coherence matrix " +
        number(out.coupling_reciprocal_condition[first_coupled]) + " < " +
        number(options.min_reciprocal_condition) +
        "); the inputs are linearly dependent there, so the MIMO FRF is not identifiable "
        "(Perreault et al. 1999 eq 3): drop a dependent input or excite the inputs independently");
  }
  return out;
}

FrfResult estimate_frf(const Eigen::Ref<const Eigen::MatrixXd>& inputs,
                       const Eigen::Ref<const Eigen::MatrixXd>& outputs, double sample_rate_hz,
                       const FrfOptions& options) {
  if (inputs.cols() < 1 || outputs.cols() < 1) {
    throw InputError("FRF: needs at least one input and one output channel");
  }
  if (inputs.rows() != outputs.rows()) {
    throw InputError("FRF: inputs have " + std::to_string(inputs.rows()) + " samples, outputs " +
                     std::to_string(outputs.rows()));
  }
  Eigen::MatrixXd all(inputs.rows(), inputs.cols() + outputs.cols());
  all << inputs, outputs;
  return estimate_frf(welch_cross_spectra(all, sample_rate_hz, options.welch),
                      static_cast<int>(inputs.cols()), options);
}

FrfResult estimate_frf(const data::Trial& trial, const std::vector<std::string>& inputs,
                       const std::vector<std::string>& outputs, const FrfOptions& options) {
  if (inputs.empty() || outputs.empty()) {
    throw InputError("FRF: needs at least one input and one output channel");
  }
  std::vector<std::string> channels = inputs;
  channels.insert(channels.end(), outputs.begin(), outputs.end());
  FrfResult out = estimate_frf(welch_cross_spectra(trial, channels, options.welch),
                               static_cast<int>(inputs.size()), options);
  if (!out.status.ok) {
    std::string names;
    for (const auto& name : inputs) names += (names.empty() ? "" : ", ") + name;
    out.status.message = (trial.source.empty() ? std::string("trial") : trial.source) +
                         " (inputs " + names + "): " + out.status.message;
  }
  return out;
}

InverseFrfResult invert_frf(const std::vector<Eigen::MatrixXcd>& h, const Eigen::VectorXi& check,
                            double min_reciprocal_condition) {
  InverseFrfResult out;
  const int bins = static_cast<int>(h.size());
  out.condition_number.resize(bins);
  if (bins > 0 && h.front().rows() != h.front().cols()) {
    out.status =
        Status::failure("cannot invert a " + std::to_string(h.front().rows()) + " x " +
                        std::to_string(h.front().cols()) + " FRF: needs as many outputs as inputs");
    return out;
  }
  out.k.resize(bins);
  int singular = 0;
  int first = -1;
  for (int f = 0; f < bins; ++f) {
    const Eigen::VectorXd sigma = Eigen::JacobiSVD<Eigen::MatrixXcd>(h[f]).singularValues();
    const double smallest = sigma[sigma.size() - 1];
    out.condition_number[f] = smallest > 0.0 ? sigma[0] / smallest : kInf;
    const bool finite = h[f].allFinite();
    if (finite && smallest > 0.0) {
      out.k[f] = h[f].partialPivLu().inverse();
    } else {
      out.k[f] = Eigen::MatrixXcd::Constant(h[f].rows(), h[f].cols(), {kNaN, kNaN});
    }
    const bool checked = check.size() == 0 || (f < check.size() && check[f] != 0);
    if (checked && !(finite && smallest > min_reciprocal_condition * sigma[0])) {
      if (singular++ == 0) first = f;
    }
  }
  if (singular > 0) {
    out.status = Status::failure("the FRF matrix is singular at " + std::to_string(singular) +
                                 " checked frequencies (first at bin " + std::to_string(first) +
                                 ", condition number " + number(out.condition_number[first]) +
                                 "): its inverse (stiffness) is not defined there");
  }
  return out;
}

}  // namespace stiffid::estimators
