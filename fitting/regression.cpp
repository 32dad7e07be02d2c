#include "fitting/regression.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "data/error.hpp"
#include "estimators/savitzky_golay.hpp"
#include "fitting/pchip.hpp"

namespace stiffid::fitting {
namespace {

const std::vector<std::string> kColumns = {"th1", "th2", "x", "y", "fx", "fy"};

std::string seconds(double t) {
  std::ostringstream s;
  s << t << " s";
  return s.str();
}

/// First sample index with time >= t (within a quarter sample).
int sample_at(const data::Trial& trial, double t_s) {
  return static_cast<int>(std::ceil((t_s - trial.start_time_s) * trial.sample_rate_hz - 0.25));
}

struct Prepared {
  double onset_s = 0.0;
  std::string source;
  Eigen::MatrixXd data;  // (S x 6) th1, th2, x, y, fx, fy
};

/// Unperturbed values (1 x 6) at each sample of a window [first, last] of a trial.
Eigen::MatrixXd unperturbed(const Prepared& p, const data::Trial& trial, const data::Trial* base,
                            int first, int last, double baseline_s) {
  const int rows = last - first + 1;
  if (base == nullptr) {
    const int b1 = sample_at(trial, p.onset_s);
    const int b0 = b1 - static_cast<int>(std::llround(baseline_s * trial.sample_rate_hz));
    if (b0 < 0) {
      throw InputError(p.source + ": the trial starts less than " + seconds(baseline_s) +
                       " before the onset at " + seconds(p.onset_s) +
                       " (needed for the postural baseline; or give --baseline)");
    }
    const Eigen::RowVectorXd mean = p.data.middleRows(b0, b1 - b0).colwise().mean();
    return mean.replicate(rows, 1);
  }
  const Eigen::MatrixXd b = base->columns(kColumns);
  Eigen::MatrixXd out(rows, 6);
  for (int r = 0; r < rows; ++r) {
    const double t = trial.start_time_s + (first + r) / trial.sample_rate_hz;
    const double pos = (t - base->start_time_s) * base->sample_rate_hz;
    if (pos < -1e-6 || pos > base->sample_count() - 1 + 1e-6) {
      throw InputError(base->source + ": --baseline does not cover time " + seconds(t) + " of " +
                       p.source);
    }
    const int k = std::clamp(static_cast<int>(std::floor(pos)), 0, base->sample_count() - 2);
    const double a = std::clamp(pos - k, 0.0, 1.0);
    out.row(r) = (1.0 - a) * b.row(k) + a * b.row(k + 1);
  }
  return out;
}

int savgol_samples(const RegressionOptions& o, double rate_hz, int available) {
  int w = static_cast<int>(std::llround(o.savgol_window_s * rate_hz));
  if (w % 2 == 0) ++w;
  w = std::max(w, o.savgol_order + 1 + ((o.savgol_order % 2 == 0) ? 1 : 0));
  if (w % 2 == 0) ++w;
  if (w > available) {
    throw InputError("regression window holds " + std::to_string(available) +
                     " samples, fewer than the Savitzky-Golay window of " + std::to_string(w));
  }
  return w;
}

}  // namespace

RegressionMethod parse_regression_method(const std::string& text, const std::string& what) {
  if (text == "force-pulse") return RegressionMethod::force_pulse;
  if (text == "disp-full") return RegressionMethod::displacement_full;
  if (text == "disp-ss") return RegressionMethod::displacement_steady_state;
  throw InputError(what + ": unknown regression '" + text +
                   "', expected force-pulse, disp-full or disp-ss");
}

std::string regression_method_name(RegressionMethod method) {
  switch (method) {
    case RegressionMethod::force_pulse:
      return "force-pulse";
    case RegressionMethod::displacement_full:
      return "disp-full";
    case RegressionMethod::displacement_steady_state:
      return "disp-ss";
  }
  return "";
}

Eigen::MatrixXd solve_regression(const Eigen::MatrixXd& phi, const Eigen::MatrixXd& targets,
                                 const std::string& what, double min_rcond) {
  if (!phi.allFinite() || !targets.allFinite()) {
    throw InputError(what + ": non-finite data in the regression");
  }
  if (phi.rows() < phi.cols()) {
    throw InputError(what + ": " + std::to_string(phi.rows()) + " equations for " +
                     std::to_string(phi.cols()) + " unknowns");
  }
  Eigen::VectorXd scale = phi.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < scale.size(); ++c) {
    if (scale(c) == 0.0) throw InputError(what + ": singular regressors (a regressor is all zero)");
  }
  const Eigen::MatrixXd scaled = phi * scale.cwiseInverse().asDiagonal();
  // Householder QR of the (rows x p) scaled regressors; their singular values are those of the
  // p x p triangle R, so the condition check needs only R's SVD (no p x rows factor U).
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(scaled);
  const Eigen::Index p = phi.cols();
  const Eigen::MatrixXd r = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
  const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXd>(r).singularValues();
  if (sv(sv.size() - 1) < min_rcond * sv(0)) {
    std::ostringstream m;
    m << what << ": singular regressors (reciprocal condition " << sv(sv.size() - 1) / sv(0)
      << "; perturbation directions must span the plane)";
    throw InputError(m.str());
  }
  return scale.cwiseInverse().asDiagonal() * qr.solve(targets);
}

double detect_onset_s(const data::Trial& trial) {
  const Eigen::MatrixXd f = trial.columns({"fx", "fy"});
  const int s = trial.sample_count();
  const int ref = std::clamp(static_cast<int>(std::llround(0.05 * trial.sample_rate_hz)), 1, s);
  const Eigen::RowVectorXd mean = f.topRows(ref).colwise().mean();
  const Eigen::VectorXd dev = (f.rowwise() - mean).rowwise().norm();
  const double max_dev = dev.maxCoeff();
  if (!(max_dev > 0.0)) {
    throw InputError(trial.source + ": no perturbation found (fx, fy never change); give --onset");
  }
  const double noise = std::sqrt(dev.head(ref).squaredNorm() / ref);
  const double floor = std::max(5.0 * noise, 1e-6 * max_dev);
  int i = 0;
  while (i < s && dev(i) <= std::max(floor, 0.05 * max_dev)) ++i;
  while (i > 0 && dev(i - 1) > floor) --i;
  if (i < ref) {
    throw InputError(trial.source +
                     ": the force changes within the first 50 ms; cannot detect "
                     "the onset (give --onset)");
  }
  return trial.start_time_s + i / trial.sample_rate_hz;
}

RegressionResult regress(const std::vector<data::Trial>& trials, const data::Trial* baseline,
                         const RegressionOptions& o) {
  if (trials.empty()) throw InputError("regress: expected at least one trial");
  if (!(o.profile_hz > 0.0)) throw InputError("--profile-hz: expected a positive rate in Hz");
  const bool full = o.method != RegressionMethod::displacement_steady_state;
  std::vector<Prepared> prepared;
  for (const data::Trial& t : trials) {
    Prepared p{0.0, t.source, t.columns(kColumns)};
    if (!p.data.allFinite()) throw InputError(t.source + ": non-finite samples");
    p.onset_s = o.onset_s ? *o.onset_s : detect_onset_s(t);
    prepared.push_back(std::move(p));
  }
  if (baseline != nullptr) (void)baseline->columns(kColumns);
  // group by onset
  std::vector<int> order(trials.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return prepared[a].onset_s < prepared[b].onset_s; });
  std::vector<std::vector<int>> groups;
  for (int idx : order) {
    if (groups.empty() ||
        prepared[idx].onset_s - prepared[groups.back().front()].onset_s > o.group_tolerance_s) {
      groups.emplace_back();
    }
    groups.back().push_back(idx);
  }

  RegressionResult result;
  result.method = o.method;
  const int unknowns = full ? 6 : 2;
  for (const std::vector<int>& g : groups) {
    RegressionEstimate e;
    e.full = full;
    double onset_sum = 0.0;
    for (int idx : g) onset_sum += prepared[idx].onset_s, e.trials.push_back(prepared[idx].source);
    e.onset_s = onset_sum / g.size();
    const std::string what = "onset group at " + seconds(e.onset_s);
    if (static_cast<int>(g.size()) < unknowns) {
      throw InputError(what + ": " + std::to_string(g.size()) + " perturbation directions for " +
                       std::to_string(unknowns) + " unknowns per force component (" +
                       regression_method_name(o.method) + ")");
    }
    std::vector<Eigen::MatrixXd> phis, targets;
    Eigen::RowVectorXd posture = Eigen::RowVectorXd::Zero(6);
    for (int idx : g) {
      const Prepared& p = prepared[idx];
      const data::Trial& trial = trials[idx];
      const double rate = trial.sample_rate_hz;
      double w0 = p.onset_s, w1 = p.onset_s + o.full_window_s;
      if (!full) {
        // plateau end = onset + ramp + plateau; one sample earlier because the onset found from
        // a smooth ramp's force lags its start by up to one sample
        w1 = p.onset_s + o.ramp_s + o.plateau_s - 1.0 / rate;
        w0 = w1 - o.steady_window_s;
      }
      const int first = sample_at(trial, w0), last = sample_at(trial, w1) - 1;
      if (first < 0 || last >= trial.sample_count() || last - first < 2) {
        throw InputError(p.source + ": the regression window [" + seconds(w0) + ", " + seconds(w1) +
                         ") is not inside the trial");
      }
      const Eigen::MatrixXd base = unperturbed(p, trial, baseline, first, last, o.baseline_s);
      posture += base.row(0);
      const Eigen::MatrixXd window = p.data.middleRows(first, last - first + 1);
      const Eigen::MatrixXd dx = window.middleCols(2, 2) - base.middleCols(2, 2);
      const Eigen::MatrixXd df = window.middleCols(4, 2) - base.middleCols(4, 2);
      if (full) {
        const int sg = savgol_samples(o, rate, static_cast<int>(dx.rows()));
        // sg is odd, so (sg - 1) / rate seconds round back to exactly sg samples.
        const estimators::SavitzkyGolayResult d =
            estimators::savitzky_golay(dx, rate, {(sg - 1) / rate, o.savgol_order});
        Eigen::MatrixXd phi(dx.rows(), 6);
        phi << d.second_derivative, d.first_derivative, dx;
        phis.push_back(phi);
      } else {
        phis.push_back(dx);
      }
      targets.push_back(df);
    }
    posture /= static_cast<double>(g.size());
    Eigen::Index rows = 0;
    for (const auto& p : phis) rows += p.rows();
    Eigen::MatrixXd phi(rows, unknowns), target(rows, 2);
    rows = 0;
    for (std::size_t k = 0; k < phis.size(); ++k) {
      phi.middleRows(rows, phis[k].rows()) = phis[k];
      target.middleRows(rows, phis[k].rows()) = targets[k];
      rows += phis[k].rows();
    }
    const Eigen::MatrixXd theta = solve_regression(phi, target, what);
    const Eigen::MatrixXd residual = target - phi * theta;
    e.residual_rms_n =
        (residual.colwise().squaredNorm() / static_cast<double>(rows)).cwiseSqrt().transpose();
    // dF^T = dx''^T M^T + dx'^T B^T + dx^T K^T
    if (full) {
      e.m_endpoint_kg = theta.middleRows(0, 2).transpose();
      e.b_endpoint_ns_per_m = theta.middleRows(2, 2).transpose();
      e.k_endpoint_n_per_m = theta.middleRows(4, 2).transpose();
      e.time_s = e.onset_s + 0.5 * o.full_window_s;
    } else {
      e.k_endpoint_n_per_m = theta.transpose();
      e.b_endpoint_ns_per_m.setConstant(std::numeric_limits<double>::quiet_NaN());
      e.m_endpoint_kg.setConstant(std::numeric_limits<double>::quiet_NaN());
      e.time_s = e.onset_s + o.ramp_s + o.plateau_s - 0.5 * o.steady_window_s;
    }
    e.theta_rad = posture.head(2).transpose();
    const Eigen::Vector2d hand_force = -posture.segment(4, 2).transpose();
    e.k_joint_nm_per_rad = models::endpoint_to_joint(o.arm, e.theta_rad, e.k_endpoint_n_per_m) +
                           models::load_stiffness(o.arm, e.theta_rad, hand_force);
    e.b_joint_nms_per_rad = models::endpoint_to_joint(o.arm, e.theta_rad, e.b_endpoint_ns_per_m);
    e.m_joint_kg_m2 = models::endpoint_to_joint(o.arm, e.theta_rad, e.m_endpoint_kg);
    result.estimates.push_back(e);
  }

  // PCHIP profiles of every entry between the estimation times.
  const int n = static_cast<int>(result.estimates.size());
  Eigen::VectorXd knots(n);
  Eigen::MatrixXd values(n, 16);
  for (int i = 0; i < n; ++i) {
    const RegressionEstimate& e = result.estimates[i];
    knots(i) = e.time_s;
    // disp-ss has no damping: zeros to interpolate, reported as null
    const Eigen::Matrix2d bj = full ? e.b_joint_nms_per_rad : Eigen::Matrix2d::Zero();
    const Eigen::Matrix2d bx = full ? e.b_endpoint_ns_per_m : Eigen::Matrix2d::Zero();
    values.row(i) << e.k_joint_nm_per_rad.reshaped().transpose(), bj.reshaped().transpose(),
        e.k_endpoint_n_per_m.reshaped().transpose(), bx.reshaped().transpose();
  }
  for (int i = 1; i < n; ++i) {
    if (!(knots(i) > knots(i - 1))) {
      throw InputError("onset groups at " + seconds(result.estimates[i - 1].onset_s) + " and " +
                       seconds(result.estimates[i].onset_s) + " give the same estimation time");
    }
  }
  const int count =
      static_cast<int>(std::floor((knots(n - 1) - knots(0)) * o.profile_hz + 1e-9)) + 1;
  RegressionProfile& prof = result.profile;
  prof.t_s = Eigen::VectorXd::LinSpaced(count, 0, count - 1) / o.profile_hz;
  prof.t_s.array() += knots(0);
  Eigen::MatrixXd curves = values.leftCols(8);
  Eigen::MatrixXd at = Pchip(knots, curves)(prof.t_s);
  Eigen::MatrixXd endpoint_k = Pchip(knots, values.middleCols(8, 4))(prof.t_s);
  Eigen::MatrixXd endpoint_b = Pchip(knots, values.middleCols(12, 4))(prof.t_s);
  for (int i = 0; i < count; ++i) {
    prof.k_joint_nm_per_rad.push_back(at.row(i).segment(0, 4).reshaped(2, 2));
    prof.b_joint_nms_per_rad.push_back(at.row(i).segment(4, 4).reshaped(2, 2));
    prof.k_endpoint_n_per_m.push_back(endpoint_k.row(i).reshaped(2, 2));
    prof.b_endpoint_ns_per_m.push_back(endpoint_b.row(i).reshaped(2, 2));
  }
  return result;
}

nlohmann::json to_json(const RegressionResult& r) {
  auto matrix = [](const Eigen::Matrix2d& m) {
    nlohmann::json rows = nlohmann::json::array();
    for (int i = 0; i < 2; ++i) {
      nlohmann::json row = nlohmann::json::array();
      for (int j = 0; j < 2; ++j) {
        row.push_back(std::isfinite(m(i, j)) ? nlohmann::json(m(i, j)) : nlohmann::json());
      }
      rows.push_back(row);
    }
    return rows;
  };
  auto series = [](const std::vector<Eigen::Matrix2d>& ms) {
    // [row][column][time], as the K_nm_per_rad[r][c] series of `stiffid tfa`
    nlohmann::json out = nlohmann::json::array();
    for (int i = 0; i < 2; ++i) {
      nlohmann::json row = nlohmann::json::array();
      for (int j = 0; j < 2; ++j) {
        nlohmann::json s = nlohmann::json::array();
        for (const Eigen::Matrix2d& m : ms) {
          s.push_back(std::isfinite(m(i, j)) ? nlohmann::json(m(i, j)) : nlohmann::json());
        }
        row.push_back(s);
      }
      out.push_back(row);
    }
    return out;
  };
  nlohmann::json j;
  j["method"] = regression_method_name(r.method);
  j["estimates"] = nlohmann::json::array();
  for (const RegressionEstimate& e : r.estimates) {
    nlohmann::json x;
    x["onset_s"] = e.onset_s;
    x["time_s"] = e.time_s;
    x["trials"] = e.trials;
    x["theta_rad"] = {e.theta_rad(0), e.theta_rad(1)};
    x["K_endpoint_n_per_m"] = matrix(e.k_endpoint_n_per_m);
    x["B_endpoint_ns_per_m"] = e.full ? matrix(e.b_endpoint_ns_per_m) : nlohmann::json();
    x["M_endpoint_kg"] = e.full ? matrix(e.m_endpoint_kg) : nlohmann::json();
    x["K_joint_nm_per_rad"] = matrix(e.k_joint_nm_per_rad);
    x["B_joint_nms_per_rad"] = e.full ? matrix(e.b_joint_nms_per_rad) : nlohmann::json();
    x["M_joint_kg_m2"] = e.full ? matrix(e.m_joint_kg_m2) : nlohmann::json();
    x["residual_rms"] = {e.residual_rms_n(0), e.residual_rms_n(1)};
    j["estimates"].push_back(x);
  }
  const bool full = r.method != RegressionMethod::displacement_steady_state;
  nlohmann::json p;
  p["t_s"] = std::vector<double>(r.profile.t_s.data(), r.profile.t_s.data() + r.profile.t_s.size());
  p["K_joint_nm_per_rad"] = series(r.profile.k_joint_nm_per_rad);
  p["B_joint_nms_per_rad"] = full ? series(r.profile.b_joint_nms_per_rad) : nlohmann::json();
  p["K_endpoint_n_per_m"] = series(r.profile.k_endpoint_n_per_m);
  p["B_endpoint_ns_per_m"] = full ? series(r.profile.b_endpoint_ns_per_m) : nlohmann::json();
  j["profile"] = p;
  return j;
}

}  // namespace stiffid::fitting
