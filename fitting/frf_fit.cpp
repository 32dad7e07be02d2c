#include "fitting/frf_fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <memory>

#include "data/error.hpp"
#include "data/text_input.hpp"

namespace stiffid::fitting {
namespace {

template <typename T>
using Dense = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

// Real and imaginary parts of the compliance H = Z^-1 at angular frequency omega (rad/s), from
// the real 2n x 2n form of the complex solves.
bool all_finite(double x) { return std::isfinite(x); }
template <int N>
bool all_finite(const ceres::Jet<double, N>& x) {
  return std::isfinite(x.a) && x.v.allFinite();
}

// False when a matrix overflows (log-diagonal entries of hundreds: the solves would turn the
// infinities into NaN derivatives).
template <typename T>
bool compliance(LumpedModel model, const T* theta, int n, double omega, Dense<T>& hr,
                Dense<T>& hi) {
  const std::vector<SmallMatrix<T>> m = theta_to_matrices(theta, model, n);
  for (const SmallMatrix<T>& a : m) {
    for (Eigen::Index i = 0; i < a.size(); ++i) {
      if (!all_finite(a(i))) return false;
    }
  }
  Dense<T> zr(n, n), zi(n, n);
  if (model == LumpedModel::poynting_thomson) {
    // W = KS + KP + i omega CP; X = W^-1 KS; Z = -omega^2 I + KS - KS X.
    const Dense<T> ks = m[1], kp = m[2], cp = m[3];
    Dense<T> w(2 * n, 2 * n), rhs = Dense<T>::Zero(2 * n, n);
    w << ks + kp, -T(omega) * cp, T(omega) * cp, ks + kp;
    rhs.topRows(n) = ks;
    const Dense<T> x = w.partialPivLu().solve(rhs);
    zr = -T(omega * omega) * Dense<T>(m[0]) + ks - ks * x.topRows(n);
    zi = -ks * x.bottomRows(n);
  } else {
    zr = Dense<T>(m[2]) - T(omega * omega) * Dense<T>(m[0]);
    zi = T(omega) * Dense<T>(m[1]);
  }
  Dense<T> z(2 * n, 2 * n), rhs = Dense<T>::Zero(2 * n, n);
  z << zr, -zi, zi, zr;
  rhs.topRows(n) = Dense<T>::Identity(n, n);
  const Dense<T> h = z.partialPivLu().solve(rhs);
  hr = h.topRows(n);
  hi = h.bottomRows(n);
  return true;
}

// Residuals of one frequency: 2 n^2 (real, imaginary) for output j, input i.
struct FrequencyResidual {
  LumpedModel model;
  int n;
  double omega;
  Eigen::MatrixXcd measured;  // (n x n)
  Eigen::VectorXd weight;     // [n] sqrt(coherence) / scale per output, 0 when unused

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    Dense<T> hr, hi;
    if (!compliance(model, parameters[0], n, omega, hr, hi)) return false;
    int k = 0;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        residuals[k++] = T(weight(j)) * (hr(j, i) - T(measured(j, i).real()));
        residuals[k++] = T(weight(j)) * (hi(j, i) - T(measured(j, i).imag()));
      }
    }
    // A step to parameters whose matrices overflow (log-diagonals of hundreds) is rejected, so
    // Levenberg-Marquardt shrinks its trust region instead of failing on NaN.
    for (int r = 0; r < k; ++r) {
      if (!all_finite(residuals[r])) return false;
    }
    return true;
  }
};

const nlohmann::json& at(const nlohmann::json& j, const std::string& key, const std::string& path,
                         const std::string& where) {
  return data::json_member(j, key, path, where, "the JSON of stiffid frf");
}

std::vector<double> numbers(const nlohmann::json& j, const std::string& path,
                            const std::string& key, std::size_t size) {
  return data::json_numbers(j, path, key, size);
}

double mean_abs_diagonal(const Eigen::MatrixXd& a) { return a.diagonal().cwiseAbs().mean(); }

}  // namespace

FrfTarget read_frf_json(const std::string& path) {
  const nlohmann::json j = data::read_json_file(path);
  FrfTarget t;
  t.source = path;
  try {
    t.inputs = at(j, "inputs", path, "").get<std::vector<std::string>>();
    t.outputs = at(j, "outputs", path, "").get<std::vector<std::string>>();
  } catch (const nlohmann::json::type_error&) {
    throw InputError(path + ": 'inputs' and 'outputs' must be arrays of channel names");
  }
  const int n = static_cast<int>(t.inputs.size());
  if (n < 1 || t.outputs.size() != t.inputs.size()) {
    throw InputError(path + ": a lumped model needs as many outputs as inputs (got " +
                     std::to_string(t.outputs.size()) + " and " + std::to_string(n) + ")");
  }
  if (n > kMaxDof) throw InputError(path + ": at most " + std::to_string(kMaxDof) + " DOF");
  const std::vector<double> f = numbers(at(j, "frequency_hz", path, ""), path, "frequency_hz", 0);
  const std::size_t count = f.size();
  if (count < 2) throw InputError(path + ": 'frequency_hz' holds fewer than 2 frequencies");
  t.frequency_hz = Eigen::Map<const Eigen::VectorXd>(f.data(), static_cast<Eigen::Index>(count));
  t.compliance.assign(count, Eigen::MatrixXcd::Zero(n, n));
  t.coherence.resize(static_cast<Eigen::Index>(count), n);
  const nlohmann::json& frf = at(j, "frf", path, "");
  const nlohmann::json& multiple = at(at(j, "coherence", path, ""), "multiple", path, "coherence.");
  for (int r = 0; r < n; ++r) {
    const std::string& out = t.outputs[r];
    const std::vector<double> c = numbers(at(multiple, out, path, "coherence.multiple."), path,
                                          "coherence.multiple." + out, count);
    for (std::size_t k = 0; k < count; ++k) t.coherence(static_cast<Eigen::Index>(k), r) = c[k];
    for (int i = 0; i < n; ++i) {
      const std::string key = "frf." + out + "." + t.inputs[i];
      const nlohmann::json& h =
          at(at(frf, out, path, "frf."), t.inputs[i], path, "frf." + out + ".");
      const std::vector<double> re =
          numbers(at(h, "re", path, key + "."), path, key + ".re", count);
      const std::vector<double> im =
          numbers(at(h, "im", path, key + "."), path, key + ".im", count);
      for (std::size_t k = 0; k < count; ++k) t.compliance[k](r, i) = {re[k], im[k]};
    }
  }
  return t;
}

Eigen::MatrixXcd model_compliance(LumpedModel model, const Eigen::VectorXd& theta, int n,
                                  double frequency_hz) {
  Dense<double> hr, hi;
  if (!compliance(model, theta.data(), n, 2.0 * M_PI * frequency_hz, hr, hi)) {
    return Eigen::MatrixXcd::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  }
  return hr.cast<std::complex<double>>() +
         std::complex<double>(0.0, 1.0) * hi.cast<std::complex<double>>();
}

namespace {

// Frequencies used: inside the band, finite, f > 0, with at least one output coherent enough.
std::vector<int> used_frequencies(const FrfTarget& t, const FrfFitOptions& o) {
  std::vector<int> used;
  for (Eigen::Index k = 0; k < t.frequency_hz.size(); ++k) {
    const double f = t.frequency_hz(k);
    if (!(f > 0.0) || f < o.band_low_hz || f > o.band_high_hz) continue;
    if (!t.compliance[k].allFinite()) continue;
    if ((t.coherence.row(k).array() >= o.min_coherence).any()) used.push_back(static_cast<int>(k));
  }
  return used;
}

}  // namespace

std::map<std::string, StartRange> default_frf_ranges(LumpedModel model, const FrfTarget& t,
                                                     const FrfFitOptions& o) {
  const std::vector<int> used = used_frequencies(t, o);
  if (used.empty()) throw InputError(t.source + ": no frequency to fit (band and coherence)");
  auto stiffness_at = [&](int k) -> Eigen::MatrixXcd { return t.compliance[k].inverse(); };
  const double w_lo = 2.0 * M_PI * t.frequency_hz(used.front());
  const double w_hi = 2.0 * M_PI * t.frequency_hz(used.back());
  const double k_ref = mean_abs_diagonal(stiffness_at(used.front()).cwiseAbs());
  const double i_ref =
      std::max(mean_abs_diagonal(stiffness_at(used.back()).cwiseAbs()) / (w_hi * w_hi),
               1e-12 * k_ref / (w_lo * w_lo));
  int peak = used.front();
  for (int k : used) {
    if (t.compliance[k].cwiseAbs().maxCoeff() > t.compliance[peak].cwiseAbs().maxCoeff()) peak = k;
  }
  const double w_peak = 2.0 * M_PI * t.frequency_hz(peak);
  const double c_ref = std::max(mean_abs_diagonal(stiffness_at(peak).imag().cwiseAbs()) / w_peak,
                                1e-9 * k_ref / w_peak);
  std::map<std::string, StartRange> r;
  r["I"] = {i_ref / 10.0, 10.0 * i_ref};
  if (model == LumpedModel::poynting_thomson) {
    r["KS"] = {k_ref / 10.0, 10.0 * k_ref};
    r["KP"] = {k_ref / 10.0, 10.0 * k_ref};
    r["CP"] = {c_ref / 100.0, 10.0 * c_ref};
  } else {
    r["K"] = {k_ref / 10.0, 10.0 * k_ref};
    r["C"] = {c_ref / 100.0, 10.0 * c_ref};
  }
  return r;
}

LumpedFitResult fit_frf(const FrfTarget& t, const FrfFitOptions& o) {
  if (o.model == LumpedModel::duffing) {
    throw InputError(
        "fit duffing --frf: the Duffing model is nonlinear and has no frequency "
        "response; an FRF measured at one excitation level only holds its "
        "equivalent linear stiffness (K + 3 B E[x^2] for Gaussian motion), which "
        "does not separate K from B: fit it to a trial (TRIAL.csv --inputs "
        "--outputs) or to a tfa free response (--tfa)");
  }
  if (o.starts < 1) throw InputError("--starts: expected at least 1");
  if (o.max_iterations < 1) throw InputError("--max-iterations: expected at least 1");
  if (!(o.min_coherence >= 0.0 && o.min_coherence < 1.0)) {
    throw InputError("--min-coherence: expected a value in [0, 1)");
  }
  const int n = static_cast<int>(t.inputs.size());
  const std::vector<int> used = used_frequencies(t, o);
  if (used.size() * n * n * 2 <= static_cast<std::size_t>(theta_size(o.model, n))) {
    throw InputError(t.source + ": " + std::to_string(used.size()) +
                     " usable frequencies are too few for the model's parameters (band " +
                     std::to_string(o.band_low_hz) + "-" + std::to_string(o.band_high_hz) +
                     " Hz, multiple coherence >= " + std::to_string(o.min_coherence) + ")");
  }
  // Per-output scale: RMS over the used frequencies of |H_est| in that output's row.
  Eigen::VectorXd scale = Eigen::VectorXd::Zero(n);
  for (int k : used) scale += t.compliance[k].rowwise().squaredNorm().real();
  for (int j = 0; j < n; ++j) {
    scale(j) = std::sqrt(scale(j) / static_cast<double>(used.size()));
    if (!(scale(j) > 0.0))
      throw InputError(t.source + ": output " + t.outputs[j] + " has a zero FRF");
  }
  // One residual term per used frequency, built once for the finiteness check of the starts,
  // every local solve and the covariance.
  std::vector<FrequencyResidual> residuals;
  for (int k : used) {
    Eigen::VectorXd w(n);
    for (int j = 0; j < n; ++j) {
      const double c = t.coherence(k, j);
      w(j) = c >= o.min_coherence ? std::sqrt(std::min(1.0, c)) / scale(j) : 0.0;
    }
    residuals.push_back({o.model, n, 2.0 * M_PI * t.frequency_hz(k), t.compliance[k], w});
  }
  std::map<std::string, StartRange> ranges = default_frf_ranges(o.model, t, o);
  for (const auto& [name, r] : o.ranges) ranges[name] = r;
  const int p = theta_size(o.model, n);

  auto build = [&](ceres::Problem& problem, Eigen::VectorXd& theta) {
    for (const FrequencyResidual& term : residuals) {
      auto* cost =
          new ceres::DynamicAutoDiffCostFunction<FrequencyResidual, 8>(new FrequencyResidual(term));
      cost->AddParameterBlock(p);
      cost->SetNumResiduals(2 * n * n);
      problem.AddResidualBlock(cost, nullptr, theta.data());
    }
  };
  LumpedFitResult best;
  ceres::Solver::Summary best_summary;
  double best_cost = std::numeric_limits<double>::infinity();
  const std::vector<Eigen::VectorXd> points = start_points(o.model, n, ranges, o.starts, o.seed);
  auto finite_at = [&](const Eigen::VectorXd& theta) {
    std::vector<double> r(2 * n * n);
    const double* blocks[] = {theta.data()};
    for (const FrequencyResidual& term : residuals) {
      if (!term(blocks, r.data())) return false;
    }
    return true;
  };
  for (const Eigen::VectorXd& start : points) {
    if (!finite_at(start)) continue;  // a start on a singular model (undamped resonance)
    Eigen::VectorXd theta = start;
    ceres::Problem problem;
    build(problem, theta);
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = o.max_iterations;
    so.function_tolerance = 1e-12;
    so.gradient_tolerance = 1e-14;
    so.parameter_tolerance = 1e-12;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    if (std::isfinite(summary.final_cost) && summary.final_cost < best_cost) {  // ties: earlier
      best_cost = summary.final_cost;
      best.theta = theta;
      best_summary = summary;
    }
  }
  LumpedFitResult& result = best;
  result.model = o.model;
  result.target = "frf";
  result.dof = n;
  result.starts = static_cast<int>(points.size());
  if (!std::isfinite(best_cost)) {
    result.status = Status::failure("the FRF fit diverged from every start");
    return result;
  }
  result.cost = best_cost;
  result.iterations = static_cast<int>(best_summary.iterations.size());
  result.termination = std::string(ceres::TerminationTypeToString(best_summary.termination_type)) +
                       ": " + best_summary.message;
  if (best_summary.termination_type != ceres::CONVERGENCE) {
    result.status = Status::failure("the fit did not converge: " + result.termination);
  }
  // Fit quality per output over the used frequencies.
  result.vaf_percent.resize(n);
  result.residual_rms_m.resize(n);
  Eigen::VectorXd error = Eigen::VectorXd::Zero(n), total = Eigen::VectorXd::Zero(n),
                  squared = Eigen::VectorXd::Zero(n), count = Eigen::VectorXd::Zero(n);
  for (const FrequencyResidual& term : residuals) {
    const Eigen::MatrixXcd h =
        model_compliance(o.model, result.theta, n, term.omega / (2.0 * M_PI));
    for (int j = 0; j < n; ++j) {
      if (term.weight(j) == 0.0) continue;
      const double w = term.weight(j) * term.weight(j);
      const double e2 = (h.row(j) - term.measured.row(j)).squaredNorm();
      error(j) += w * e2;
      total(j) += w * term.measured.row(j).squaredNorm();
      squared(j) += e2;
      count(j) += n;
    }
  }
  for (int j = 0; j < n; ++j) {
    result.vaf_percent(j) = total(j) > 0.0 ? 100.0 * (1.0 - error(j) / total(j)) : std::nan("");
    result.residual_rms_m(j) = count(j) > 0 ? std::sqrt(squared(j) / count(j)) : std::nan("");
  }
  ceres::Problem problem;
  Eigen::VectorXd theta = result.theta;
  build(problem, theta);
  set_parameters(result, problem, {theta.data()}, static_cast<double>(used.size() * 2 * n * n) - p);
  if (result.status.ok && !result.standard_errors_ok) {
    result.status.message = "standard errors unavailable: the Jacobian is rank deficient";
  }
  return result;
}

}  // namespace stiffid::fitting
