#!/usr/bin/env python3
"""Piovesan 2012 posture trials for tests/estimators/test_tfa_posture.cpp, simulated with scipy
(independent of stiffid): the nonlinear two-link arm of eq 8-10 (Table 1 parameters, horizontal
plane) held at the hand position (0.4, 0) m by a Kelvin-Voigt joint element
    M(th) th'' + H(th, th') th' + K(t) (th - th0) + C(t) th' = J(th)^T F(t),
K(t) = K0 u(t), C = C0 = 0.01 K0 (eq 52-54, u = constant, sigmoid or sharp from 2.5 s on, 1
before), F = a 5 N, 20 ms force pulse at 2.5 s towards 45 degrees. Written at 2 kHz from 2.0 s to
5.0 s (the test needs the 0.2 s before the onset and the free response after it), noise-free; the
test adds its 20 dB noise with a seeded generator. Run: python3 make_posture_trials.py"""
import numpy as np
from scipy.integrate import solve_ivp

l1, r1, m1, i1 = 0.29, 0.132, 1.99, 0.0161
l2, r2, m2, i2 = 0.4, 0.17, 1.10, 0.0146
kappa = i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2)
beta = m2 * l1 * r2
chi = i2 + m2 * r2**2
K0 = np.array([[35.0, 5.0], [5.0, 20.0]])
C0 = 0.01 * K0
T = 5.0


def profile(kind, t):
    if t < 2.5 or kind == "constant":
        return 1.0
    if kind == "sigmoid":
        return 4.0 / (1.0 + np.exp(-4.0 * (t - 0.75 * T))) + 1.0
    if kind == "sharp":
        return 4.0 / (1.0 + np.exp(-30.0 * (t - 0.75 * T))) + 1.0
    raise ValueError(kind)


def inverse_kinematics(x, y):
    c2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    th2 = np.arccos(c2)
    th1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(th2), l1 + l2 * np.cos(th2))
    return np.array([th1, th2])


th0 = inverse_kinematics(0.4, 0.0)
direction = np.pi / 4
f_pulse = 5.0 * np.array([np.cos(direction), np.sin(direction)])


def force(t):
    return f_pulse if 2.5 <= t < 2.52 else np.zeros(2)


def rhs(kind):
    def f(t, s):
        th, w = s[:2], s[2:]
        c2, s2 = np.cos(th[1]), np.sin(th[1])
        m = np.array([[kappa + 2 * beta * c2, chi + beta * c2], [chi + beta * c2, chi]])
        h = np.array([[-beta * s2 * w[1], -beta * s2 * (w[0] + w[1])], [beta * s2 * w[0], 0.0]])
        s1, s12, c1, c12 = np.sin(th[0]), np.sin(th[0] + th[1]), np.cos(th[0]), np.cos(th[0] + th[1])
        jac = np.array([[-l1 * s1 - l2 * s12, -l2 * s12], [l1 * c1 + l2 * c12, l2 * c12]])
        u = profile(kind, t)
        tau = jac.T @ force(t) - u * K0 @ (th - th0) - C0 @ w - h @ w
        return np.concatenate([w, np.linalg.solve(m, tau)])
    return f


fs = 2000.0
t_out = np.round(np.arange(int(2.0 * fs), int(T * fs)) / fs, 10)
for kind in ["constant", "sigmoid", "sharp"]:
    state = np.concatenate([th0, [0.0, 0.0]])
    pieces = []
    for a, b in [(2.0, 2.5), (2.5, 2.52), (2.52, T)]:
        sol = solve_ivp(rhs(kind), (a, b), state, method="DOP853", rtol=1e-11, atol=1e-14,
                        dense_output=True, max_step=1e-3)
        sel = t_out[(t_out >= a) & ((t_out < b) | (b == T))]
        pieces.append(sol.sol(sel)[:2].T if sel.size else np.zeros((0, 2)))
        state = sol.y[:, -1]
    th = np.vstack(pieces)
    f = np.array([force(t) for t in t_out])
    with open(f"posture_{kind}.csv", "w") as out:
        out.write("t,th1[rad],th2[rad],fx[N],fy[N]\n")
        for i in range(t_out.size):
            out.write(f"{t_out[i]:.4f},{th[i,0]:.12g},{th[i,1]:.12g},{f[i,0]:.6g},{f[i,1]:.6g}\n")
