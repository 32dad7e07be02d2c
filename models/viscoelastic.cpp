#include "models/viscoelastic.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "data/error.hpp"

namespace stiffid::models {

namespace {

double logistic(double steepness, double t, double midpoint) {
  return 1.0 / (1.0 + std::exp(-steepness * (t - midpoint)));
}

std::string describe(const Eigen::MatrixXd& m) {
  std::ostringstream out;
  out << "[";
  for (int i = 0; i < m.rows(); ++i) {
    out << (i ? "; " : "");
    for (int j = 0; j < m.cols(); ++j) out << (j ? " " : "") << m(i, j);
  }
  out << "]";
  return out.str();
}

void require_square(const Eigen::MatrixXd& m, int n, const std::string& key) {
  if (m.rows() != n || m.cols() != n) {
    std::ostringstream msg;
    msg << key << ": expected a " << n << " x " << n << " matrix, got " << m.rows() << " x "
        << m.cols();
    throw InputError(msg.str());
  }
  if (!m.allFinite()) throw InputError(key + ": expected finite entries, got " + describe(m));
}

void require_symmetric(const Eigen::MatrixXd& m, const std::string& key) {
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-12 * scale) {
    throw InputError(key + ": expected a symmetric matrix, got " + describe(m));
  }
}

// Smallest eigenvalue of a symmetric matrix.
double min_eigenvalue(const Eigen::MatrixXd& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m, Eigen::EigenvaluesOnly)
      .eigenvalues()
      .minCoeff();
}

}  // namespace

std::vector<double> table_breakpoints(const std::vector<double>& time_s, double t0_s, double t1_s) {
  std::vector<double> out;
  if (time_s.size() < 2) return out;  // one knot: a constant, nothing to stop at
  for (double t : time_s) {
    if (t > t0_s && t < t1_s) out.push_back(t);
  }
  return out;
}

void validate_table_times(const std::vector<double>& time_s, std::size_t values,
                          const std::string& key) {
  if (time_s.empty() || time_s.size() != values) {
    throw InputError(key + ": a table needs as many times as values, at least one (got " +
                     std::to_string(time_s.size()) + " times and " + std::to_string(values) +
                     " values)");
  }
  for (std::size_t k = 0; k < time_s.size(); ++k) {
    if (!std::isfinite(time_s[k])) {
      throw InputError(key + ".time_s[" + std::to_string(k) + "]: expected a finite time in s");
    }
    if (k > 0 && !(time_s[k] > time_s[k - 1])) {
      throw InputError(key + ".time_s[" + std::to_string(k) +
                       "]: expected strictly increasing times");
    }
  }
}

double TimeProfile::value(double t_s, double branch_s) const {
  if (kind == ProfileKind::table) {
    return table_interpolate(table_time_s, table_value, t_s, branch_s);
  }
  if (kind == ProfileKind::constant || branch_s < start_s) return 1.0;
  const double three_quarters = 0.75 * horizon_s;
  switch (kind) {
    case ProfileKind::sigmoid:
      return 4.0 * logistic(4.0, t_s, three_quarters) + 1.0;
    case ProfileKind::sinlin:
      return std::sin(0.8 * M_PI * t_s) + 1.6 * t_s - 4.0;
    case ProfileKind::sharp:
      return 4.0 * logistic(30.0, t_s, three_quarters) + 1.0;
    default:
      return 1.0;
  }
}

std::vector<double> TimeProfile::breakpoints(double t0_s, double t1_s) const {
  std::vector<double> out;
  if (kind == ProfileKind::table) {
    out = table_breakpoints(table_time_s, t0_s, t1_s);
  } else if (kind != ProfileKind::constant && start_s > t0_s && start_s < t1_s) {
    out.push_back(start_s);
  }
  return out;
}

void TimeProfile::validate(const std::string& key) const {
  if (kind == ProfileKind::table) {
    validate_table_times(table_time_s, table_value.size(), key);
    for (double v : table_value) {
      if (!std::isfinite(v)) throw InputError(key + ".value: table entries must be finite");
    }
    return;
  }
  if (!std::isfinite(start_s)) throw InputError(key + ".start_s: expected a finite time in s");
  if (!(horizon_s > 0.0) || !std::isfinite(horizon_s)) {
    throw InputError(key + ".horizon_s: expected a positive finite time in s");
  }
}

ProfileKind profile_kind_from_name(const std::string& name, const std::string& key) {
  if (name == "constant") return ProfileKind::constant;
  if (name == "sigmoid") return ProfileKind::sigmoid;
  if (name == "sinlin") return ProfileKind::sinlin;
  if (name == "sharp") return ProfileKind::sharp;
  if (name == "table") return ProfileKind::table;
  throw InputError(key + ": unknown profile \"" + name +
                   "\", expected constant, sigmoid, sinlin, sharp or table");
}

std::string profile_kind_name(ProfileKind kind) {
  switch (kind) {
    case ProfileKind::constant:
      return "constant";
    case ProfileKind::sigmoid:
      return "sigmoid";
    case ProfileKind::sinlin:
      return "sinlin";
    case ProfileKind::sharp:
      return "sharp";
    case ProfileKind::table:
      return "table";
  }
  return "constant";
}

ElementKind element_kind_from_name(const std::string& name, const std::string& key) {
  if (name == "kelvin_voigt") return ElementKind::kelvin_voigt;
  if (name == "poynting_thomson") return ElementKind::poynting_thomson;
  if (name == "duffing") return ElementKind::duffing;
  if (name == "none") return ElementKind::none;
  throw InputError(key + ": unknown element \"" + name +
                   "\", expected kelvin_voigt, poynting_thomson, duffing or none");
}

std::string element_kind_name(ElementKind kind) {
  switch (kind) {
    case ElementKind::kelvin_voigt:
      return "kelvin_voigt";
    case ElementKind::poynting_thomson:
      return "poynting_thomson";
    case ElementKind::duffing:
      return "duffing";
    case ElementKind::none:
      return "none";
  }
  return "none";
}

std::string element_key(const std::string& field, Space space) {
  const bool joint = space == Space::joint;
  if (field == "damping") return joint ? "damping_nms_per_rad" : "damping_ns_per_m";
  if (field == "cubic_stiffness") {
    return joint ? "cubic_stiffness_nm_per_rad3" : "cubic_stiffness_n_per_m3";
  }
  return field + (joint ? "_nm_per_rad" : "_n_per_m");
}

namespace {

// A stiffness (positive definite) or damping (positive semi-definite; definite for PT) matrix.
void require_element_matrix(const Eigen::MatrixXd& m, int n, bool stiffness, bool definite,
                            const std::string& key) {
  require_square(m, n, key);
  require_symmetric(m, key);
  if (stiffness || definite) {
    if (!(min_eigenvalue(m) > 0.0)) {
      throw InputError(key + ": expected a positive definite matrix, got " + describe(m));
    }
  } else if (!(min_eigenvalue(m) > -1e-12)) {
    throw InputError(key + ": expected a positive semi-definite matrix, got " + describe(m));
  }
}

// A matrix table under `key` ("viscoelasticity.stiffness_table"): given alone (no constant matrix
// `matrix_key`, a constant profile), times, and every knot matrix as the constant one.
void validate_matrix_table(const MatrixTable& table, const Eigen::MatrixXd& matrix,
                           const TimeProfile& profile, ElementKind kind, int n, bool stiffness,
                           const std::string& key, const std::string& matrix_key,
                           const std::string& profile_key) {
  if (kind != ElementKind::kelvin_voigt && kind != ElementKind::duffing) {
    throw InputError(key + ": matrix tables are for kelvin_voigt and duffing elements, not " +
                     element_kind_name(kind));
  }
  if (matrix.size()) {
    throw InputError(key + ": give either " + key.substr(key.rfind('.') + 1) + " or " +
                     matrix_key.substr(matrix_key.rfind('.') + 1) + ", not both");
  }
  if (profile.kind != ProfileKind::constant) {
    throw InputError(key + ": a table replaces " + profile_key.substr(profile_key.rfind('.') + 1) +
                     " (the table holds K(t) or C(t) itself), give only one");
  }
  validate_table_times(table.time_s, table.value.size(), key);
  const std::string value_key = key + "." + matrix_key.substr(matrix_key.rfind('.') + 1);
  for (std::size_t k = 0; k < table.value.size(); ++k) {
    require_element_matrix(table.value[k], n, stiffness, false,
                           value_key + "[" + std::to_string(k) + "]");
  }
}

}  // namespace

void Viscoelasticity::validate(const std::string& prefix, Space space) const {
  const std::string key = prefix + ".";
  const std::string k_key = key + element_key("stiffness", space);
  const std::string c_key = key + element_key("damping", space);
  const std::string s_key = key + element_key("series_stiffness", space);
  const std::string b_key = key + element_key("cubic_stiffness", space);
  const int n = dimension();
  if (n < 1) throw InputError(k_key + ": the stiffness matrix is empty");
  if (stiffness_table.empty()) {
    require_square(stiffness, n, k_key);
  } else {
    validate_matrix_table(stiffness_table, stiffness, stiffness_profile, kind, n, true,
                          key + "stiffness_table", k_key, key + "stiffness_profile");
  }
  if (damping_table.empty()) {
    require_square(damping, n, c_key);
  } else {
    validate_matrix_table(damping_table, damping, damping_profile, kind, n, false,
                          key + "damping_table", c_key, key + "damping_profile");
    if (damping_rotation_rad != 0.0) {
      throw InputError(key + "damping_table: a table replaces damping_rotation_deg " +
                       "(rotate the tabulated matrices instead), give only one");
    }
  }
  if (kind == ElementKind::none) return;
  const bool pt = kind == ElementKind::poynting_thomson;
  if (stiffness_table.empty()) require_element_matrix(stiffness, n, true, pt, k_key);
  if (damping_table.empty()) require_element_matrix(damping, n, false, pt, c_key);
  if (kind == ElementKind::poynting_thomson) {
    require_square(series_stiffness, n, s_key);
    require_symmetric(series_stiffness, s_key);
    if (!(min_eigenvalue(series_stiffness) > 0.0)) {
      throw InputError(s_key + ": expected a positive definite matrix, got " +
                       describe(series_stiffness));
    }
  }
  if (kind == ElementKind::duffing) {
    require_square(cubic_stiffness, n, b_key);
    if ((cubic_stiffness.diagonal().array() < 0.0).any()) {
      throw InputError(b_key + ": expected a non-negative diagonal (hardening)");
    }
  }
  if (damping_rotation_rad != 0.0 && n != 2) {
    throw InputError(key + "damping_rotation_deg: the rotation of eq 55 needs n = 2");
  }
  if (!std::isfinite(damping_rotation_rad)) {
    throw InputError(key + "damping_rotation_deg: expected a finite angle");
  }
  stiffness_profile.validate(key + "stiffness_profile");
  damping_profile.validate(key + "damping_profile");
}

Eigen::Matrix2d rotate_damping(const Eigen::Matrix2d& damping, double nu_rad) {
  Eigen::Matrix2d r;
  r << std::cos(nu_rad), -std::sin(nu_rad), std::sin(nu_rad), std::cos(nu_rad);
  return r * damping * r.transpose();
}

Eigen::MatrixXd stiffness_at(const Viscoelasticity& e, double t_s) {
  if (!e.stiffness_table.empty()) return e.stiffness_table.at(t_s);
  return e.stiffness * e.stiffness_profile.value(t_s);
}

Eigen::MatrixXd damping_at(const Viscoelasticity& e, double t_s) {
  if (!e.damping_table.empty()) return e.damping_table.at(t_s);
  const double u = e.damping_profile.value(t_s);
  if (e.damping_rotation_rad != 0.0 && e.dimension() == 2) {
    return Eigen::MatrixXd(rotate_damping(e.damping, e.damping_rotation_rad)) * u;
  }
  return e.damping * u;
}

Eigen::VectorXd element_force(const Viscoelasticity& e, double t_s, const Eigen::VectorXd& d,
                              const Eigen::VectorXd& d_dot, const Eigen::VectorXd& z) {
  switch (e.kind) {
    case ElementKind::none:
      return Eigen::VectorXd::Zero(d.size());
    case ElementKind::kelvin_voigt:
      return -damping_at(e, t_s) * d_dot - stiffness_at(e, t_s) * d;
    case ElementKind::duffing:
      return -damping_at(e, t_s) * d_dot - stiffness_at(e, t_s) * d -
             e.cubic_stiffness * d.array().cube().matrix();
    case ElementKind::poynting_thomson:
      return -e.series_stiffness * (d - z);
  }
  return Eigen::VectorXd::Zero(d.size());
}

Eigen::VectorXd element_internal_rate(const Viscoelasticity& e, double t_s,
                                      const Eigen::VectorXd& d, const Eigen::VectorXd& z) {
  if (e.kind != ElementKind::poynting_thomson) return {};
  const Eigen::VectorXd drive = e.series_stiffness * (d - z) - stiffness_at(e, t_s) * z;
  return damping_at(e, t_s).ldlt().solve(drive);
}

Viscoelasticity piovesan_kelvin_voigt() {
  Viscoelasticity e;
  e.kind = ElementKind::kelvin_voigt;
  e.stiffness = (Eigen::MatrixXd(2, 2) << 35.0, 5.0, 5.0, 20.0).finished();
  e.damping = 0.01 * e.stiffness;
  return e;
}

Viscoelasticity piovesan_duffing() {
  Viscoelasticity e = piovesan_kelvin_voigt();
  e.kind = ElementKind::duffing;
  e.cubic_stiffness = 2.0e5 * e.stiffness;
  return e;
}

Viscoelasticity piovesan_poynting_thomson() {
  const Viscoelasticity k0 = piovesan_kelvin_voigt();
  Viscoelasticity e;
  e.kind = ElementKind::poynting_thomson;
  e.stiffness = 2.0 * k0.stiffness;
  e.series_stiffness = 5.0 * e.stiffness;
  e.damping = k0.stiffness.cwiseAbs();
  return e;
}

}  // namespace stiffid::models
