#pragma once
// Simulated trials with known truth (issue 4): the nonlinear two-link arm of Piovesan et al. 2012
// eq 8 / Perreault et al. 1999 eq 14 with joint viscoelasticity about a posture or the sigmoid
// reach of eqs 50-51, and the lumped endpoint model I x'' + f_visc(x, x', t) = f of Perreault eq 15
// (any dimension). See docs/simulator.md for the model choices and parameter sources.
//
// Channels of the returned trial (data::Trial, uniform rate, first sample at t = 0):
//   arm:       fx, fy [N]      force applied TO the hand BY the robot (all perturbations summed)
//              th1, th2 [rad]  shoulder (from +x) and elbow (relative) angles, from the measured
//                              hand position by inverse kinematics (noise included)
//              x, y [m]        measured hand position (noise included)
//              dth1, dth2 [rad], dx, dy [m]  the same minus the unperturbed trajectory
//   endpoint:  fx, fy [N], x, y [m] for n = 2 (n = 1: fx, x; n = 3: fx, fy, fz, x, y, z;
//              otherwise f1..fn, x1..xn): force applied to the endpoint and its displacement from
//              equilibrium (noise included).
// The CSV writer of data/ adds the time column t [s].

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "data/trial.hpp"
#include "models/arm.hpp"
#include "models/perturbation.hpp"
#include "models/viscoelastic.hpp"

namespace stiffid::models {

enum class ModelKind { arm, endpoint };
enum class TaskKind { posture, reach };

/// The arm's task: the unperturbed trajectory the feedforward torque produces exactly.
///   posture: the hand held at `posture_hand_m` (Piovesan: (0.4, 0) m), or at the joint angles
///            `posture_joint_rad` when `posture_by_angles` (Perreault Fig 6: shoulder/elbow).
///   reach:   eqs 50-51: p(t) = D + G / (1 + Q exp(-B (t - E))) along the straight line from
///            D = reach_start_m to reach_target_m, G = target - start, B = reach_rate_per_s,
///            Q = reach_q, E = reach_midpoint_s (NaN -> duration / 2). Piovesan: (0.25, 0) ->
///            (0.55, 0) m, B = 4 1/s, Q = 1, E = T/2 = 2.5 s.
struct ArmTask {
  TaskKind kind = TaskKind::posture;
  Eigen::Vector2d posture_hand_m{0.4, 0.0};  ///< m
  bool posture_by_angles = false;
  Eigen::Vector2d posture_joint_rad{0.0, 0.0};  ///< rad (shoulder, elbow)
  Eigen::Vector2d reach_start_m{0.25, 0.0};     ///< m
  Eigen::Vector2d reach_target_m{0.55, 0.0};    ///< m
  double reach_rate_per_s = 4.0;                ///< B of eq 51, 1/s
  double reach_q = 1.0;                         ///< Q of eq 51, dimensionless
  double reach_midpoint_s = std::numeric_limits<double>::quiet_NaN();  ///< E of eq 51, s
};

/// The unperturbed trajectory at one instant: hand (m, m/s, m/s^2) and joints (rad, rad/s, rad/s^2)
/// obtained from it exactly (inverse kinematics, theta' = J^-1 p', theta'' = J^-1 (p'' - J'
/// theta')).
struct ReferencePoint {
  Eigen::Vector2d hand_m, hand_velocity_m_per_s, hand_acceleration_m_per_s2;
  Eigen::Vector2d theta_rad, theta_dot_rad_per_s, theta_ddot_rad_per_s2;
};
/// The reference of `task` at t_s for a trial of `duration_s` (used for E = T/2).
ReferencePoint arm_reference(const ArmParameters& arm, const ArmTask& task, double duration_s,
                             double t_s);
/// Exact feedforward torque along the reference, N m (2): tau_ff = M(theta) theta'' +
/// H(theta, theta') theta' (eq 8 without gravity), so that the unperturbed arm follows the task.
Eigen::Vector2d feedforward_torque(const ArmParameters& arm, const ReferencePoint& reference);

/// Lumped endpoint model of Perreault eq 15 in n dimensions: inertia I (n x n, kg, SPD) and a
/// viscoelastic element in endpoint units (N/m, N s/m, N/m^3) about x = 0.
struct EndpointModel {
  Eigen::MatrixXd inertia_kg;  ///< (n x n)
  Viscoelasticity element;     ///< n = inertia_kg.rows()
};
/// The endpoint model of the shared MIMO reference case (/work/shared/reference): I = [1.2 0.1;
/// 0.1 0.9] kg, B = [10 1; 1 7] N s/m, K = [250 40; 40 180] N/m, constant.
EndpointModel reference_endpoint_model();

/// Integration methods. A stiff method (Boost.Odeint rosenbrock4) is not offered: it needs
/// Boost.uBLAS, whose storage does not compile as C++20 with Boost 1.74 (std::allocator::construct
/// was removed). The default servo (2e4 N/m, 250 N s/m against a ~1.5 kg hand: eigenvalues of a few
/// hundred 1/s) is not stiff at the step sizes accuracy needs, so the explicit methods handle it; a
/// much stiffer servo still works, with proportionally more steps.
enum class IntegratorKind {
  automatic,  ///< exact for a linear time-invariant endpoint model driven by random forces, else
              ///< adaptive
  adaptive,   ///< error-controlled Runge-Kutta per segment (see integrate.hpp): Dormand-Prince
              ///< 5(4) with dense output on a segment with samples inside it, Runge-Kutta-
              ///< Fehlberg 7(8) stepping exactly to the end of a segment without (e.g. between
              ///< the samples of a first-order-hold random force)
  dopri5,     ///< Boost.Odeint Dormand-Prince 5(4) with dense output on every segment
  exact,      ///< matrix-exponential discretization (linear time-invariant endpoint model only)
};
IntegratorKind integrator_kind_from_name(const std::string& name, const std::string& key);
std::string integrator_kind_name(IntegratorKind kind);

/// Error control of the adaptive integrators. Local error per step <= absolute + relative * |state|
/// on every state (deviations in rad or m and their rates in rad/s or m/s).
struct IntegratorOptions {
  IntegratorKind kind = IntegratorKind::automatic;
  double absolute_tolerance = 1e-10;  ///< rad (arm) or m (endpoint), and per s for rates
  double relative_tolerance = 1e-9;   ///< dimensionless
  double initial_step_s = 1e-4;       ///< s
  long max_steps = 50'000'000;        ///< accepted steps per trial before giving up (status)
};

/// Everything that defines a trial. Defaults: Piovesan's posture trial (5 s at 4 kHz, hand at
/// (0.4, 0) m, K0/C0 of eq 52, constant profiles, no perturbation, no noise).
struct TrialSpec {
  ModelKind model = ModelKind::arm;
  double duration_s = 5.0;         ///< s; samples = round(duration_s * sample_rate_hz)
  double sample_rate_hz = 4000.0;  ///< Hz
  ArmParameters arm;               ///< model == arm
  ArmTask task;                    ///< model == arm
  Viscoelasticity joint = piovesan_kelvin_voigt();      ///< model == arm, joint space (2 x 2)
  EndpointModel endpoint = reference_endpoint_model();  ///< model == endpoint
  /// Initial deviation from the reference (rad or m, n) and its rate (rad/s or m/s, n); empty =
  /// zero. The arm starts on its reference when these are empty.
  Eigen::VectorXd initial_deviation, initial_deviation_rate;
  Perturbations perturbations;
  NoiseOptions noise;
  IntegratorOptions integrator;
  std::uint64_t seed = 1;  ///< seed of the generator the CLI passes to simulate()
  std::string source;      ///< where the spec came from (for messages)

  /// Degrees of freedom: 2 for the arm, inertia_kg.rows() for the endpoint model.
  int dimension() const;
  /// Throws InputError naming the spec key of the first impossible value (durations, rates, masses,
  /// unreachable hand positions, non-SPD inertia or stiffness, pulse onsets outside the trial ...).
  void validate() const;
};

/// The truth of a trial, sampled at the trial's times. Matrix time series are stored one sample
/// per row, row-major: series(s, i * n + j) = A(t_s)(i, j); use matrix_at() to get one.
struct Truth {
  ModelKind model = ModelKind::arm;
  int dimension = 0;                   ///< n
  Eigen::VectorXd time_s;              ///< [S] s
  Eigen::MatrixXd stiffness;           ///< (S x n*n) K(t) (K_P(t) for PT): N m/rad | N/m
  Eigen::MatrixXd damping;             ///< (S x n*n) C(t) (C_P(t) for PT): N m s/rad | N s/m
  Eigen::MatrixXd inertia;             ///< (S x n*n) M(theta(t)) kg m^2 | I kg
  Eigen::MatrixXd series_stiffness;    ///< (n x n) K_S (PT) N m/rad | N/m, else empty
  Eigen::MatrixXd cubic_stiffness;     ///< (n x n) B (Duffing) N m/rad^3 | N/m^3, else empty
  Eigen::VectorXd stiffness_profile;   ///< [S] u_K(t)
  Eigen::VectorXd damping_profile;     ///< [S] u_C(t)
  Eigen::MatrixXd position;            ///< (S x n) noise-free joint angles rad | displacement m
  Eigen::MatrixXd velocity;            ///< (S x n) rad/s | m/s
  Eigen::MatrixXd reference_position;  ///< (S x n) unperturbed joint angles rad | 0 m
  Eigen::MatrixXd reference_velocity;  ///< (S x n) rad/s | m/s
  Eigen::MatrixXd internal_state;      ///< (S x n) PT fibre deviation z, rad | m; else empty
  Eigen::MatrixXd hand_position_m;     ///< (S x 2) noise-free hand position (arm), m
  Eigen::MatrixXd reference_hand_position_m;  ///< (S x 2) unperturbed hand path (eqs 50-51), m
  Eigen::MatrixXd applied_force_n;            ///< (S x forces) force on the hand/endpoint, N
  std::vector<ForcePulse> pulses;             ///< as applied (random directions resolved)
  std::vector<DisplacementRamp> ramps;        ///< as applied
  Eigen::VectorXd noise_sigma;                ///< [outputs] constant-noise standard deviation, m
  double sdn_max_sigma = 0.0;  ///< largest signal-dependent noise std over outputs, m
};
/// A(t_s) (n x n) from a row of a matrix series of Truth.
Eigen::MatrixXd matrix_at(const Eigen::MatrixXd& series, int sample, int n);

struct SimulationResult {
  Status status;      ///< not ok when the integrator gave up or the state blew up
  data::Trial trial;  ///< the measured channels (see the top of this file)
  Truth truth;
  IntegratorKind integrator = IntegratorKind::automatic;  ///< the method actually used
  long steps = 0;            ///< accepted integrator steps (0 for the exact method)
  long rhs_evaluations = 0;  ///< right-hand-side evaluations of the ODE (0 for exact)
};

/// Simulates one trial. Randomness (random forces, random octant directions, noise) is drawn from
/// `rng` only, in that order, so the same seed gives the same trial bit for bit on any thread.
/// Calls spec.validate() first (InputError on bad input); numerical failure goes to status.
SimulationResult simulate(const TrialSpec& spec, std::mt19937_64& rng);

/// The truth (and the applied perturbations) as JSON with unit-suffixed keys (docs/simulator.md).
nlohmann::json truth_to_json(const SimulationResult& result);

}  // namespace stiffid::models
