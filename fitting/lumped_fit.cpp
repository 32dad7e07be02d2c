#include "fitting/lumped_fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include "data/text_input.hpp"
#include "estimators/differences.hpp"
#include "fitting/latin_hypercube.hpp"

namespace stiffid::fitting {
namespace {

constexpr int kStride = 8;  // jet width: derivatives are taken 8 parameters per pass
using Jet = ceres::Jet<double, kStride>;

/// Everything a segment's residual needs, shared by all segments of one fit.
struct FitData {
  LumpedModel model;
  InputHold hold;
  int n = 0;       // DOF
  int state = 0;   // state size
  int params = 0;  // theta size
  double dt_s = 0.0;
  const Eigen::MatrixXd* inputs;   // S x n, N
  const Eigen::MatrixXd* outputs;  // S x n, m
  Eigen::VectorXd output_weight;   // [n] 1 / RMS(x_j), 1/m
  Eigen::VectorXd state_weight;    // [state] 1/RMS of x, x' (and q as x)
};

/// Residuals of one multiple-shooting segment [first, last]: weighted data residuals
/// w_j (x_sim_j(t_i) - y_j(t_i)) for samples first..last (last excluded when a next segment
/// exists), then, when it exists, weighted continuity residuals c (z_sim(t_last) - z_next).
/// Parameter blocks: theta, z_first, [z_next].
class SegmentCost final : public ceres::CostFunction {
 public:
  SegmentCost(const FitData& data, int first, int last, bool has_next, double continuity_weight,
              int substeps)
      : data_(data),
        first_(first),
        last_(last),
        has_next_(has_next),
        continuity_weight_(continuity_weight),
        substeps_(substeps) {
    mutable_parameter_block_sizes()->push_back(data.params);
    mutable_parameter_block_sizes()->push_back(data.state);
    if (has_next) mutable_parameter_block_sizes()->push_back(data.state);
    set_num_residuals(data_rows() + (has_next ? data.state : 0));
  }

  int data_rows() const { return (last_ - first_ + (has_next_ ? 0 : 1)) * data_.n; }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int p = data_.params, s = data_.state, rows = num_residuals();
    if (jacobians == nullptr || (jacobians[0] == nullptr && jacobians[1] == nullptr)) {
      run<double>(parameters[0], parameters[1], parameters, residuals);
      if (jacobians != nullptr && has_next_ && jacobians[2] != nullptr) next_jacobian(jacobians[2]);
      return finite(residuals, rows);
    }
    // Forward-mode passes: seed kStride of the (theta, z_first) variables at a time.
    const int total = p + s;
    std::vector<Jet> theta(p), z(s);
    std::vector<Jet> out(rows);
    for (int begin = 0; begin < total; begin += kStride) {
      for (int i = 0; i < p; ++i) theta[i] = Jet(parameters[0][i]);
      for (int i = 0; i < s; ++i) z[i] = Jet(parameters[1][i]);
      for (int k = 0; k < kStride && begin + k < total; ++k) {
        const int v = begin + k;
        if (v < p)
          theta[v].v[k] = 1.0;
        else
          z[v - p].v[k] = 1.0;
      }
      run<Jet>(theta.data(), z.data(), parameters, out.data());
      for (int r = 0; r < rows; ++r) {
        if (begin == 0) residuals[r] = out[r].a;
        for (int k = 0; k < kStride && begin + k < total; ++k) {
          const int v = begin + k;
          if (v < p) {
            if (jacobians[0] != nullptr) jacobians[0][r * p + v] = out[r].v[k];
          } else if (jacobians[1] != nullptr) {
            jacobians[1][r * s + (v - p)] = out[r].v[k];
          }
        }
      }
    }
    if (has_next_ && jacobians[2] != nullptr) next_jacobian(jacobians[2]);
    return finite(residuals, rows);
  }

 private:
  static bool finite(const double* r, int n) {
    for (int i = 0; i < n; ++i) {
      if (!std::isfinite(r[i])) return false;
    }
    return true;
  }

  // d(continuity residual)/d(z_next) = -c w; zero for the data rows.
  void next_jacobian(double* jac) const {
    const int s = data_.state, rows = num_residuals(), d = data_rows();
    std::fill(jac, jac + rows * s, 0.0);
    for (int i = 0; i < s; ++i) jac[(d + i) * s + i] = -continuity_weight_ * data_.state_weight(i);
  }

  template <typename T>
  void run(const T* theta, const T* z_first, double const* const* parameters, T* out) const {
    const int n = data_.n;
    const LumpedDynamics<T> dyn(theta, data_.model, n);
    std::vector<SmallVector<T>> g;
    g.reserve(last_ - first_ + 1);
    for (int i = first_; i <= last_; ++i) {
      g.push_back(dyn.accel_of_force(data_.inputs->row(i).transpose()));
    }
    SmallVector<T> z0(data_.state);
    for (int i = 0; i < data_.state; ++i) z0(i) = z_first[i];
    const int data_end = has_next_ ? last_ - 1 : last_;
    const Eigen::MatrixXd& y = *data_.outputs;
    const SmallVector<T> z_end = simulate_rk4<T>(dyn, g, first_, last_, z0, data_.dt_s, substeps_,
                                                 data_.hold, [&](int i, const SmallVector<T>& z) {
                                                   if (i > data_end) return;
                                                   for (int j = 0; j < n; ++j) {
                                                     out[(i - first_) * n + j] =
                                                         (z(j) - y(i, j)) * data_.output_weight(j);
                                                   }
                                                 });
    if (has_next_) {
      const double* z_next = parameters[2];
      const int d = data_rows();
      for (int i = 0; i < data_.state; ++i) {
        out[d + i] = (z_end(i) - z_next[i]) * (continuity_weight_ * data_.state_weight(i));
      }
    }
  }

  const FitData& data_;
  int first_, last_;
  bool has_next_;
  double continuity_weight_;
  int substeps_;
};

double rms(const Eigen::Ref<const Eigen::MatrixXd>& a) {
  return std::sqrt(a.squaredNorm() / static_cast<double>(a.size()));
}

/// Fastest rate of the model (1/s), for the automatic RK4 step (see LumpedFitOptions::substeps).
double fastest_rate(LumpedModel model, const Eigen::VectorXd& theta, int n, double x_max_m) {
  const std::vector<SmallMatrix<double>> m = theta_to_matrices(theta.data(), model, n);
  auto top = [](const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(a, b, Eigen::EigenvaluesOnly);
    return std::abs(es.eigenvalues().cwiseAbs().maxCoeff());
  };
  const Eigen::MatrixXd inertia = m[0];
  if (model == LumpedModel::poynting_thomson) {
    return std::max(std::sqrt(top(m[1], inertia)), top(m[1] + m[2], m[3]));
  }
  Eigen::MatrixXd k = m[2];
  if (model == LumpedModel::duffing) {
    k += 3.0 * x_max_m * x_max_m * Eigen::MatrixXd(m[3]).cwiseAbs();
  }
  return std::max(std::sqrt(top(k, inertia)), top(m[1], inertia));
}

int automatic_substeps(const LumpedFitOptions& o, const Eigen::VectorXd& theta, int n, double dt_s,
                       double x_max_m, double target) {
  if (o.substeps > 0) return o.substeps;
  const double rate = fastest_rate(o.model, theta, n, x_max_m);
  const double steps = std::ceil(dt_s * rate / target);
  return static_cast<int>(std::clamp(steps, 1.0, 256.0));
}

/// One start's solution.
struct StartSolution {
  Eigen::VectorXd theta;
  std::vector<Eigen::VectorXd> states;
  ceres::Solver::Summary summary;
  int iterations = 0;
  int substeps = 1;
  double cost = std::numeric_limits<double>::infinity();
};

struct Segments {
  std::vector<int> bounds;  // sample index of each segment start, then the last sample
  int count() const { return static_cast<int>(bounds.size()) - 1; }
};

Segments make_segments(int samples, double rate_hz, double segment_s, int state) {
  Segments seg;
  int k = 1;
  if (segment_s > 0.0) {
    const double per = std::max(segment_s * rate_hz, 1.0);
    k = std::max(1, static_cast<int>(std::floor((samples - 1) / per)));
    // each segment must hold more data than it has free initial states
    while (k > 1 && (samples - 1) / k < 2 * state) --k;
  }
  for (int i = 0; i <= k; ++i) {
    seg.bounds.push_back(
        static_cast<int>(std::llround(static_cast<double>(i) * (samples - 1) / k)));
  }
  return seg;
}

ceres::LinearSolverType linear_solver(int segments) {
  if (segments > 1 && ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    return ceres::SPARSE_NORMAL_CHOLESKY;
  }
  return ceres::DENSE_QR;
}

void build_problem(ceres::Problem& problem, const FitData& data, const Segments& seg,
                   Eigen::VectorXd& theta, std::vector<Eigen::VectorXd>& states, double weight,
                   int substeps) {
  for (int k = 0; k < seg.count(); ++k) {
    const bool has_next = k + 1 < seg.count();
    auto* cost =
        new SegmentCost(data, seg.bounds[k], seg.bounds[k + 1], has_next, weight, substeps);
    if (has_next) {
      problem.AddResidualBlock(cost, nullptr, theta.data(), states[k].data(), states[k + 1].data());
    } else {
      problem.AddResidualBlock(cost, nullptr, theta.data(), states[k].data());
    }
  }
}

/// Sum of squared weighted data residuals / 2 and the simulated outputs, segment by segment.
double data_cost(const FitData& data, const Segments& seg, const Eigen::VectorXd& theta,
                 const std::vector<Eigen::VectorXd>& states, int substeps,
                 Eigen::MatrixXd* simulated) {
  const LumpedDynamics<double> dyn(theta.data(), data.model, data.n);
  const Eigen::MatrixXd& y = *data.outputs;
  double cost = 0.0;
  for (int k = 0; k < seg.count(); ++k) {
    const int first = seg.bounds[k], last = seg.bounds[k + 1];
    const int data_end = (k + 1 < seg.count()) ? last - 1 : last;
    std::vector<SmallVector<double>> g;
    for (int i = first; i <= last; ++i) {
      g.push_back(dyn.accel_of_force(data.inputs->row(i).transpose()));
    }
    const SmallVector<double> z0 = states[k];
    simulate_rk4<double>(dyn, g, first, last, z0, data.dt_s, substeps, data.hold,
                         [&](int i, const SmallVector<double>& z) {
                           if (i > data_end) return;
                           for (int j = 0; j < data.n; ++j) {
                             const double r = (z(j) - y(i, j)) * data.output_weight(j);
                             cost += 0.5 * r * r;
                             if (simulated != nullptr) (*simulated)(i, j) = z(j);
                           }
                         });
  }
  return cost;
}

std::vector<Eigen::VectorXd> initial_states(const FitData& data, const Segments& seg,
                                            const Eigen::VectorXd& theta,
                                            const Eigen::MatrixXd& velocity) {
  const int n = data.n;
  std::vector<Eigen::VectorXd> states;
  std::vector<SmallMatrix<double>> m = theta_to_matrices(theta.data(), data.model, n);
  for (int k = 0; k < seg.count(); ++k) {
    const int i = seg.bounds[k];
    Eigen::VectorXd z(data.state);
    z.head(n) = data.outputs->row(i).transpose();
    z.segment(n, n) = velocity.row(i).transpose();
    if (data.model == LumpedModel::poynting_thomson) {
      // quasi-static internal state: (KS + KP) q = KS x
      const Eigen::MatrixXd ks = m[1], kp = m[2];
      z.segment(2 * n, n) = (ks + kp).ldlt().solve(ks * z.head(n));
    }
    states.push_back(z);
  }
  return states;
}

StartSolution solve_start(const FitData& data, const Segments& seg, const LumpedFitOptions& o,
                          const Eigen::VectorXd& theta0, const Eigen::MatrixXd& velocity,
                          double x_max_m) {
  StartSolution sol;
  sol.theta = theta0;
  sol.states = initial_states(data, seg, theta0, velocity);
  // Coarse steps first (h r <= 1: stable, rough) so that stiff start points stay cheap, then
  // the accurate count (h r <= step_target) for the fitted values, re-solving until it holds.
  sol.substeps = automatic_substeps(o, theta0, data.n, data.dt_s, x_max_m, 1.0);
  std::vector<double> weights;
  if (seg.count() > 1 && o.continuity_weight != 1.0) weights.push_back(1.0);
  weights.push_back(o.continuity_weight);
  ceres::Solver::Options so;
  so.linear_solver_type = linear_solver(seg.count());
  so.max_num_iterations = o.max_iterations;
  so.function_tolerance = o.function_tolerance;
  so.gradient_tolerance = o.gradient_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  const int weight_stages = static_cast<int>(weights.size());
  for (int stage = 0;; ++stage) {
    const double w = weights[std::min(stage, weight_stages - 1)];
    ceres::Problem problem;
    build_problem(problem, data, seg, sol.theta, sol.states, w, sol.substeps);
    ceres::Solve(so, &problem, &sol.summary);
    sol.iterations += sol.summary.num_successful_steps + sol.summary.num_unsuccessful_steps;
    if (!sol.theta.allFinite() || sol.summary.termination_type == ceres::FAILURE) break;
    if (stage + 1 < weight_stages) continue;
    // a start that wandered off (no convergence) is not worth a finer, costlier step
    if (sol.summary.termination_type != ceres::CONVERGENCE) break;
    const int needed = automatic_substeps(o, sol.theta, data.n, data.dt_s, x_max_m, o.step_target);
    if (needed == sol.substeps || stage >= weight_stages + 3) break;
    sol.substeps = needed;
  }
  sol.cost = sol.theta.allFinite()
                 ? data_cost(data, seg, sol.theta, sol.states, sol.substeps, nullptr)
                 : std::numeric_limits<double>::infinity();
  if (!std::isfinite(sol.cost)) sol.cost = std::numeric_limits<double>::infinity();
  return sol;
}

/// Start points: the box centre, then a Latin hypercube over the diagonal entries.

void check_finite(const Eigen::MatrixXd& a, const std::string& what) {
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < a.cols(); ++j) {
      if (!std::isfinite(a(i, j))) {
        throw InputError(what + ": sample " + std::to_string(i) + " of column " +
                         std::to_string(j + 1) + " is not finite");
      }
    }
  }
}

void validate(const Eigen::MatrixXd& u, const Eigen::MatrixXd& y, double rate_hz,
              const LumpedFitOptions& o) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw InputError("sample rate: expected a positive number of Hz");
  }
  if (u.cols() < 1 || u.cols() > kMaxDof) {
    throw InputError("--inputs: expected 1 to " + std::to_string(kMaxDof) +
                     " force channels, got " + std::to_string(u.cols()));
  }
  if (y.cols() != u.cols()) {
    throw InputError("--outputs: expected as many displacement channels as --inputs (" +
                     std::to_string(u.cols()) + "), got " + std::to_string(y.cols()));
  }
  if (u.rows() != y.rows()) throw InputError("inputs and outputs differ in sample count");
  const int n = static_cast<int>(u.cols());
  if (u.rows() < 4 * state_size(o.model, n) + theta_size(o.model, n)) {
    throw InputError("trial: " + std::to_string(u.rows()) + " samples are too few to fit " +
                     std::to_string(theta_size(o.model, n)) + " parameters");
  }
  check_finite(u, "--inputs");
  check_finite(y, "--outputs");
  for (int j = 0; j < n; ++j) {
    if (rms(u.col(j)) == 0.0)
      throw InputError("--inputs: column " + std::to_string(j + 1) + " is all zero");
    if (rms(y.col(j)) == 0.0)
      throw InputError("--outputs: column " + std::to_string(j + 1) + " is all zero");
  }
  if (o.starts < 1) throw InputError("--starts: expected at least 1");
  if (o.max_iterations < 1) throw InputError("--max-iterations: expected at least 1");
  if (o.substeps < 0) throw InputError("substeps: expected 0 (automatic) or a positive count");
  if (!(o.continuity_weight > 0.0)) throw InputError("continuity weight: expected > 0");
  for (const auto& [name, r] : o.ranges) {
    bool known = false, diagonal = false;
    for (const MatrixParameter& m : model_matrices(o.model)) {
      if (m.name == name) known = true, diagonal = m.diagonal;
    }
    if (!known) {
      throw InputError("bounds: '" + name + "' is not a parameter of model " + model_name(o.model));
    }
    if (!std::isfinite(r.lower) || !std::isfinite(r.upper) || !(r.lower < r.upper) ||
        (!diagonal && !(r.lower > 0.0))) {
      throw InputError("bounds: '" + name + "' expected finite lower < upper" +
                       (diagonal ? std::string() : std::string(" with lower > 0")));
    }
  }
}

}  // namespace

std::vector<Eigen::VectorXd> start_points(LumpedModel model, int n,
                                          const std::map<std::string, StartRange>& ranges,
                                          int starts, std::uint64_t seed) {
  const std::vector<MatrixParameter> layout = model_matrices(model);
  const int dims = static_cast<int>(layout.size()) * n;
  Eigen::MatrixXd unit(starts, dims);
  unit.row(0).setConstant(0.5);
  if (starts > 1) unit.bottomRows(starts - 1) = latin_hypercube(starts - 1, dims, seed);
  std::vector<Eigen::VectorXd> points;
  for (int s = 0; s < starts; ++s) {
    std::vector<Eigen::MatrixXd> mats;
    for (std::size_t m = 0; m < layout.size(); ++m) {
      const StartRange r = ranges.at(layout[m].name);
      Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
      for (int i = 0; i < n; ++i) {
        const double u = unit(s, static_cast<int>(m) * n + i);
        a(i, i) = layout[m].diagonal
                      ? r.lower + u * (r.upper - r.lower)
                      : std::exp(std::log(r.lower) + u * (std::log(r.upper) - std::log(r.lower)));
      }
      mats.push_back(a);
    }
    points.push_back(matrices_to_theta(model, mats));
  }
  return points;
}

Eigen::MatrixXd entries_jacobian(LumpedModel model, const Eigen::VectorXd& theta, int n) {
  const int p = static_cast<int>(theta.size());
  const int m = static_cast<int>(model_matrices(model).size());
  Eigen::MatrixXd g(m * n * n, p);
  std::vector<Jet> t(p);
  for (int begin = 0; begin < p; begin += kStride) {
    for (int i = 0; i < p; ++i) t[i] = Jet(theta(i));
    for (int k = 0; k < kStride && begin + k < p; ++k) t[begin + k].v[k] = 1.0;
    const std::vector<SmallMatrix<Jet>> mats = theta_to_matrices(t.data(), model, n);
    for (int a = 0; a < m; ++a) {
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < n; ++c) {
          for (int k = 0; k < kStride && begin + k < p; ++k) {
            g(a * n * n + r * n + c, begin + k) = mats[a](r, c).v[k];
          }
        }
      }
    }
  }
  return g;
}

void set_parameters(LumpedFitResult& result, ceres::Problem& problem,
                    const std::vector<double*>& blocks, double dof_left) {
  const int n = result.dof;
  const int p_theta = static_cast<int>(result.theta.size());
  Eigen::MatrixXd cov_theta =
      Eigen::MatrixXd::Constant(p_theta, p_theta, std::numeric_limits<double>::quiet_NaN());
  result.standard_errors_ok = false;
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  ceres::CRSMatrix crs;
  double unused = 0.0;
  if (dof_left > 0 && problem.Evaluate(eo, &unused, nullptr, nullptr, &crs)) {
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
    for (int r = 0; r < crs.num_rows; ++r) {
      for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) jac(r, crs.cols[k]) = crs.values[k];
    }
    // (J^T J)^-1 from the SVD of the column-scaled Jacobian: the columns differ by many orders
    // of magnitude (B in N/m^3 against log-diagonals), which scaling removes before the rank test.
    Eigen::VectorXd scale = jac.colwise().norm().transpose();
    for (Eigen::Index c = 0; c < scale.size(); ++c)
      scale(c) = scale(c) > 0.0 ? 1.0 / scale(c) : 1.0;
    jac = jac * scale.asDiagonal();
    Eigen::BDCSVD<Eigen::MatrixXd> svd(jac, Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    // rank test on the scaled Jacobian: 1e-10 leaves 1e-6 relative accuracy in the variances
    if (sv.size() > 0 && sv(sv.size() - 1) > 1e-10 * sv(0)) {
      const Eigen::MatrixXd v = svd.matrixV().topRows(p_theta);
      const Eigen::MatrixXd c = v * sv.cwiseInverse().cwiseAbs2().asDiagonal() * v.transpose();
      const Eigen::VectorXd st = scale.head(p_theta);
      cov_theta = st.asDiagonal() * c * st.asDiagonal() * (2.0 * result.cost / dof_left);
      result.standard_errors_ok = cov_theta.allFinite();
    }
  }
  const Eigen::MatrixXd g = entries_jacobian(result.model, result.theta, n);
  const Eigen::VectorXd var = (g * cov_theta * g.transpose()).diagonal();
  const std::vector<SmallMatrix<double>> mats =
      theta_to_matrices(result.theta.data(), result.model, n);
  const std::vector<MatrixParameter> layout = model_matrices(result.model);
  result.parameters.clear();
  for (std::size_t a = 0; a < layout.size(); ++a) {
    FittedMatrix fm{layout[a].name, layout[a].unit, mats[a], Eigen::MatrixXd(n, n)};
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        fm.std_error(r, c) =
            result.standard_errors_ok
                ? std::sqrt(std::max(0.0, var(static_cast<int>(a) * n * n + r * n + c)))
                : std::numeric_limits<double>::quiet_NaN();
      }
    }
    result.parameters.push_back(fm);
  }
}

std::map<std::string, StartRange> default_ranges(LumpedModel model, const Eigen::MatrixXd& u,
                                                 const Eigen::MatrixXd& y, double rate_hz) {
  const double dt = 1.0 / rate_hz;
  const Eigen::MatrixXd v = estimators::central_differences(y, dt);
  const Eigen::MatrixXd a = estimators::central_differences(v, dt);
  const double f = rms(u), x = rms(y), xd = rms(v), xdd = rms(a);
  const double x3 = rms(y.array().cube().matrix());
  auto box = [](double ref, double below, double above) {
    return StartRange{ref / below, ref * above};
  };
  std::map<std::string, StartRange> r;
  r["I"] = box(f / xdd, 10.0, 10.0);
  if (model == LumpedModel::poynting_thomson) {
    r["KS"] = box(f / x, 10.0, 10.0);
    r["KP"] = box(f / x, 10.0, 10.0);
    r["CP"] = box(f / xd, 100.0, 10.0);
  } else {
    r["K"] = box(f / x, 10.0, 10.0);
    r["C"] = box(f / xd, 100.0, 10.0);
  }
  if (model == LumpedModel::duffing) r["B"] = StartRange{0.0, f / x3};
  return r;
}

Eigen::MatrixXd simulate_lumped(LumpedModel model, const Eigen::VectorXd& theta,
                                const Eigen::VectorXd& z0, const Eigen::MatrixXd& inputs_n,
                                double sample_rate_hz, InputHold hold, int substeps) {
  const int n = static_cast<int>(inputs_n.cols());
  const LumpedDynamics<double> dyn(theta.data(), model, n);
  std::vector<SmallVector<double>> g;
  for (Eigen::Index i = 0; i < inputs_n.rows(); ++i) {
    g.push_back(dyn.accel_of_force(inputs_n.row(i).transpose()));
  }
  Eigen::MatrixXd out(inputs_n.rows(), n);
  const SmallVector<double> z = z0;
  simulate_rk4<double>(
      dyn, g, 0, static_cast<int>(inputs_n.rows()) - 1, z, 1.0 / sample_rate_hz, substeps, hold,
      [&](int i, const SmallVector<double>& s) { out.row(i) = s.head(n).transpose(); });
  return out;
}

LumpedFitResult fit_lumped(const Eigen::MatrixXd& u, const Eigen::MatrixXd& y, double rate_hz,
                           const LumpedFitOptions& o) {
  validate(u, y, rate_hz, o);
  const int n = static_cast<int>(u.cols());
  FitData data{
      o.model,       o.hold, n,  state_size(o.model, n), theta_size(o.model, n),
      1.0 / rate_hz, &u,     &y, Eigen::VectorXd(n),     Eigen::VectorXd(state_size(o.model, n))};
  const Eigen::MatrixXd velocity = estimators::central_differences(y, data.dt_s);
  for (int j = 0; j < n; ++j) {
    data.output_weight(j) = 1.0 / rms(y.col(j));
    data.state_weight(j) = data.output_weight(j);
    const double vs = rms(velocity.col(j));
    data.state_weight(n + j) = vs > 0.0 ? 1.0 / vs : data.output_weight(j) * data.dt_s;
    if (o.model == LumpedModel::poynting_thomson)
      data.state_weight(2 * n + j) = data.output_weight(j);
  }
  const double x_max = y.cwiseAbs().maxCoeff();
  std::map<std::string, StartRange> ranges = default_ranges(o.model, u, y, rate_hz);
  for (const auto& [name, r] : o.ranges) ranges[name] = r;

  const Segments seg = make_segments(static_cast<int>(u.rows()), rate_hz, o.segment_s, data.state);
  const std::vector<Eigen::VectorXd> points = start_points(o.model, n, ranges, o.starts, o.seed);
  StartSolution best;
  for (const Eigen::VectorXd& theta0 : points) {
    StartSolution s = solve_start(data, seg, o, theta0, velocity, x_max);
    if (s.cost < best.cost || best.theta.size() == 0) best = std::move(s);  // ties: earlier start
  }

  LumpedFitResult result;
  result.model = o.model;
  result.dof = n;
  result.starts = static_cast<int>(points.size());
  result.iterations = best.iterations;
  result.substeps = best.substeps;
  result.segments = seg.count();
  result.theta = best.theta;
  result.termination = std::string(ceres::TerminationTypeToString(best.summary.termination_type)) +
                       ": " + best.summary.message;
  result.segment_states.resize(seg.count(), data.state);
  for (int k = 0; k < seg.count(); ++k) result.segment_states.row(k) = best.states[k].transpose();
  if (!std::isfinite(best.cost)) {
    result.status =
        Status::failure("the fit diverged (non-finite residuals): " + result.termination);
    return result;
  }
  result.simulated_m.resize(u.rows(), n);
  result.cost = data_cost(data, seg, best.theta, best.states, best.substeps, &result.simulated_m);
  const Eigen::MatrixXd err = y - result.simulated_m;
  result.vaf_percent.resize(n);
  result.residual_rms_m.resize(n);
  for (int j = 0; j < n; ++j) {
    const Eigen::ArrayXd e = err.col(j).array() - err.col(j).mean();
    const Eigen::ArrayXd yc = y.col(j).array() - y.col(j).mean();
    result.vaf_percent(j) = 100.0 * (1.0 - e.square().sum() / yc.square().sum());
    result.residual_rms_m(j) = rms(err.col(j));
  }
  if (best.summary.termination_type != ceres::CONVERGENCE) {
    result.status = Status::failure("the fit did not converge: " + result.termination);
  }

  // Standard errors: Cov(theta) = sigma^2 (J^T J)^-1 with J the Jacobian Ceres evaluates at the
  // solution (continuity rows included, so their large weight makes it the covariance under
  // continuity), sigma^2 = 2 cost / (m - p) with m data residuals and p = theta plus one free
  // initial state; entries by the delta method.
  {
    ceres::Problem problem;
    Eigen::VectorXd theta = best.theta;
    std::vector<Eigen::VectorXd> states = best.states;
    build_problem(problem, data, seg, theta, states, o.continuity_weight, best.substeps);
    std::vector<double*> blocks{theta.data()};
    for (Eigen::VectorXd& z : states) blocks.push_back(z.data());
    const double m_rows = static_cast<double>(u.rows() * n);
    set_parameters(result, problem, blocks, m_rows - data.params - data.state);
  }
  if (result.status.ok && !result.standard_errors_ok) {
    result.status.message = "standard errors unavailable: the Jacobian is rank deficient";
  }
  return result;
}

LumpedFitResult fit_lumped(const data::Trial& trial, const std::vector<std::string>& inputs,
                           const std::vector<std::string>& outputs, const LumpedFitOptions& o) {
  if (inputs.size() != outputs.size()) {
    throw InputError("--outputs: expected as many channels as --inputs (" +
                     std::to_string(inputs.size()) + "), got " + std::to_string(outputs.size()));
  }
  return fit_lumped(trial.columns(inputs), trial.columns(outputs), trial.sample_rate_hz, o);
}

std::map<std::string, StartRange> read_ranges_json(const std::string& path, LumpedModel model) {
  const nlohmann::json j = data::read_json_file(path);
  if (!j.is_object()) throw InputError(path + ": expected an object {NAME: [lower, upper]}");
  std::map<std::string, StartRange> out;
  for (const auto& [key, value] : j.items()) {
    bool known = false;
    for (const MatrixParameter& m : model_matrices(model)) known = known || m.name == key;
    if (!known) {
      throw InputError(path + ": key '" + key + "' is not a parameter of model " +
                       model_name(model));
    }
    if (!value.is_array() || value.size() != 2 || !value[0].is_number() || !value[1].is_number()) {
      throw InputError(path + ": key '" + key + "': expected [lower, upper] numbers");
    }
    out[key] = StartRange{value[0].get<double>(), value[1].get<double>()};
  }
  return out;
}

nlohmann::json to_json(const LumpedFitResult& r) {
  auto matrix = [](const Eigen::MatrixXd& m) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      nlohmann::json row = nlohmann::json::array();
      for (Eigen::Index j = 0; j < m.cols(); ++j) {
        row.push_back(std::isfinite(m(i, j)) ? nlohmann::json(m(i, j)) : nlohmann::json());
      }
      rows.push_back(row);
    }
    return rows;
  };
  auto vector = [](const Eigen::VectorXd& v) {
    nlohmann::json a = nlohmann::json::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      a.push_back(std::isfinite(v(i)) ? nlohmann::json(v(i)) : nlohmann::json());
    }
    return a;
  };
  nlohmann::json j;
  j["model"] = model_name(r.model);
  j["dof"] = r.dof;
  j["parameters"] = nlohmann::json::object();
  for (const FittedMatrix& m : r.parameters) {
    j["parameters"][m.name] = {
        {"value", matrix(m.value)}, {"std_error", matrix(m.std_error)}, {"unit", m.unit}};
  }
  j["target"] = r.target;
  j["vaf_percent"] = vector(r.vaf_percent);
  // Residual RMS in the target's unit: m (trial), m/N (frf), each matrix's own unit (tfa).
  const char* residual_key = r.target == "frf"   ? "residual_rms_m_per_n"
                             : r.target == "tfa" ? "residual_rms"
                                                 : "residual_rms_m";
  j[residual_key] = vector(r.residual_rms_m);
  j["status"] = r.status.ok;
  j["message"] = r.status.message;
  j["termination"] = r.termination;
  j["iterations"] = r.iterations;
  j["starts"] = r.starts;
  j["substeps"] = r.substeps;
  j["segments"] = r.segments;
  return j;
}

}  // namespace stiffid::fitting
