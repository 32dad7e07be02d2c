#include "fitting/tfa_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
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
  const std::vector<double> time =
      data::json_numbers(data::json_member(j, "t_s", path, "", kExpected), path, "t_s", 0);
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
    throw InputError(path +
                     ": missing key 'M_kg_m2' (the inertia track; written by stiffid tfa "
                     "from version 0.1.0 on: re-run stiffid tfa)");
  }
  t.inertia_kg_m2 = read_track(j, "M_kg_m2", path, n, frames);
  if (j.contains("options") && j["options"].is_object() && j["options"].contains("chirp")) {
    const nlohmann::json& chirp = j["options"]["chirp"];
    t.chirped_frames = chirp.is_boolean() && chirp.get<bool>();
  }
  t.valid.assign(frames, true);
  if (j.contains("valid")) {  // [j][T], one series per mode
    const nlohmann::json& v = j.at("valid");
    if (!v.is_array() || static_cast<int>(v.size()) != n) {
      throw InputError(path + ": 'valid' must hold " + std::to_string(n) + " series of " +
                       std::to_string(frames) + " booleans (one per mode)");
    }
    for (int mode = 0; mode < n; ++mode) {
      if (!v[mode].is_array() || v[mode].size() != frames) {
        throw InputError(path + ": 'valid[" + std::to_string(mode) + "]' must be an array of " +
                         std::to_string(frames) + " booleans");
      }
      for (std::size_t f = 0; f < frames; ++f) {
        if (!v[mode][f].is_boolean()) throw InputError(path + ": 'valid' holds a non-boolean");
        t.valid[f] = t.valid[f] && v[mode][f].get<bool>();
      }
    }
  }
  if (j.contains("eigenvectors")) t.eigenvectors = read_track(j, "eigenvectors", path, n, frames);
  if (j.contains("normalized_force") && j.at("normalized_force").contains("envelope")) {
    const nlohmann::json& e = j.at("normalized_force").at("envelope");
    if (!e.is_array() || static_cast<int>(e.size()) != n) {
      throw InputError(path + ": 'normalized_force.envelope' must hold " + std::to_string(n) +
                       " series (one per mode)");
    }
    t.envelope.resize(static_cast<Eigen::Index>(frames), n);
    for (int mode = 0; mode < n; ++mode) {
      const std::string where = "normalized_force.envelope[" + std::to_string(mode) + "]";
      const std::vector<double> v = data::json_numbers(e[mode], path, where, frames, true);
      for (std::size_t f = 0; f < frames; ++f)
        t.envelope(static_cast<Eigen::Index>(f), mode) = v[f];
    }
  }
  if (j.contains("K_valid")) {
    const nlohmann::json& v = j.at("K_valid");
    if (!v.is_array() || v.size() != frames) {
      throw InputError(path + ": 'K_valid' must be an array of " + std::to_string(frames) +
                       " booleans");
    }
    for (std::size_t f = 0; f < frames; ++f) {
      if (!v[f].is_boolean()) throw InputError(path + ": 'K_valid' holds a non-boolean");
      t.valid[f] = t.valid[f] && v[f].get<bool>();
    }
  }
  return t;
}

namespace {

// A matrix fitted to a track: its value and standard errors, the variance inflation of each
// entry, and the share of the track's energy the fit explains.
struct MatrixFit {
  FittedMatrix fitted;
  Eigen::MatrixXd inflation;
  double vaf_percent = 0.0;
  double residual_rms = 0.0;
};

// (1 + rho) / (1 - rho) of a residual series, at most `count` (one independent frame).
double inflation_factor(const Eigen::VectorXd& residual, int count) {
  const double rho = lag1_autocorrelation(residual);
  return std::min((1.0 + rho) / (1.0 - rho), static_cast<double>(count));
}

Eigen::MatrixXd symmetric(const Eigen::MatrixXd& a) { return 0.5 * (a + a.transpose()); }

// The frame mean of a track over the frames `used` (Kelvin-Voigt; I and C of Duffing).
MatrixFit mean_fit(const std::vector<Eigen::MatrixXd>& track, const std::vector<Eigen::Index>& used,
                   const std::string& name, const std::string& unit) {
  const int n = static_cast<int>(track[used.front()].rows());
  const int count = static_cast<int>(used.size());
  Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(n, n);
  double energy = 0.0;
  for (const Eigen::Index f : used) {
    const Eigen::MatrixXd a = symmetric(track[f]);
    mean += a;
    energy += a.squaredNorm();
  }
  mean /= count;
  MatrixFit out{{name, unit, mean, Eigen::MatrixXd(n, n)}, Eigen::MatrixXd(n, n)};
  double residual_energy = 0.0;
  for (int r = 0; r < n; ++r) {
    for (int c = r; c < n; ++c) {
      Eigen::VectorXd e(count);
      for (int k = 0; k < count; ++k) {
        const Eigen::Index f = used[k];
        e(k) = 0.5 * (track[f](r, c) + track[f](c, r)) - mean(r, c);
      }
      const double factor = inflation_factor(e, count);
      const double variance = e.squaredNorm() / (count - 1);
      out.fitted.std_error(r, c) = out.fitted.std_error(c, r) =
          std::sqrt(variance * factor / count);
      out.inflation(r, c) = out.inflation(c, r) = factor;
      residual_energy += (r == c ? 1.0 : 2.0) * e.squaredNorm();
    }
  }
  out.vaf_percent = energy > 0.0 ? 100.0 * (1.0 - residual_energy / energy) : 0.0;
  out.residual_rms = std::sqrt(residual_energy / (static_cast<double>(count) * n * n));
  return out;
}

// The Duffing backbone fit of the K track (see the top of tfa_fit.hpp): K (symmetric) and the
// diagonal B by linear least squares over the frames `used`.
struct BackboneFit {
  MatrixFit k;
  MatrixFit b;
  std::string failure;  // empty on success
};

BackboneFit backbone_fit(const TfaTarget& t, const std::vector<Eigen::Index>& used) {
  const int n = static_cast<int>(t.stiffness_nm_per_rad[used.front()].rows());
  const int count = static_cast<int>(used.size());
  const int entries = n * (n + 1) / 2;  // K's upper triangle, row by row
  const int unknowns = entries + n;     // then B_00 .. B_n-1,n-1
  Eigen::MatrixXd a(static_cast<Eigen::Index>(count) * entries, unknowns);
  Eigen::VectorXd y(a.rows());
  a.setZero();
  for (int k = 0; k < count; ++k) {
    const Eigen::Index f = used[k];
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> inertia(symmetric(t.inertia_kg_m2[f]));
    const Eigen::MatrixXd root = inertia.operatorSqrt();            // M^1/2, sqrt(kg) m
    const Eigen::MatrixXd& p = t.eigenvectors[f];                   // columns p_j
    const Eigen::MatrixXd phi = inertia.operatorInverseSqrt() * p;  // M^-1/2 P, columns phi_j
    const Eigen::ArrayXd amplitude2 = t.envelope.row(f).transpose().array().square();  // a_j^2
    std::vector<Eigen::MatrixXd> g(n);
    for (int i = 0; i < n; ++i) {
      const Eigen::ArrayXd phi2 = phi.row(i).transpose().array().square();  // phi_ij^2 over j
      const double all = (phi2 * amplitude2).sum();                         // sum_k phi_ik^2 a_k^2
      // 3/4 phi_ij^2 a_j^2 + 3/2 sum_{k != j} phi_ik^2 a_k^2 = 3/2 all - 3/4 phi_ij^2 a_j^2
      const Eigen::VectorXd modal = (phi2 * (1.5 * all - 0.75 * phi2 * amplitude2)).matrix();
      g[i] = root * p * modal.asDiagonal() * p.transpose() * root;
    }
    const Eigen::MatrixXd measured = symmetric(t.stiffness_nm_per_rad[f]);
    for (int r = 0, e = 0; r < n; ++r) {
      for (int c = r; c < n; ++c, ++e) {
        const Eigen::Index row = static_cast<Eigen::Index>(k) * entries + e;
        const double w = r == c ? 1.0 : std::sqrt(2.0);  // off-diagonal entries weigh twice
        a(row, e) = w;
        for (int i = 0; i < n; ++i) a(row, entries + i) = w * g[i](r, c);
        y(row) = w * measured(r, c);
      }
    }
  }
  // Columns scaled to unit norm (the B columns are ~a^2 smaller than K's), then column-pivoted QR.
  const Eigen::VectorXd scale = a.colwise().norm().transpose();
  BackboneFit out;
  if (!(scale.array() > 0.0).all()) {
    out.failure =
        "the modal amplitudes are zero on every frame used: the cubic stiffness B is "
        "not excited";
    return out;
  }
  const Eigen::MatrixXd scaled = a * scale.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(scaled);
  const Eigen::MatrixXd r =
      qr.matrixR().topLeftCorner(unknowns, unknowns).triangularView<Eigen::Upper>();
  const double rcond = std::abs(r(unknowns - 1, unknowns - 1) / r(0, 0));
  if (qr.rank() < unknowns || !(rcond > 1e-10)) {
    out.failure = "K and B cannot be told apart from the tracks over " + std::to_string(count) +
                  " frames (reciprocal condition " + std::to_string(rcond) +
                  " of the least-squares system): the modal amplitudes hardly change over the "
                  "interval; use the decaying free response right after the impulse";
    return out;
  }
  const Eigen::VectorXd theta = qr.solve(y).cwiseQuotient(scale);
  const Eigen::VectorXd residual = y - a * theta;
  // Covariance s^2 (A^T A)^-1 = s^2 S^-1 Pi R^-1 R^-T Pi^T S^-1 (S the scaling, Pi the pivots).
  const int dof = static_cast<int>(a.rows()) - unknowns;
  const double s2 =
      dof > 0 ? residual.squaredNorm() / dof : std::numeric_limits<double>::quiet_NaN();
  const Eigen::MatrixXd r_inverse =
      r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(unknowns, unknowns));
  const Eigen::MatrixXd permuted = qr.colsPermutation() * r_inverse;
  Eigen::MatrixXd covariance = s2 * (permuted * permuted.transpose());
  covariance = scale.cwiseInverse().asDiagonal() * covariance * scale.cwiseInverse().asDiagonal();
  // Serial correlation: the largest inflation of K's entry residual series.
  double factor = 1.0;
  for (int e = 0; e < entries; ++e) {
    Eigen::VectorXd series(count);
    for (int k = 0; k < count; ++k)
      series(k) = residual(static_cast<Eigen::Index>(k) * entries + e);
    factor = std::max(factor, inflation_factor(series, count));
  }
  covariance *= factor;

  Eigen::MatrixXd k_value(n, n), k_error(n, n);
  for (int r0 = 0, e = 0; r0 < n; ++r0) {
    for (int c = r0; c < n; ++c, ++e) {
      k_value(r0, c) = k_value(c, r0) = theta(e);
      k_error(r0, c) = k_error(c, r0) = std::sqrt(covariance(e, e));
    }
  }
  Eigen::MatrixXd b_value = Eigen::MatrixXd::Zero(n, n), b_error = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    b_value(i, i) = theta(entries + i);
    b_error(i, i) = std::sqrt(covariance(entries + i, entries + i));
  }
  double energy = 0.0;
  for (const Eigen::Index f : used) energy += symmetric(t.stiffness_nm_per_rad[f]).squaredNorm();
  const double residual_energy = residual.squaredNorm();  // = sum_t ||K_t - fit_t||_F^2
  out.k = {{"K", "N m/rad", k_value, k_error}, Eigen::MatrixXd::Constant(n, n, factor)};
  out.k.vaf_percent = energy > 0.0 ? 100.0 * (1.0 - residual_energy / energy) : 0.0;
  out.k.residual_rms = std::sqrt(residual_energy / (static_cast<double>(count) * n * n));
  out.b = {{"B", "N m/rad^3", b_value, b_error}, Eigen::MatrixXd::Constant(n, n, factor)};
  return out;
}

bool positive_definite(const Eigen::MatrixXd& a) {
  return Eigen::LLT<Eigen::MatrixXd>(a).info() == Eigen::Success;
}

}  // namespace

TfaFitResult fit_tfa(const TfaTarget& target, const TfaFitOptions& options) {
  const bool duffing = options.model == LumpedModel::duffing;
  if (options.model != LumpedModel::kelvin_voigt && !duffing) {
    throw InputError("fit " + model_name(options.model) +
                     " --tfa: a Poynting-Thomson limb cannot be identified from tfa tracks: they "
                     "give two numbers per mode (eta^2 and Gamma at the mode's frequency) while "
                     "K_S, K_P and C_P are three symmetric matrices, and the relaxation pole "
                     "that would separate them is not tracked; fit kv or duffing to the tracks, "
                     "or pt to the trial itself (TRIAL.csv --inputs --outputs)");
  }
  if (!(options.from_s <= options.to_s)) {
    throw InputError("--interval: the first time must not exceed the last");
  }
  const Eigen::Index frames = target.time_s.size();
  const int n = frames > 0 ? static_cast<int>(target.stiffness_nm_per_rad[0].rows()) : 0;
  if (duffing && (static_cast<Eigen::Index>(target.eigenvectors.size()) != frames ||
                  target.envelope.rows() != frames || target.envelope.cols() != n)) {
    throw InputError(target.source +
                     ": fit duffing --tfa needs the modal eigenvectors "
                     "('eigenvectors') and amplitudes ('normalized_force.envelope') of stiffid "
                     "tfa, and the file lacks them");
  }
  const std::vector<const std::vector<Eigen::MatrixXd>*> tracks{
      &target.inertia_kg_m2, &target.damping_nms_per_rad, &target.stiffness_nm_per_rad};
  std::vector<Eigen::Index> used;
  for (Eigen::Index f = 0; f < frames; ++f) {
    const double t = target.time_s(f);
    if (!target.valid[f] || t < options.from_s || t > options.to_s) continue;
    bool finite = true;
    for (const auto* track : tracks) finite = finite && (*track)[f].allFinite();
    if (duffing) {
      finite = finite && target.eigenvectors[f].allFinite() && target.envelope.row(f).allFinite();
    }
    if (finite) used.push_back(f);
  }
  const int count = static_cast<int>(used.size());
  const int needed = duffing ? 2 * (n * (n + 1) / 2 + n) : 3;
  if (count < std::max(3, needed)) {
    std::ostringstream msg;
    msg << target.source << ": " << count << " valid frames with finite K, C and M";
    if (duffing) msg << ", eigenvectors and envelopes";
    if (std::isfinite(options.from_s) || std::isfinite(options.to_s)) {
      msg << " in " << options.from_s << ".." << options.to_s << " s";
    }
    msg << ", need at least " << std::max(3, needed);
    throw InputError(msg.str());
  }

  TfaFitResult out;
  out.frames = count;
  out.first_s = target.time_s(used.front());
  out.last_s = target.time_s(used.back());
  LumpedFitResult& fit = out.fit;
  fit.model = options.model;
  fit.target = "tfa";
  fit.dof = n;
  fit.starts = 0;
  fit.iterations = 0;
  fit.termination =
      duffing ? "closed form: linear least squares of the first-order backbone K(t) = K + sum_i "
                "B_ii G_i(t) over " +
                    std::to_string(count) + " frames; frame means for I and C"
              : "closed form: frame mean of each track over " + std::to_string(count) + " frames";
  fit.vaf_percent.resize(3);
  fit.residual_rms_m.resize(3);
  fit.standard_errors_ok = true;
  std::vector<MatrixFit> fits{mean_fit(target.inertia_kg_m2, used, "I", "kg m^2"),
                              mean_fit(target.damping_nms_per_rad, used, "C", "N m s/rad")};
  std::string failure;
  if (duffing) {
    BackboneFit backbone = backbone_fit(target, used);
    if (!backbone.failure.empty()) {
      fit.status = Status::failure(backbone.failure);
      return out;
    }
    fits.push_back(std::move(backbone.k));
    fits.push_back(std::move(backbone.b));
  } else {
    fits.push_back(mean_fit(target.stiffness_nm_per_rad, used, "K", "N m/rad"));
  }
  std::vector<Eigen::MatrixXd> values;
  for (std::size_t a = 0; a < fits.size(); ++a) {
    const MatrixFit& m = fits[a];
    if (a < 3) {
      fit.vaf_percent(static_cast<Eigen::Index>(a)) = m.vaf_percent;
      fit.residual_rms_m(static_cast<Eigen::Index>(a)) = m.residual_rms;
      if (!positive_definite(m.fitted.value) && failure.empty()) {
        failure = "the fitted " + m.fitted.name + " over " + std::to_string(count) +
                  " frames is not positive definite (the track is indefinite where the modes "
                  "are poorly resolved: narrow --interval to the valid part)";
      }
    }
    fit.parameters.push_back(m.fitted);
    out.variance_inflation.push_back(m.inflation);
    values.push_back(m.fitted.value);
  }
  if (!failure.empty()) {
    fit.status = Status::failure(failure);
    return out;
  }
  fit.theta = matrices_to_theta(options.model, values);
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
