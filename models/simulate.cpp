#include "models/simulate.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "models/integrate.hpp"
#include "models/linear_endpoint.hpp"

namespace stiffid::models {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;

// ---------------------------------------------------------------------------------------------
// Element evaluation with fixed-size matrices (N = 2 for the arm, Dynamic for endpoint models):
// the hot loop of the integrator must not allocate.
template <int N>
struct ElementEval {
  using Mat = Eigen::Matrix<double, N, N>;
  using Vec = Eigen::Matrix<double, N, 1>;
  ElementKind kind = ElementKind::none;
  Mat k0, c0, ks, cubic, c0_inverse;
  const TimeProfile* stiffness_profile = nullptr;
  const TimeProfile* damping_profile = nullptr;
  // Matrix tables (KV, Duffing) as fixed-size knots; interpolated by table_interpolate, the same
  // code as the scalar table profile.
  const std::vector<double>* stiffness_times = nullptr;
  const std::vector<double>* damping_times = nullptr;
  std::vector<Mat> stiffness_knots, damping_knots;

  explicit ElementEval(const Viscoelasticity& e)
      : kind(e.kind), stiffness_profile(&e.stiffness_profile), damping_profile(&e.damping_profile) {
    const int n = e.dimension();
    k0 = e.stiffness.size() ? Mat(e.stiffness) : Mat(Mat::Zero(n, n));
    c0 = e.damping.size() == 0 ? Mat(Mat::Zero(n, n))
         : e.damping_rotation_rad != 0.0 && n == 2
             ? Mat(Eigen::MatrixXd(rotate_damping(e.damping, e.damping_rotation_rad)))
             : Mat(e.damping);
    if (!e.stiffness_table.empty()) {
      stiffness_times = &e.stiffness_table.time_s;
      for (const Eigen::MatrixXd& m : e.stiffness_table.value) stiffness_knots.emplace_back(m);
    }
    if (!e.damping_table.empty()) {
      damping_times = &e.damping_table.time_s;
      for (const Eigen::MatrixXd& m : e.damping_table.value) damping_knots.emplace_back(m);
    }
    ks = e.kind == ElementKind::poynting_thomson ? Mat(e.series_stiffness) : Mat(Mat::Zero(n, n));
    cubic = e.kind == ElementKind::duffing ? Mat(e.cubic_stiffness) : Mat(Mat::Zero(n, n));
    c0_inverse = e.kind == ElementKind::poynting_thomson ? Mat(c0.inverse()) : Mat(Mat::Zero(n, n));
  }

  // K(t) d and C(t) d' of eqs 15, 17: the profile times the constant matrix, or the table.
  template <class V>
  Vec stiffness_term(double t, double branch, const V& d) const {
    if (stiffness_times) return table_interpolate(*stiffness_times, stiffness_knots, t, branch) * d;
    return stiffness_profile->value(t, branch) * (k0 * d);
  }
  template <class V>
  Vec damping_term(double t, double branch, const V& dd) const {
    if (damping_times) return table_interpolate(*damping_times, damping_knots, t, branch) * dd;
    return damping_profile->value(t, branch) * (c0 * dd);
  }

  // Force on the limb (eqs 15-17) for deviation d, rate dd, internal state z.
  template <class V>
  Vec force(double t, double branch, const V& d, const V& dd, const V& z) const {
    switch (kind) {
      case ElementKind::none:
        return Vec::Zero(d.size());
      case ElementKind::kelvin_voigt:
        return -damping_term(t, branch, dd) - stiffness_term(t, branch, d);
      case ElementKind::duffing:
        return -damping_term(t, branch, dd) - stiffness_term(t, branch, d) -
               cubic * d.array().cube().matrix();
      case ElementKind::poynting_thomson:
        return -(ks * (d - z));
    }
    return Vec::Zero(d.size());
  }
  // z' of the Poynting-Thomson element (no tables): C_P(t) z' = K_S (d - z) - K_P(t) z.
  template <class V>
  Vec internal_rate(double t, double branch, const V& d, const V& z) const {
    const Vec drive = ks * (d - z) - stiffness_profile->value(t, branch) * (k0 * z);
    return c0_inverse * drive / damping_profile->value(t, branch);
  }
};

// ---------------------------------------------------------------------------------------------
// Piecewise definition of the applied force. Inside one integration segment every piece is
// smooth; the segment's midpoint ("branch") selects the pieces, continued past the segment's ends
// so that the integrator sees a smooth right-hand side (see integrate.hpp).
struct Forcing {
  int forces = 2;  // force components
  std::vector<ForcePulse> pulses;
  std::vector<DisplacementRamp> ramps;
  Eigen::MatrixXd random;  // (S x forces) or empty
  InputHold hold = InputHold::first_order;
  double sample_rate_hz = 1.0;

  // Open-loop force (pulses + random), N.
  Eigen::VectorXd open_loop(double t, double branch) const {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(forces);
    add_open_loop(t, branch, f);
    return f;
  }
  template <class V>
  void add_open_loop(double t, double branch, V& f) const {
    for (const ForcePulse& p : pulses) {
      if (branch >= p.onset_s && branch < p.onset_s + p.duration_s) {
        f(0) += p.amplitude_n * std::cos(p.direction_rad);
        if (forces > 1) f(1) += p.amplitude_n * std::sin(p.direction_rad);
      }
    }
    if (random.rows() > 0) {
      const Eigen::Index last = random.rows() - 1;
      const Eigen::Index k =
          std::clamp<Eigen::Index>(static_cast<Eigen::Index>(std::floor(branch * sample_rate_hz)),
                                   0, std::max<Eigen::Index>(last - 1, 0));
      const Eigen::Index k1 = std::min(k + 1, last);
      const double w =
          hold == InputHold::first_order ? t * sample_rate_hz - static_cast<double>(k) : 0.0;
      for (int i = 0; i < forces; ++i) f(i) += (1.0 - w) * random(k, i) + w * random(k1, i);
    }
  }
  // Active ramp at `branch` (nullptr when none) and its piecewise-linear target offset, m.
  const DisplacementRamp* active_ramp(double branch) const {
    for (const DisplacementRamp& r : ramps) {
      if (branch >= r.onset_s && branch < r.end_s()) return &r;
    }
    return nullptr;
  }
  static void ramp_offset(const DisplacementRamp& r, double t, double branch, Eigen::Vector2d& p,
                          Eigen::Vector2d& p_dot) {
    const Eigen::Vector2d rate = r.offset_rate_m_per_s(branch);
    p = r.offset_m(branch) + rate * (t - branch);
    p_dot = rate;
  }
  std::vector<double> breakpoints(double t_end) const {
    std::vector<double> out;
    auto add = [&](double t) {
      if (t > 0.0 && t < t_end) out.push_back(t);
    };
    for (const ForcePulse& p : pulses) {
      add(p.onset_s);
      add(p.onset_s + p.duration_s);
    }
    for (const DisplacementRamp& r : ramps) {
      add(r.onset_s);
      add(r.onset_s + r.ramp_s);
      add(r.onset_s + r.ramp_s + r.plateau_s);
      add(r.end_s());
    }
    return out;
  }
};

std::vector<double> segment_bounds(double t_end, std::vector<double> inner, bool every_sample,
                                   int samples, double rate) {
  // A breakpoint that is a sample time up to round-off (0.1 + 0.02 vs 120 / 1000) is snapped onto
  // it, so that the sample unambiguously belongs to the segment that starts there.
  for (double& t : inner) {
    const double k = std::round(t * rate);
    if (std::abs(t * rate - k) < 1e-6) t = k / rate;
  }
  if (every_sample) {
    for (int k = 1; k < samples - 1; ++k) inner.push_back(k / rate);
  }
  inner.push_back(0.0);
  inner.push_back(t_end);
  std::sort(inner.begin(), inner.end());
  std::vector<double> out;
  for (double t : inner) {
    // Merge breakpoints closer than a femtosecond-scale gap: they would make empty segments.
    if (out.empty() || t - out.back() > 1e-12 * std::max(1.0, t_end)) out.push_back(t);
  }
  if (out.back() < t_end) out.back() = t_end;
  return out;
}

// ---------------------------------------------------------------------------------------------
// Arm dynamics in deviation coordinates d = theta - theta_ref (exact, not linearized):
//   M(theta) d'' = (M(theta_ref) - M(theta)) theta_ref'' + H(theta_ref, theta_ref') theta_ref'
//                  - H(theta, theta') theta' + f_visc(d, d', t) + J(theta)^T F(t, x, x')
// which is eq 8 with tau_in = tau_ff + f_visc and tau_ext = J^T F; it is zero at d = 0 without
// perturbation, so the unperturbed trajectory is exact. State: [d(2), d'(2), z(2)].
using ArmState = std::array<double, 6>;

// cos and sin of a + d from those of a, with d a small deviation: for |d| <= 1/16 rad the Taylor
// polynomials (sin to d^9, cos to d^10; remainders below 1e-20 relative) replace the library
// calls, which dominated the arm's right-hand side; larger d takes std::cos/std::sin of a + d.
void cos_sin_of_sum(double a, double cos_a, double sin_a, double d, double& cos_out,
                    double& sin_out) {
  if (!(std::abs(d) <= 0.0625)) {
    cos_out = std::cos(a + d);
    sin_out = std::sin(a + d);
    return;
  }
  // Horner forms with the reciprocals as constants (a division per term would dominate).
  constexpr double k6 = 1.0 / 6.0, k20 = 1.0 / 20.0, k42 = 1.0 / 42.0, k72 = 1.0 / 72.0;
  constexpr double k2 = 1.0 / 2.0, k12 = 1.0 / 12.0, k30 = 1.0 / 30.0, k56 = 1.0 / 56.0;
  constexpr double k90 = 1.0 / 90.0;
  const double d2 = d * d;
  const double sin_d = d * (1.0 - d2 * k6 * (1.0 - d2 * k20 * (1.0 - d2 * k42 * (1.0 - d2 * k72))));
  const double cos_d =
      1.0 - d2 * k2 * (1.0 - d2 * k12 * (1.0 - d2 * k30 * (1.0 - d2 * k56 * (1.0 - d2 * k90))));
  cos_out = cos_a * cos_d - sin_a * sin_d;
  sin_out = sin_a * cos_d + cos_a * sin_d;
}

struct ArmSystem {
  const ArmParameters* arm;
  const ArmTask* task;
  double duration_s;
  ElementEval<2> element;
  const Forcing* forcing;
  bool posture;
  ReferencePoint fixed_reference;
  double branch = 0.0;
  long* evaluations;
  InertiaConstants inertia;                     // of *arm, eq 9
  Eigen::Vector2d fixed_reference_torque;       // reference_torque(fixed_reference), N m
  Eigen::Array2d reference_cos, reference_sin;  // of fixed_reference.theta_rad

  ReferencePoint reference(double t) const {
    return posture ? fixed_reference : arm_reference(*arm, *task, duration_s, t);
  }

  // Force applied to the hand, N, given the reference and the actual hand state.
  Eigen::Vector2d hand_force(double t, const ReferencePoint& ref, const Eigen::Vector2d& theta,
                             const Eigen::Vector2d& theta_dot) const {
    Eigen::Vector2d f = Eigen::Vector2d::Zero();
    forcing->add_open_loop(t, branch, f);
    if (const DisplacementRamp* r = forcing->active_ramp(branch)) {
      Eigen::Vector2d p, p_dot;
      Forcing::ramp_offset(*r, t, branch, p, p_dot);
      const Eigen::Vector2d x = hand_position(*arm, theta);
      const Eigen::Vector2d x_dot = jacobian(*arm, theta) * theta_dot;
      f += r->servo_stiffness_n_per_m * (ref.hand_m + p - x) +
           r->servo_damping_ns_per_m * (ref.hand_velocity_m_per_s + p_dot - x_dot);
    }
    return f;
  }

  // Reference-side torque M(theta_ref) theta_ref'' + H(theta_ref, theta_ref') theta_ref', N m: the
  // feedforward that keeps the unperturbed arm on its path; constant (zero) at a posture.
  Eigen::Vector2d reference_torque(const ReferencePoint& ref) const {
    return inertia_matrix(*arm, ref.theta_rad) * ref.theta_ddot_rad_per_s2 +
           coriolis_matrix(*arm, ref.theta_rad, ref.theta_dot_rad_per_s) * ref.theta_dot_rad_per_s;
  }

  // Each trigonometric function of the actual angles is evaluated once per call (M, H and J share
  // them; this is the simulator's inner loop; at a posture from the fixed reference's by the sum
  // formulas), and the posture's reference torque once per trial.
  void operator()(const ArmState& s, ArmState& ds, double t) const {
    ++*evaluations;
    const ReferencePoint ref = reference(t);
    const Eigen::Vector2d d(s[0], s[1]), dd(s[2], s[3]), z(s[4], s[5]);
    const Eigen::Vector2d theta = ref.theta_rad + d;
    const Eigen::Vector2d theta_dot = ref.theta_dot_rad_per_s + dd;
    double c1, s1, c2, s2;
    if (posture) {  // theta = theta_ref + d with theta_ref fixed: cos/sin of the sums
      cos_sin_of_sum(ref.theta_rad(0), reference_cos(0), reference_sin(0), d(0), c1, s1);
      cos_sin_of_sum(ref.theta_rad(1), reference_cos(1), reference_sin(1), d(1), c2, s2);
    } else {
      c1 = std::cos(theta(0));
      s1 = std::sin(theta(0));
      c2 = std::cos(theta(1));
      s2 = std::sin(theta(1));
    }
    Eigen::Matrix2d m;  // eq 9
    m << inertia.kappa + 2.0 * inertia.beta * c2, inertia.chi + inertia.beta * c2,
        inertia.chi + inertia.beta * c2, inertia.chi;
    const double bs2 = inertia.beta * s2;  // H(theta, theta') theta', eq 9
    const Eigen::Vector2d coriolis(-bs2 * (2.0 * theta_dot(0) + theta_dot(1)) * theta_dot(1),
                                   bs2 * theta_dot(0) * theta_dot(0));
    Eigen::Vector2d rhs = (posture ? fixed_reference_torque : reference_torque(ref)) -
                          m * ref.theta_ddot_rad_per_s2 - coriolis +
                          element.force(t, branch, d, dd, z);
    if (forcing->pulses.size() + forcing->ramps.size() > 0 || forcing->random.rows() > 0) {
      const double s12 = s1 * c2 + c1 * s2, c12 = c1 * c2 - s1 * s2;
      Eigen::Matrix2d j;  // hand Jacobian
      j << -arm->l1_m * s1 - arm->l2_m * s12, -arm->l2_m * s12, arm->l1_m * c1 + arm->l2_m * c12,
          arm->l2_m * c12;
      rhs += j.transpose() * hand_force(t, ref, theta, theta_dot);
    }
    // M is symmetric positive definite (checked by TrialSpec::validate): Cramer's rule.
    const double inverse_det = 1.0 / (m(0, 0) * m(1, 1) - m(0, 1) * m(0, 1));
    ds[0] = dd(0);
    ds[1] = dd(1);
    ds[2] = (m(1, 1) * rhs(0) - m(0, 1) * rhs(1)) * inverse_det;
    ds[3] = (m(0, 0) * rhs(1) - m(0, 1) * rhs(0)) * inverse_det;
    if (element.kind == ElementKind::poynting_thomson) {
      const Eigen::Vector2d zr = element.internal_rate(t, branch, d, z);
      ds[4] = zr(0);
      ds[5] = zr(1);
    } else {
      ds[4] = ds[5] = 0.0;
    }
  }
};

// Lumped endpoint model: I x'' = f_visc(x, x', t) + F(t). State: [x(n), x'(n), z(n)].
struct EndpointSystem {
  Eigen::MatrixXd inertia_inverse;
  ElementEval<Eigen::Dynamic> element;
  const Forcing* forcing;
  int n;
  double branch = 0.0;
  long* evaluations;

  Eigen::VectorXd applied_force(double t, const Eigen::VectorXd& x,
                                const Eigen::VectorXd& v) const {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(n);
    forcing->add_open_loop(t, branch, f);
    if (const DisplacementRamp* r = forcing->active_ramp(branch)) {
      Eigen::Vector2d p, p_dot;
      Forcing::ramp_offset(*r, t, branch, p, p_dot);
      for (int i = 0; i < std::min(n, 2); ++i) {
        f(i) += r->servo_stiffness_n_per_m * (p(i) - x(i)) +
                r->servo_damping_ns_per_m * (p_dot(i) - v(i));
      }
    }
    return f;
  }

  void operator()(const std::vector<double>& s, std::vector<double>& ds, double t) const {
    ++*evaluations;
    const Eigen::Map<const Eigen::VectorXd> x(s.data(), n), v(s.data() + n, n);
    const Eigen::VectorXd z =
        element.kind == ElementKind::poynting_thomson
            ? Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(s.data() + 2 * n, n))
            : Eigen::VectorXd::Zero(n);
    const Eigen::VectorXd acc =
        inertia_inverse * (element.force(t, branch, Eigen::VectorXd(x), Eigen::VectorXd(v), z) +
                           applied_force(t, x, v));
    for (int i = 0; i < n; ++i) {
      ds[i] = v(i);
      ds[n + i] = acc(i);
    }
    if (element.kind == ElementKind::poynting_thomson) {
      const Eigen::VectorXd zr = element.internal_rate(t, branch, Eigen::VectorXd(x), z);
      for (int i = 0; i < n; ++i) ds[2 * n + i] = zr(i);
    }
  }
};

std::vector<std::string> endpoint_axis_names(int n, const std::string& force_prefix, bool force) {
  static const char* axes[] = {"x", "y", "z"};
  std::vector<std::string> names;
  for (int i = 0; i < n; ++i) {
    if (n <= 3) {
      names.push_back(force ? force_prefix + axes[i] : std::string(axes[i]));
    } else {
      names.push_back((force ? force_prefix : std::string("x")) + std::to_string(i + 1));
    }
  }
  return names;
}

double rms(const Eigen::VectorXd& v) {
  return v.size() ? std::sqrt(v.squaredNorm() / static_cast<double>(v.size())) : 0.0;
}

// Draws the measurement noise (S x outputs) for deviations `signal` (S x outputs), in the order
// channel by channel, sample by sample (constant draw then SDN draw).
Eigen::MatrixXd draw_noise(const NoiseOptions& noise, const Eigen::MatrixXd& signal,
                           const Eigen::VectorXd& profile, Truth& truth, std::mt19937_64& rng) {
  const Eigen::Index samples = signal.rows(), outputs = signal.cols();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(samples, outputs);
  truth.noise_sigma = Eigen::VectorXd::Zero(outputs);
  const bool constant = std::isfinite(noise.snr_db);
  if (!constant && !noise.signal_dependent) return out;
  std::normal_distribution<double> normal(0.0, 1.0);
  const double profile_max = profile.size() ? profile.cwiseAbs().maxCoeff() : 0.0;
  for (Eigen::Index c = 0; c < outputs; ++c) {
    const double level = rms(signal.col(c));
    const double sigma = constant ? level / std::pow(10.0, noise.snr_db / 20.0) : 0.0;
    const double sdn = noise.signal_dependent && profile_max > 0.0
                           ? level / std::pow(10.0, noise.sdn_max_snr_db / 20.0)
                           : 0.0;
    truth.noise_sigma(c) = sigma;
    truth.sdn_max_sigma = std::max(truth.sdn_max_sigma, sdn);
    for (Eigen::Index s = 0; s < samples; ++s) {
      double e = 0.0;
      if (constant) e += sigma * normal(rng);
      if (noise.signal_dependent)
        e += sdn * std::abs(profile(s)) / std::max(profile_max, 1e-300) * normal(rng);
      out(s, c) = e;
    }
  }
  return out;
}

void fill_matrix_row(Eigen::MatrixXd& series, Eigen::Index row, const Eigen::MatrixXd& m) {
  const Eigen::Index n = m.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) series(row, i * n + j) = m(i, j);
  }
}

// Row-major flattening of a square matrix, as one row of a Truth matrix series.
Eigen::RowVectorXd flatten(const Eigen::MatrixXd& m) {
  Eigen::RowVectorXd out(m.size());
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    for (Eigen::Index j = 0; j < m.cols(); ++j) out(i * m.cols() + j) = m(i, j);
  }
  return out;
}

// Fills the element truth (K(t), C(t), u_K, u_C) at the sample times: the profile times the
// constant matrix, or the interpolated table (u = 1 then: a table has no profile).
void fill_element_truth(const Viscoelasticity& e, Truth& truth) {
  const Eigen::Index samples = truth.time_s.size();
  const int n = e.dimension();
  const bool none = e.kind == ElementKind::none;
  truth.stiffness_profile.resize(samples);
  truth.damping_profile.resize(samples);
  for (Eigen::Index s = 0; s < samples; ++s) {
    const double t = truth.time_s(s);
    truth.stiffness_profile(s) = none ? 0.0 : e.stiffness_profile.value(t);
    truth.damping_profile(s) = none ? 0.0 : e.damping_profile.value(t);
  }
  auto table_series = [&](const MatrixTable& table) {
    Eigen::MatrixXd series(samples, n * n);
    for (Eigen::Index s = 0; s < samples; ++s) {
      fill_matrix_row(series, s, table.at(truth.time_s(s)));
    }
    return series;
  };
  if (e.stiffness_table.empty()) {
    truth.stiffness = truth.stiffness_profile * flatten(e.stiffness);
  } else {
    truth.stiffness = table_series(e.stiffness_table);
  }
  if (e.damping_table.empty()) {
    const Eigen::MatrixXd c_rot =
        e.damping_rotation_rad != 0.0 && n == 2
            ? Eigen::MatrixXd(rotate_damping(e.damping, e.damping_rotation_rad))
            : e.damping;
    truth.damping = truth.damping_profile * flatten(c_rot);
  } else {
    truth.damping = table_series(e.damping_table);
  }
  if (e.kind == ElementKind::poynting_thomson) truth.series_stiffness = e.series_stiffness;
  if (e.kind == ElementKind::duffing) truth.cubic_stiffness = e.cubic_stiffness;
}

Forcing make_forcing(const TrialSpec& spec, int forces, int samples, std::mt19937_64& rng,
                     Truth& truth) {
  Forcing forcing;
  forcing.forces = forces;
  forcing.sample_rate_hz = spec.sample_rate_hz;
  forcing.hold = spec.perturbations.random_force.hold;
  if (spec.perturbations.random) {
    forcing.random =
        random_forces(spec.perturbations.random_force, samples, forces, spec.sample_rate_hz, rng);
  }
  std::uniform_int_distribution<int> octant(0, 7);
  forcing.pulses = spec.perturbations.pulses;
  for (ForcePulse& p : forcing.pulses) {
    if (p.random_octant) {
      p.direction_rad = octant_direction_rad(octant(rng));
      p.random_octant = false;
    }
  }
  forcing.ramps = spec.perturbations.ramps;
  for (DisplacementRamp& r : forcing.ramps) {
    if (r.random_octant) {
      r.direction_rad = octant_direction_rad(octant(rng));
      r.random_octant = false;
    }
  }
  truth.pulses = forcing.pulses;
  truth.ramps = forcing.ramps;
  return forcing;
}

std::vector<double> all_breakpoints(const TrialSpec& spec, const Viscoelasticity& e,
                                    const Forcing& forcing, double t_end) {
  std::vector<double> inner = forcing.breakpoints(t_end);
  for (double t : e.stiffness_profile.breakpoints(0.0, t_end)) inner.push_back(t);
  for (double t : e.damping_profile.breakpoints(0.0, t_end)) inner.push_back(t);
  for (double t : e.stiffness_table.breakpoints(0.0, t_end)) inner.push_back(t);
  for (double t : e.damping_table.breakpoints(0.0, t_end)) inner.push_back(t);
  (void)spec;
  return inner;
}

// ---------------------------------------------------------------------------------------------
SimulationResult simulate_arm(const TrialSpec& spec, std::mt19937_64& rng) {
  SimulationResult result;
  Truth& truth = result.truth;
  const int samples = static_cast<int>(std::lround(spec.duration_s * spec.sample_rate_hz));
  const double rate = spec.sample_rate_hz;
  const double t_end = (samples - 1) / rate;
  truth.model = ModelKind::arm;
  truth.dimension = 2;
  truth.time_s = Eigen::VectorXd::LinSpaced(samples, 0.0, t_end);
  for (int s = 0; s < samples; ++s) truth.time_s(s) = s / rate;

  const Forcing forcing = make_forcing(spec, 2, samples, rng, truth);
  ArmSystem system{&spec.arm,
                   &spec.task,
                   spec.duration_s,
                   ElementEval<2>(spec.joint),
                   &forcing,
                   spec.task.kind == TaskKind::posture,
                   {},
                   0.0,
                   &result.rhs_evaluations,
                   inertia_constants(spec.arm),
                   Eigen::Vector2d::Zero(),
                   {},
                   {}};
  system.fixed_reference = arm_reference(spec.arm, spec.task, spec.duration_s, 0.0);
  system.fixed_reference_torque = system.reference_torque(system.fixed_reference);
  system.reference_cos = system.fixed_reference.theta_rad.array().cos();
  system.reference_sin = system.fixed_reference.theta_rad.array().sin();

  ArmState x0{};
  for (int i = 0; i < 2; ++i) {
    if (spec.initial_deviation.size() == 2) x0[i] = spec.initial_deviation(i);
    if (spec.initial_deviation_rate.size() == 2) x0[2 + i] = spec.initial_deviation_rate(i);
  }
  const std::vector<double> bounds =
      segment_bounds(t_end, all_breakpoints(spec, spec.joint, forcing, t_end),
                     forcing.random.rows() > 0, samples, rate);

  Eigen::MatrixXd states(samples, 6);
  Eigen::MatrixXd force(samples, 2);
  auto record = [&](int s, const ArmState& x, double branch) {
    for (int i = 0; i < 6; ++i) states(s, i) = x[i];
    const double t = truth.time_s(s);
    const ReferencePoint ref = system.reference(t);
    const Eigen::Vector2d theta = ref.theta_rad + Eigen::Vector2d(x[0], x[1]);
    const Eigen::Vector2d theta_dot = ref.theta_dot_rad_per_s + Eigen::Vector2d(x[2], x[3]);
    const double saved = system.branch;
    system.branch = branch;
    force.row(s) = system.hand_force(t, ref, theta, theta_dot).transpose();
    system.branch = saved;
  };
  IntegratorKind method = spec.integrator.kind;
  if (method == IntegratorKind::exact) {
    throw InputError(spec.source + (spec.source.empty() ? "" : ": ") +
                     "integrator.method: \"exact\" applies to linear endpoint models only");
  }
  if (method == IntegratorKind::automatic) method = IntegratorKind::adaptive;
  result.integrator = method;
  result.status = integrate_segments(method, system, x0, bounds, truth.time_s, spec.integrator,
                                     record, result.steps);
  if (!result.status.ok) return result;

  // Truth time series.
  truth.position.resize(samples, 2);
  truth.velocity.resize(samples, 2);
  truth.reference_position.resize(samples, 2);
  truth.reference_velocity.resize(samples, 2);
  truth.hand_position_m.resize(samples, 2);
  truth.reference_hand_position_m.resize(samples, 2);
  truth.inertia.resize(samples, 4);
  for (int s = 0; s < samples; ++s) {
    const ReferencePoint ref = system.reference(truth.time_s(s));
    const Eigen::Vector2d theta = ref.theta_rad + states.block<1, 2>(s, 0).transpose();
    truth.position.row(s) = theta.transpose();
    truth.velocity.row(s) =
        (ref.theta_dot_rad_per_s + states.block<1, 2>(s, 2).transpose()).transpose();
    truth.reference_position.row(s) = ref.theta_rad.transpose();
    truth.reference_velocity.row(s) = ref.theta_dot_rad_per_s.transpose();
    truth.hand_position_m.row(s) = hand_position(spec.arm, theta).transpose();
    truth.reference_hand_position_m.row(s) = ref.hand_m.transpose();
    fill_matrix_row(truth.inertia, s, inertia_matrix(spec.arm, theta));
  }
  if (spec.joint.kind == ElementKind::poynting_thomson) truth.internal_state = states.rightCols(2);
  truth.applied_force_n = force;
  fill_element_truth(spec.joint, truth);

  // Measurement: noisy hand position, angles from it by inverse kinematics.
  const Eigen::MatrixXd hand_deviation = truth.hand_position_m - truth.reference_hand_position_m;
  const Eigen::MatrixXd noise =
      draw_noise(spec.noise, hand_deviation, truth.stiffness_profile, truth, rng);
  const bool noisy = std::isfinite(spec.noise.snr_db) || spec.noise.signal_dependent;
  Eigen::MatrixXd hand = truth.hand_position_m + noise;
  Eigen::MatrixXd angles = truth.position;
  if (noisy) {
    for (int s = 0; s < samples; ++s) {
      Eigen::Vector2d th = inverse_kinematics(spec.arm, hand.row(s).transpose(), "noisy hand");
      th(0) += kTwoPi * std::round((truth.position(s, 0) - th(0)) / kTwoPi);
      if (truth.position(s, 1) < 0.0) {  // the arm is on the other elbow branch
        th(1) = -th(1);
        th(0) = std::atan2(hand(s, 1), hand(s, 0)) -
                std::atan2(spec.arm.l2_m * std::sin(th(1)),
                           spec.arm.l1_m + spec.arm.l2_m * std::cos(th(1)));
        th(0) += kTwoPi * std::round((truth.position(s, 0) - th(0)) / kTwoPi);
      }
      angles.row(s) = th.transpose();
    }
  }
  data::Trial& trial = result.trial;
  trial.sample_rate_hz = rate;
  trial.source = spec.source;
  trial.names = {"fx", "fy", "th1", "th2", "x", "y", "dth1", "dth2", "dx", "dy"};
  trial.units = {"N", "N", "rad", "rad", "m", "m", "rad", "rad", "m", "m"};
  trial.samples.resize(samples, 10);
  trial.samples << force, angles, hand, angles - truth.reference_position,
      hand - truth.reference_hand_position_m;
  return result;
}

bool is_linear_time_invariant(const TrialSpec& spec) {
  const Viscoelasticity& e = spec.endpoint.element;
  return (e.kind == ElementKind::kelvin_voigt || e.kind == ElementKind::none) &&
         (e.kind == ElementKind::none || (e.stiffness_profile.kind == ProfileKind::constant &&
                                          e.damping_profile.kind == ProfileKind::constant &&
                                          e.stiffness_table.empty() && e.damping_table.empty())) &&
         spec.perturbations.pulses.empty() && spec.perturbations.ramps.empty();
}

SimulationResult simulate_endpoint(const TrialSpec& spec, std::mt19937_64& rng) {
  SimulationResult result;
  Truth& truth = result.truth;
  const int n = spec.dimension();
  const int samples = static_cast<int>(std::lround(spec.duration_s * spec.sample_rate_hz));
  const double rate = spec.sample_rate_hz;
  const double t_end = (samples - 1) / rate;
  truth.model = ModelKind::endpoint;
  truth.dimension = n;
  truth.time_s.resize(samples);
  for (int s = 0; s < samples; ++s) truth.time_s(s) = s / rate;
  const Forcing forcing = make_forcing(spec, n, samples, rng, truth);
  const Viscoelasticity& e = spec.endpoint.element;

  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(n), v0 = Eigen::VectorXd::Zero(n);
  if (spec.initial_deviation.size() == n) x0 = spec.initial_deviation;
  if (spec.initial_deviation_rate.size() == n) v0 = spec.initial_deviation_rate;

  Eigen::MatrixXd position(samples, n), velocity(samples, n), force(samples, n);
  Eigen::MatrixXd internal;
  IntegratorKind method = spec.integrator.kind;
  const bool lti = is_linear_time_invariant(spec);
  if (method == IntegratorKind::automatic) {
    method = lti ? IntegratorKind::exact : IntegratorKind::adaptive;
  }
  result.integrator = method;
  if (method == IntegratorKind::exact) {
    if (!lti) {
      throw InputError(spec.source + ": integrator.method: \"exact\" needs a linear " +
                       "time-invariant endpoint model (kelvin_voigt, constant profiles, no " +
                       "tables) driven by random forces only");
    }
    const Eigen::MatrixXd k =
        e.kind == ElementKind::none ? Eigen::MatrixXd::Zero(n, n) : e.stiffness;
    const Eigen::MatrixXd c =
        e.kind == ElementKind::none ? Eigen::MatrixXd::Zero(n, n) : damping_at(e, 0.0);
    const Eigen::MatrixXd u =
        forcing.random.rows() ? forcing.random : Eigen::MatrixXd::Zero(samples, n);
    const LinearResponse r =
        simulate_linear_endpoint(spec.endpoint.inertia_kg, c, k, u, rate, forcing.hold, x0, v0);
    position = r.position;
    velocity = r.velocity;
    force = u;
  } else {
    long evaluations = 0;
    EndpointSystem system{spec.endpoint.inertia_kg.inverse(),
                          ElementEval<Eigen::Dynamic>(e),
                          &forcing,
                          n,
                          0.0,
                          &evaluations};
    const int states = e.kind == ElementKind::poynting_thomson ? 3 * n : 2 * n;
    std::vector<double> x(states, 0.0);
    for (int i = 0; i < n; ++i) {
      x[i] = x0(i);
      x[n + i] = v0(i);
    }
    if (e.kind == ElementKind::poynting_thomson) internal.resize(samples, n);
    const std::vector<double> bounds = segment_bounds(
        t_end, all_breakpoints(spec, e, forcing, t_end), forcing.random.rows() > 0, samples, rate);
    auto record = [&](int s, const std::vector<double>& st, double branch) {
      const Eigen::Map<const Eigen::VectorXd> xs(st.data(), n), vs(st.data() + n, n);
      position.row(s) = xs.transpose();
      velocity.row(s) = vs.transpose();
      if (internal.size()) {
        internal.row(s) = Eigen::Map<const Eigen::VectorXd>(st.data() + 2 * n, n).transpose();
      }
      const double saved = system.branch;
      system.branch = branch;
      force.row(s) = system.applied_force(truth.time_s(s), xs, vs).transpose();
      system.branch = saved;
    };
    result.status = integrate_segments(method, system, x, bounds, truth.time_s, spec.integrator,
                                       record, result.steps);
    result.rhs_evaluations = evaluations;
    if (!result.status.ok) return result;
  }
  truth.position = position;
  truth.velocity = velocity;
  truth.reference_position = Eigen::MatrixXd::Zero(samples, n);
  truth.reference_velocity = Eigen::MatrixXd::Zero(samples, n);
  truth.internal_state = internal;
  truth.applied_force_n = force;
  truth.inertia = Eigen::VectorXd::Ones(samples) * flatten(spec.endpoint.inertia_kg);
  fill_element_truth(e, truth);

  const Eigen::MatrixXd noise =
      draw_noise(spec.noise, position, truth.stiffness_profile, truth, rng);
  const Eigen::MatrixXd measured = position + noise;
  data::Trial& trial = result.trial;
  trial.sample_rate_hz = rate;
  trial.source = spec.source;
  trial.names = endpoint_axis_names(n, "f", true);
  for (const std::string& name : endpoint_axis_names(n, "", false)) trial.names.push_back(name);
  trial.units.assign(n, "N");
  trial.units.resize(2 * n, "m");
  trial.samples.resize(samples, 2 * n);
  trial.samples << force, measured;
  return result;
}

}  // namespace

// -----------------------------------------------------------------------------------------------

ReferencePoint arm_reference(const ArmParameters& arm, const ArmTask& task, double duration_s,
                             double t_s) {
  ReferencePoint r;
  if (task.kind == TaskKind::posture) {
    r.theta_rad = task.posture_by_angles
                      ? task.posture_joint_rad
                      : inverse_kinematics(arm, task.posture_hand_m, "task.hand_m");
    r.hand_m = hand_position(arm, r.theta_rad);
    if (!task.posture_by_angles) r.hand_m = task.posture_hand_m;
    r.hand_velocity_m_per_s.setZero();
    r.hand_acceleration_m_per_s2.setZero();
    r.theta_dot_rad_per_s.setZero();
    r.theta_ddot_rad_per_s2.setZero();
    return r;
  }
  // Eqs 50-51: s(t) = 1 / (1 + Q exp(-B (t - E))), s' = B s (1 - s), s'' = B s' (1 - 2 s).
  const double midpoint =
      std::isnan(task.reach_midpoint_s) ? 0.5 * duration_s : task.reach_midpoint_s;
  const double b = task.reach_rate_per_s;
  const double s = 1.0 / (1.0 + task.reach_q * std::exp(-b * (t_s - midpoint)));
  const double s_dot = b * s * (1.0 - s);
  const double s_ddot = b * s_dot * (1.0 - 2.0 * s);
  const Eigen::Vector2d g = task.reach_target_m - task.reach_start_m;
  r.hand_m = task.reach_start_m + s * g;
  r.hand_velocity_m_per_s = s_dot * g;
  r.hand_acceleration_m_per_s2 = s_ddot * g;
  r.theta_rad = inverse_kinematics(arm, r.hand_m, "task (reach)");
  const Eigen::Matrix2d j = jacobian(arm, r.theta_rad);
  const Eigen::PartialPivLU<Eigen::Matrix2d> lu(j);
  r.theta_dot_rad_per_s = lu.solve(r.hand_velocity_m_per_s);
  r.theta_ddot_rad_per_s2 =
      lu.solve(r.hand_acceleration_m_per_s2 -
               jacobian_dot(arm, r.theta_rad, r.theta_dot_rad_per_s) * r.theta_dot_rad_per_s);
  return r;
}

Eigen::Vector2d feedforward_torque(const ArmParameters& arm, const ReferencePoint& ref) {
  return inertia_matrix(arm, ref.theta_rad) * ref.theta_ddot_rad_per_s2 +
         coriolis_matrix(arm, ref.theta_rad, ref.theta_dot_rad_per_s) * ref.theta_dot_rad_per_s;
}

EndpointModel reference_endpoint_model() {
  EndpointModel m;
  m.inertia_kg = (Eigen::MatrixXd(2, 2) << 1.2, 0.1, 0.1, 0.9).finished();
  m.element.kind = ElementKind::kelvin_voigt;
  m.element.stiffness = (Eigen::MatrixXd(2, 2) << 250.0, 40.0, 40.0, 180.0).finished();
  m.element.damping = (Eigen::MatrixXd(2, 2) << 10.0, 1.0, 1.0, 7.0).finished();
  return m;
}

IntegratorKind integrator_kind_from_name(const std::string& name, const std::string& key) {
  if (name == "automatic") return IntegratorKind::automatic;
  if (name == "adaptive") return IntegratorKind::adaptive;
  if (name == "dopri5") return IntegratorKind::dopri5;
  if (name == "exact") return IntegratorKind::exact;
  throw InputError(key + ": unknown integrator \"" + name +
                   "\", expected automatic, adaptive, dopri5 or exact");
}

std::string integrator_kind_name(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::automatic:
      return "automatic";
    case IntegratorKind::adaptive:
      return "adaptive";
    case IntegratorKind::dopri5:
      return "dopri5";
    case IntegratorKind::exact:
      return "exact";
  }
  return "automatic";
}

int TrialSpec::dimension() const {
  return model == ModelKind::arm ? 2 : static_cast<int>(endpoint.inertia_kg.rows());
}

Eigen::MatrixXd matrix_at(const Eigen::MatrixXd& series, int sample, int n) {
  Eigen::MatrixXd m(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) m(i, j) = series(sample, i * n + j);
  }
  return m;
}

SimulationResult simulate(const TrialSpec& spec, std::mt19937_64& rng) {
  spec.validate();
  return spec.model == ModelKind::arm ? simulate_arm(spec, rng) : simulate_endpoint(spec, rng);
}

}  // namespace stiffid::models
