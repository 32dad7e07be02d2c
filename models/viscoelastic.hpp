#pragma once
// Viscoelastic elements of the simulator: Kelvin-Voigt with time-varying K(t), C(t) (Piovesan et
// al. 2012 eq 15), Poynting-Thomson with its internal state (eq 16), Duffing with a cubic matrix
// (eq 17); the time profiles u1..u4 of eq 54 and tabulated user profiles; the rotation of C of
// eq 55. An element has n degrees of freedom: n = 2 joints for the arm (N m/rad, N m s/rad) or the
// n axes of an endpoint model (N/m, N s/m). Forces are generalized forces ON the limb.

#include <Eigen/Core>
#include <algorithm>
#include <string>
#include <vector>

namespace stiffid::models {

/// Piecewise-linear interpolation of the knots (time_s[k], values[k]) (time_s strictly increasing,
/// one value per time), held constant outside [time_s.front(), time_s.back()]: the value at t_s on
/// the linear piece that holds at `branch_s` (the integrator passes its segment's midpoint, so that
/// a step overshooting a knot continues the segment's piece; branch_s = t_s is the plain
/// interpolation). T is double (the `table` profile) or an Eigen matrix (the matrix tables); this
/// is the one interpolation of both.
template <class T>
T table_interpolate(const std::vector<double>& time_s, const std::vector<T>& values, double t_s,
                    double branch_s) {
  if (branch_s < time_s.front() || time_s.size() == 1) return values.front();
  if (branch_s >= time_s.back()) return values.back();
  const auto upper = std::upper_bound(time_s.begin(), time_s.end(), branch_s);
  const std::size_t k = static_cast<std::size_t>(upper - time_s.begin());
  const double w = (t_s - time_s[k - 1]) / (time_s[k] - time_s[k - 1]);
  return T((1.0 - w) * values[k - 1] + w * values[k]);
}
/// The knots of a table strictly inside (t0_s, t1_s): where the interpolant's derivative jumps,
/// for the integrator to stop at (none for a one-knot table, a constant).
std::vector<double> table_breakpoints(const std::vector<double>& time_s, double t0_s, double t1_s);
/// Throws InputError naming `key` unless `time_s` holds `values` (>= 1) finite, strictly
/// increasing times ("KEY.time_s: ..." for the times, "KEY: ..." for the count).
void validate_table_times(const std::vector<double>& time_s, std::size_t values,
                          const std::string& key);

/// Named time profiles of Piovesan eq 54 (T = horizon_s, 5 s in the paper):
///   constant u1 = 1
///   sigmoid  u2 = 4 / (1 + exp(-4 (t - 3T/4))) + 1
///   sinlin   u3 = sin(4/5 pi t) + 8/5 t - 4          (as printed; u3(2.5 s) = 0, u3(5 s) = 4)
///   sharp    u4 = 4 / (1 + exp(-30 (t - 3T/4))) + 1
///   table    linear interpolation of (table_time_s, table_value), held constant outside.
enum class ProfileKind { constant, sigmoid, sinlin, sharp, table };

/// A dimensionless multiplier u(t) of a stiffness or damping matrix (Piovesan eq 53). Eq 53 applies
/// the profile for start_s <= t <= T; before start_s the multiplier is 1 (the "constant stiffness
/// and damping imposed at the beginning of the movement", Fig 3), so the named profiles may jump at
/// start_s (u2: 1 -> 1.027, u3: 1 -> 0). A table profile ignores start_s and horizon_s.
struct TimeProfile {
  ProfileKind kind = ProfileKind::constant;
  double start_s = 2.5;              ///< time the profile starts to act, s (Piovesan: 2.5 s)
  double horizon_s = 5.0;            ///< T of eq 54, s (Piovesan: 5 s, the trial duration)
  std::vector<double> table_time_s;  ///< [P] strictly increasing times, s (kind == table)
  std::vector<double> table_value;   ///< [P] multipliers at those times, dimensionless

  /// u(t), dimensionless.
  double value(double t_s) const { return value(t_s, t_s); }
  /// u(t) continued from the smooth piece that holds at `branch_s` (used by the integrator so that
  /// a step overshooting a breakpoint keeps a smooth right-hand side; equals value(t) when t and
  /// branch_s lie between the same breakpoints).
  double value(double t_s, double branch_s) const;
  /// Times in [t0_s, t1_s] where u(t) or its derivative is discontinuous (start_s for named
  /// non-constant profiles, the interior table knots), for the integrator to stop at.
  std::vector<double> breakpoints(double t0_s, double t1_s) const;
  /// Throws InputError naming `key` on a malformed table or non-finite times.
  void validate(const std::string& key) const;
};

/// Profile kind from its name ("constant", "sigmoid", "sinlin", "sharp", "table"); throws
/// InputError naming `key` on an unknown name.
ProfileKind profile_kind_from_name(const std::string& name, const std::string& key);
std::string profile_kind_name(ProfileKind kind);

/// A time table of full (n x n) matrices A(t) (stiffness or damping): piecewise-linear
/// interpolation of every entry between the knots, held constant outside (table_interpolate).
/// Entries in N m/rad, N m s/rad (joint space) or N/m, N s/m (endpoint). Empty = no table.
struct MatrixTable {
  std::vector<double> time_s;          ///< [P] strictly increasing knot times, s
  std::vector<Eigen::MatrixXd> value;  ///< [P] of (n x n) matrices at those times

  bool empty() const { return time_s.empty() && value.empty(); }
  int dimension() const { return value.empty() ? 0 : static_cast<int>(value.front().rows()); }
  /// A(t) (n x n) on the piece that holds at branch_s (see table_interpolate).
  Eigen::MatrixXd at(double t_s) const { return at(t_s, t_s); }
  Eigen::MatrixXd at(double t_s, double branch_s) const {
    return table_interpolate(time_s, value, t_s, branch_s);
  }
  /// Interior knots in (t0_s, t1_s), for the integrator to stop at.
  std::vector<double> breakpoints(double t0_s, double t1_s) const {
    return table_breakpoints(time_s, t0_s, t1_s);
  }
};

/// Where an element acts: joint space (N m/rad, N m s/rad, N m/rad^3) or endpoint space (N/m,
/// N s/m, N/m^3).
enum class Space { joint, endpoint };
/// Spec key of a matrix field with its unit suffix: field "stiffness", "damping",
/// "series_stiffness" or "cubic_stiffness" -> e.g. "stiffness_nm_per_rad" (joint) or
/// "stiffness_n_per_m" (endpoint).
std::string element_key(const std::string& field, Space space);

/// The mechanical networks of Piovesan Fig 2.
/// `none` is no element at all (a free limb, f = 0), for energy checks.
enum class ElementKind { kelvin_voigt, poynting_thomson, duffing, none };
ElementKind element_kind_from_name(const std::string& name, const std::string& key);
std::string element_kind_name(ElementKind kind);

/// A viscoelastic element about a reference trajectory q_ref(t) with deviation d = q - q_ref:
///   kelvin_voigt      f = -C(t) d' - K(t) d                                   (eq 15)
///   duffing           f = -C(t) d' - K(t) d - B d.^3  (elementwise cube)      (eq 17)
///   poynting_thomson  f = -K_S (d - z),  C_P(t) z' = K_S (d - z) - K_P(t) z   (eq 16)
/// where K(t) = stiffness * u_K(t), C(t) = R(nu) damping R(nu)^T * u_C(t) (eqs 53, 55; the rotation
/// only for n = 2), or, for Kelvin-Voigt and Duffing, K(t) = stiffness_table(t) and/or C(t) =
/// damping_table(t) (full matrices interpolated in time, for changes that are not a common
/// factor; a table replaces the matrix, its profile and, for damping, the rotation), and for
/// Poynting-Thomson K_P = stiffness (the fibre spring, parallel to C_P), C_P = damping, K_S =
/// series_stiffness (tendon) and z (n) is the internal state: the deviation of the fibre element.
/// Eliminating z gives eq 16 (with matrix products in place of the scalar ones). All matrices are
/// (n x n); units are N m/rad, N m s/rad, N m/rad^3 in joint space and N/m, N s/m, N/m^3 for an
/// endpoint model.
struct Viscoelasticity {
  ElementKind kind = ElementKind::kelvin_voigt;
  Eigen::MatrixXd stiffness;          ///< (n x n) K0 (KV, Duffing) or K_P (PT); empty with a table
  Eigen::MatrixXd damping;            ///< (n x n) C0 (KV, Duffing) or C_P (PT, must be invertible);
                                      ///< empty with a table
  Eigen::MatrixXd series_stiffness;   ///< (n x n) K_S (PT only, else empty)
  Eigen::MatrixXd cubic_stiffness;    ///< (n x n) B of eq 17 (Duffing only, else empty)
  TimeProfile stiffness_profile;      ///< u_K(t) multiplying stiffness (K0 or K_P)
  TimeProfile damping_profile;        ///< u_C(t) multiplying damping (C0 or C_P)
  double damping_rotation_rad = 0.0;  ///< nu of eq 55 (n = 2 only)
  MatrixTable stiffness_table;        ///< K(t) in place of stiffness * u_K(t) (KV, Duffing)
  MatrixTable damping_table;          ///< C(t) in place of R damping R^T * u_C(t) (KV, Duffing)

  int dimension() const {
    return stiffness.size() || stiffness_table.empty() ? static_cast<int>(stiffness.rows())
                                                       : stiffness_table.dimension();
  }
  /// Internal states carried by the integrator: n for Poynting-Thomson, else 0.
  int internal_states() const { return kind == ElementKind::poynting_thomson ? dimension() : 0; }
  /// Throws InputError naming the key under `key` (e.g. "viscoelasticity.stiffness_nm_per_rad")
  /// on a size mismatch, a non-finite entry, a stiffness that is not symmetric positive definite, a
  /// damping that is not symmetric positive semi-definite (positive definite for PT), a negative
  /// cubic diagonal; for a table (under KEY.stiffness_table / KEY.damping_table): the matrix or a
  /// non-constant profile (a rotation, for damping) given as well, an element other than KV or
  /// Duffing, times that are not finite and strictly increasing, a count of matrices that differs
  /// from the count of times, and every knot matrix as the constant one above.
  void validate(const std::string& key, Space space = Space::joint) const;
};

/// K(t) = stiffness * u_K(t) (or stiffness_table(t)), (n x n).
Eigen::MatrixXd stiffness_at(const Viscoelasticity& element, double t_s);
/// C(t) = R(nu) damping R(nu)^T * u_C(t), (n x n), eq 55 (or damping_table(t)).
Eigen::MatrixXd damping_at(const Viscoelasticity& element, double t_s);
/// The rotated damping matrix R(nu) C R(nu)^T of eq 55 (C is 2 x 2; nu in rad).
Eigen::Matrix2d rotate_damping(const Eigen::Matrix2d& damping, double nu_rad);

/// Generalized force of the element ON the limb, f (n), for deviation d (n), its rate d_dot (n)
/// and internal state z (n, PT only; empty otherwise), at time t_s. Eqs 15-17.
Eigen::VectorXd element_force(const Viscoelasticity& element, double t_s, const Eigen::VectorXd& d,
                              const Eigen::VectorXd& d_dot, const Eigen::VectorXd& z);
/// Rate of the internal state z' (n) of a Poynting-Thomson element (empty for the others).
Eigen::VectorXd element_internal_rate(const Viscoelasticity& element, double t_s,
                                      const Eigen::VectorXd& d, const Eigen::VectorXd& z);

/// Piovesan's nominal joint viscoelasticity: K0 = [35 5; 5 20] N m/rad, C0 = 0.01 K0 N m s/rad
/// (eq 52), both profiles `constant` starting at 2.5 s with T = 5 s.
Viscoelasticity piovesan_kelvin_voigt();
/// Piovesan's Duffing element: K0, C0 of eq 52 and B = 2e5 K0 N m/rad^3 (text after eq 55).
Viscoelasticity piovesan_duffing();
/// Piovesan's Poynting-Thomson element (eq 56): K_P = 2 K0, K_S = 5 K_P, C_P = |K0| (elementwise)
/// N m s/rad.
Viscoelasticity piovesan_poynting_thomson();

}  // namespace stiffid::models
