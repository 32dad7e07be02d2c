#pragma once
// Perturbations applied by a simulated robot to the hand (or to an endpoint model) and measurement
// noise: band-limited random forces with input coupling (Perreault et al. 1999 section 3, Fig 2,
// Fig 7), force impulses and pulses (Piovesan et al. 2012, "Description of the Simulation"),
// displacement ramp-and-hold rendered by a stiff position servo, output noise at a given SNR and
// signal-dependent noise (Piovesan). All forces are the force applied TO the hand BY the robot, N.

#include <Eigen/Core>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace stiffid::models {

/// A rectangular force pulse: `amplitude_n` along the unit vector (cos a, sin a) of
/// a = direction_rad (from the +x axis, counter-clockwise), on for onset_s <= t < onset_s +
/// duration_s. Piovesan's impulse is 5 N for 20 ms, the regression pulse 5 N for 200 ms.
/// For a 1-D endpoint model the force is amplitude_n * cos(a).
struct ForcePulse {
  double onset_s = 2.5;        ///< s
  double duration_s = 0.02;    ///< s
  double amplitude_n = 5.0;    ///< N
  double direction_rad = 0.0;  ///< rad, from +x
  bool random_octant = false;  ///< draw the direction among the 8 octants from the rng instead
};
/// Piovesan's impulse (5 N, 20 ms) and pulse (5 N, 200 ms).
ForcePulse force_impulse(double onset_s, double direction_rad);
ForcePulse force_pulse(double onset_s, double direction_rad);

/// Displacement ramp-and-hold of the hand: the robot handle follows
///   p(t) = p_ref(t) + s(t) * amplitude_m * (cos a, sin a)
/// with s(t) rising linearly 0 -> 1 over ramp_s, holding 1 for plateau_s, and returning linearly
/// to 0 over return_s (Piovesan: 8 mm, 100 ms each). The handle is a stiff position servo active
/// on [onset_s, onset_s + ramp_s + plateau_s + return_s): force on the hand
///   F = K_servo (p - x) + C_servo (p' - x'),  x = hand position (m), p_ref = unperturbed hand
///   path.
/// Servo defaults: 2e4 N/m and 250 N s/m, a stiff (about 20 Hz against a ~1.5 kg hand) and well
/// damped (ratio ~0.7) handle, in the range of the manipulanda used by Burdet et al. 2000.
struct DisplacementRamp {
  double onset_s = 2.5;                    ///< s
  double amplitude_m = 0.008;              ///< m
  double ramp_s = 0.1;                     ///< s
  double plateau_s = 0.1;                  ///< s
  double return_s = 0.1;                   ///< s
  double direction_rad = 0.0;              ///< rad, from +x
  double servo_stiffness_n_per_m = 2.0e4;  ///< N/m, isotropic
  double servo_damping_ns_per_m = 250.0;   ///< N s/m, isotropic
  bool random_octant = false;              ///< draw the direction among the 8 octants instead

  double end_s() const { return onset_s + ramp_s + plateau_s + return_s; }
  /// Servo target offset from the unperturbed path, m (2), and its rate, m/s (2).
  Eigen::Vector2d offset_m(double t_s) const;
  Eigen::Vector2d offset_rate_m_per_s(double t_s) const;
};

/// How a sampled input is continued between its samples: constant (zero-order hold) or linear
/// interpolation (first-order hold).
enum class InputHold { zero_order, first_order };

/// Band-limited random forces (Perreault Fig 2): independent standard Gaussian white noise per
/// input at `oversample` x the trial's sample rate, filtered by a causal digital Butterworth
/// low-pass of `filter_order` with cut-off `bandwidth_hz` designed at that rate (bilinear
/// transform, as scipy.signal.butter + lfilter), after `warmup_s` of discarded filter transient,
/// then read every `oversample`-th sample. With oversample = 1 this is the digital filter at the
/// trial rate (the shared reference case); its bilinear zero at the Nyquist frequency leaves the
/// band above the cut-off almost empty (4th order, 9 Hz at 50 Hz: 1e-12 of the in-band power), so
/// a time-domain IRF solve (Perreault eq 11) is ill-conditioned (cond(Psi) ~ 1e12). oversample >= 4
/// approximates an analog filter sampled by the acquisition without anti-aliasing, as in
/// Perreault's continuous-time Simulink simulations: the power near Nyquist is that of the analog
/// roll-off plus its aliases (cond(Psi) ~ 5e3). Coupling (Fig 7): input 2 is
///   f2 = sqrt(c) * e1 + sqrt(1 - c) * e2',
/// with e1, e2' the filtered noises standardized over the trial and e2' made exactly uncorrelated
/// with e1 (sample Gram-Schmidt), so the squared sample correlation of f1 and f2 is exactly c:
/// c = coupling_percent / 100 of the variance of input 2 is linearly related to input 1 (inputs
/// 3.. of an n-D model are independent). Each input is finally shifted to zero mean and scaled to
/// `peak_to_peak_n` (Perreault: about 1 N), or to a standard deviation `rms_n` when that is > 0.
/// Between samples the force is continued by `hold`: linear interpolation by default (Perreault
/// linearly interpolated his simulations), or held constant (the shared reference case).
struct RandomForce {
  double bandwidth_hz = 9.0;      ///< low-pass cut-off (-3 dB), Hz (Perreault: about 9 Hz)
  int filter_order = 4;           ///< Butterworth order
  int oversample = 1;             ///< filter rate / trial sample rate (1..64), see above
  double coupling_percent = 0.0;  ///< % of the variance of input 2 linearly related to input 1
  double peak_to_peak_n = 1.0;    ///< N, per input (ignored when rms_n > 0)
  double rms_n = 0.0;             ///< N, per input; 0 -> use peak_to_peak_n
  double warmup_s = 2.0;          ///< filter transient discarded before t = 0, s
  InputHold hold = InputHold::first_order;  ///< continuation between samples
};

/// The random force samples (S x inputs), N, at `sample_rate_hz`. Draws (S + warm-up) x inputs
/// standard normal numbers from `rng`, input by input.
Eigen::MatrixXd random_forces(const RandomForce& options, int samples, int inputs,
                              double sample_rate_hz, std::mt19937_64& rng);

/// All perturbations of a trial (they add up).
struct Perturbations {
  std::vector<ForcePulse> pulses;
  std::vector<DisplacementRamp> ramps;
  bool random = false;  ///< apply `random_force`
  RandomForce random_force;
};

/// The eight perturbation directions of Piovesan (octants of the plane), rad: k pi / 4, k = 0..7.
double octant_direction_rad(int k);

/// Measurement noise on the position outputs (zero-mean Gaussian, independent per channel and
/// sample). The "signal" is the deviation of each output from its unperturbed value (the hand
/// displacement for the arm, the displacement x for an endpoint model); its RMS over the trial
/// sets the noise level:
///   constant:          sigma = rms / 10^(snr_db / 20)
///   signal-dependent:  sigma(t) = rms / 10^(sdn_max_snr_db / 20) * u(t) / max_t |u(t)|,
/// with u the stiffness profile (Piovesan: noise proportional to the stiffness profile, up to
/// 10 dB). Both may act together (their variances add). Angles of the arm are recomputed from the
/// noisy hand position by inverse kinematics, so all channels see the same measurement.
struct NoiseOptions {
  double snr_db = std::numeric_limits<double>::infinity();  ///< dB; infinity = no constant noise
  bool signal_dependent = false;                            ///< add Piovesan's SDN
  double sdn_max_snr_db = 10.0;                             ///< dB, SNR at the profile's maximum
};

}  // namespace stiffid::models
