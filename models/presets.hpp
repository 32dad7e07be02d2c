#pragma once
// Ready-made trial specs of the two papers (the same ones shipped as JSON in models/specs/).

#include "models/simulate.hpp"

namespace stiffid::models {

/// Perreault et al. 1999 Fig 6 postures (shoulder from the coronal plane, elbow flexion), rad:
/// 1: 63/77 deg, 2: 42/63 deg, 3: 102/59 deg, 4: 37/127 deg. Our arm frame has x lateral (along
/// the coronal plane) and y forward, so theta1 = shoulder angle and theta2 = elbow angle.
/// Throws InputError unless 1 <= position <= 4.
Eigen::Vector2d perreault_posture_rad(int position);

/// Perreault's joint viscoelasticity for the nonlinear arm (eq 14). Perreault took them from Tsuji
/// et al. 1995, which is not in our texts; we use K = [15 5; 5 12] N m/rad and B = [0.6 0.2;
/// 0.2 0.5] N m s/rad, constant (reasoning in docs/simulator.md).
Viscoelasticity perreault_joint_viscoelasticity();

/// Perreault's 60 s, 50 Hz stochastic trial of the nonlinear arm (eq 14) at Fig 6 position
/// 1..4: Table 1 arm, independent band-limited random forces (9 Hz, 4th order, 1 N peak to peak),
/// no noise.
TrialSpec perreault_arm_trial(int position);

/// Perreault's 60 s, 50 Hz stochastic trial of the linear endpoint model (eq 15) with the
/// reference case's I, B, K, input coupling in % and output SNR in dB (infinity: no noise).
TrialSpec perreault_endpoint_trial(double coupling_percent, double snr_db);

/// Piovesan et al. 2012 trial (5 s at 4 kHz) with the Kelvin-Voigt joint element of eq 52 under
/// the given stiffness and damping profiles (eq 54, start 2.5 s), posture at (0.4, 0) m or the
/// reach of eqs 50-51, and a 5 N, 20 ms impulse at 2.5 s in direction `direction_rad`.
TrialSpec piovesan_impulse_trial(TaskKind task, ProfileKind stiffness_profile,
                                 ProfileKind damping_profile, double direction_rad);

/// The same trial with a 5 N, 200 ms force pulse at `onset_s` instead of the impulse (the force
/// regression of Piovesan "Regressive Techniques").
TrialSpec piovesan_pulse_trial(TaskKind task, ProfileKind stiffness_profile,
                               ProfileKind damping_profile, double direction_rad, double onset_s);

/// The same trial with an 8 mm displacement ramp-and-hold (100/100/100 ms) at `onset_s` rendered
/// by the stiff position servo of DisplacementRamp.
TrialSpec piovesan_ramp_trial(TaskKind task, ProfileKind stiffness_profile,
                              ProfileKind damping_profile, double direction_rad, double onset_s);

}  // namespace stiffid::models
