#include "fitting/tfa_fit.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "data/error.hpp"
#include "data/text_input.hpp"

namespace stiffid::fitting {
namespace {

constexpr const char* kExpected = "the JSON of stiffid tfa";

// A [r][c][T] matrix track of the tfa JSON as T matrices (n x n).
std::vector<Eigen::MatrixXd> read_track(const nlohmann::json& j, const std::string& key,
                                        const std::string& path, int n, std::size_t frames) {
  const nlohmann::json& m = data::json_member(j, key, path, "", kExpected);
  if (!m.is_array() || static_cast<int>(m.size()) != n) {
    throw InputError(path + ": '" + key + "' must be " + std::to_string(n) + " rows [r][c][t]");
  }
  std::vector<Eigen::MatrixXd> out(frames, Eigen::MatrixXd(n, n));
  for (int r = 0; r < n; ++r) {
    if (!m[r].is_array() || static_cast<int>(m[r].size()) != n) {
      throw InputError(path + ": '" + key + "[" + std::to_string(r) + "]' must hold " +
                       std::to_string(n) + " columns");
    }
    for (int c = 0; c < n; ++c) {
      const std::string where = key + "[" + std::to_string(r) + "][" + std::to_string(c) + "]";
      const std::vector<double> v = data::json_numbers(m[r][c], path, where, frames, true);
      for (std::size_t t = 0; t < frames; ++t) out[t](r, c) = v[t];
    }
  }
  return out;
}

// Lag-1 autocorrelation of a residual series (mean removed), clipped to [0, 1).
double lag1_autocorrelation(const Eigen::VectorXd& e) {
  if (e.size() < 3) return 0.0;
  const Eigen::VectorXd c = e.array() - e.mean();
  const double denominator = c.squaredNorm();
  if (!(denominator > 0.0)) return 0.0;
  const double rho = c.head(c.size() - 1).dot(c.tail(c.size() - 1)) / denominator;
  return std::clamp(rho, 0.0, 1.0 - 1e-12);
}

}  // namespace

TfaTarget read_tfa_json(const std::string& path) {
  const nlohmann::json j = data::read_json_file(path);
  TfaTarget t;
  t.source = path;
  const std::vector<double> time = data::json_numbers(
      data::json_member(j, "t_s", path, "", kExpected), path, "t_s", 0);
  const std::size_t frames = time.size();
  if (frames == 0) throw InputError(path + ": 't_s' holds no frame");
  t.time_s = Eigen::Map<const Eigen::VectorXd>(time.data(), static_cast<Eigen::Index>(frames));
  const nlohmann::json& k = data::json_member(j, "K_nm_per_rad", path, "", kExpected);
  const int n = k.is_array() ? static_cast<int>(k.size()) : 0;
  if (n < 1 || n > kMaxDof) {
    throw InputError(path + ": 'K_nm_per_rad' must be an n x n x T array with 1 <= n <= " +
                     std::to_string(kMaxDof));
  }
  t.stiffness_nm_per_rad = read_track(j, "K_nm_per_rad", path, n, frames);
  t.damping_nms_per_rad = read_track(j, "C_nms_per_rad", path, n, frames);
  if (!j.contains("M_kg_m2")) {
    throw InputError(path + ": missing key 'M_kg_m2' (the inertia track; written by stiffid tfa "
                     "from version 0.1.0 on: re-run stiffid tfa)");
  }
  t.inertia_kg_m2 = read_track(j, "M_kg_m2", path, n, frames);
  t.valid.assign(frames, true);
  if (j.contains("K_valid")) {
    const nlohmann::json& v = j.at("K_valid");
    if (!v.is_array() || v.size() != frames) {
      throw InputError(path + ": 'K_valid' must be an array of " + std::to_string(frames) +
                       " booleans");
    }
    for (std::size_t f = 0; f < frames; ++f) {
      if (!v[f].is_boolean()) throw InputError(path + ": 'K_valid' holds a non-boolean");
      t.valid[f] = v[f].get<bool>();
    }
  }
  return t;
}

TfaFitResult fit_tfa(const TfaTarget& target, const TfaFitOptions& options) {
  if (options.model != LumpedModel::kelvin_voigt) {
    throw InputError("fit " + model_name(options.model) +
                     " --tfa: only the Kelvin-Voigt model (kv) is fitted to tfa tracks; the "
                     "modal K(t), C(t) of a Poynting-Thomson or Duffing limb are per-mode "
                     "frequency- or amplitude-dependent equivalents, not its matrices: fit the "
                     "trial itself (TRIAL.csv --inputs --outputs)");
  }
  if (!(options.from_s <= options.to_s)) {
    throw InputError("--interval: the first time must not exceed the last");
  }
  const Eigen::Index frames = target.time_s.size();
  const int n = frames > 0 ? static_cast<int>(target.stiffness_nm_per_rad[0].rows()) : 0;
  const std::vector<const std::vector<Eigen::MatrixXd>*> tracks{
      &target.inertia_kg_m2, &target.damping_nms_per_rad, &target.stiffness_nm_per_rad};
  std::vector<Eigen::Index> used;
  for (Eigen::Index f = 0; f < frames; ++f) {
    const double t = target.time_s(f);
    if (!target.valid[f] || t < options.from_s || t > options.to_s) continue;
    bool finite = true;
    for (const auto* track : tracks) finite = finite && (*track)[f].allFinite();
    if (finite) used.push_back(f);
  }
  const int count = static_cast<int>(used.size());
  if (count < 3) {
    std::ostringstream msg;
    msg << target.source << ": " << count << " valid frames with finite K, C and M";
    if (std::isfinite(options.from_s) || std::isfinite(options.to_s)) {
      msg << " in " << options.from_s << ".." << options.to_s << " s";
    }
    msg << ", need at least 3";
    throw InputError(msg.str());
  }

  TfaFitResult out;
  out.frames = count;
  out.first_s = target.time_s(used.front());
  out.last_s = target.time_s(used.back());
  LumpedFitResult& fit = out.fit;
  fit.model = LumpedModel::kelvin_voigt;
  fit.target = "tfa";
  fit.dof = n;
  fit.starts = 0;
  fit.iterations = 0;
  fit.termination = "closed form: frame mean of each track over " + std::to_string(count) +
                    " frames";
  fit.vaf_percent.resize(3);
  fit.residual_rms_m.resize(3);
  fit.standard_errors_ok = true;
  const std::vector<MatrixParameter> layout = model_matrices(LumpedModel::kelvin_voigt);  // I C K
  const char* units[] = {"kg m^2", "N m s/rad", "N m/rad"};
  std::vector<Eigen::MatrixXd> means;
  std::string failure;
  for (int a = 0; a < 3; ++a) {
    const std::vector<Eigen::MatrixXd>& track = *tracks[a];
    Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(n, n);
    double energy = 0.0;
    for (const Eigen::Index f : used) {
      const Eigen::MatrixXd symmetric = 0.5 * (track[f] + track[f].transpose());
      mean += symmetric;
      energy += symmetric.squaredNorm();
    }
    mean /= count;
    FittedMatrix fm{layout[a].name, units[a], mean, Eigen::MatrixXd(n, n)};
    Eigen::MatrixXd inflation(n, n);
    double residual_energy = 0.0;
    for (int r = 0; r < n; ++r) {
      for (int c = r; c < n; ++c) {
        Eigen::VectorXd e(count);
        for (int k = 0; k < count; ++k) {
          const Eigen::Index f = used[k];
          e(k) = 0.5 * (track[f](r, c) + track[f](c, r)) - mean(r, c);
        }
        const double rho = lag1_autocorrelation(e);
        const double factor = std::min((1.0 + rho) / (1.0 - rho), static_cast<double>(count));
        const double variance = e.squaredNorm() / (count - 1);
        fm.std_error(r, c) = fm.std_error(c, r) = std::sqrt(variance * factor / count);
        inflation(r, c) = inflation(c, r) = factor;
        residual_energy += (r == c ? 1.0 : 2.0) * e.squaredNorm();
      }
    }
    fit.vaf_percent(a) = energy > 0.0 ? 100.0 * (1.0 - residual_energy / energy) : 0.0;
    fit.residual_rms_m(a) = std::sqrt(residual_energy / (static_cast<double>(count) * n * n));
    const Eigen::LLT<Eigen::MatrixXd> llt(mean);
    if (llt.info() != Eigen::Success && failure.empty()) {
      failure = "the frame mean of " + layout[a].name + " over " + std::to_string(count) +
                " frames is not positive definite (the track is indefinite where the modes are "
                "poorly resolved: narrow --interval to the valid part)";
    }
    fit.parameters.push_back(fm);
    out.variance_inflation.push_back(inflation);
    means.push_back(mean);
  }
  if (!failure.empty()) {
    fit.status = Status::failure(failure);
    return out;
  }
  fit.theta = matrices_to_theta(LumpedModel::kelvin_voigt, means);
  fit.status = Status::success();
  return out;
}

nlohmann::json to_json(const TfaFitResult& result) {
  nlohmann::json j = to_json(result.fit);
  j["frames"] = result.frames;
  j["interval_s"] = {result.first_s, result.last_s};
  nlohmann::json names = nlohmann::json::array(), inflation = nlohmann::json::object();
  for (std::size_t a = 0; a < result.fit.parameters.size(); ++a) {
    const std::string& name = result.fit.parameters[a].name;
    names.push_back(name);
    nlohmann::json rows = nlohmann::json::array();
    const Eigen::MatrixXd& m = result.variance_inflation[a];
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
      rows.push_back(row);
    }
    inflation[name] = rows;
  }
  j["vaf_of"] = names;
  j["variance_inflation"] = inflation;
  return j;
}

}  // namespace stiffid::fitting
