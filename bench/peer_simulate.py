#!/usr/bin/env python3
"""Peer of bench_simulate.cpp: the same Piovesan 5 s, 4 kHz posture trial (hand at (0.4, 0) m,
K0/C0 of eq 52, 5 N 20 ms impulse at 2.5 s towards 45 deg) with scipy solve_ivp RK45 (the same
Dormand-Prince 5(4) pair) at the simulator's default tolerances (rtol 1e-9, atol 1e-10), split at
the impulse edges, sampled at 4 kHz.  Prints the median wall time over the repetitions.
Usage: /usr/bin/python3 peer_simulate.py [repetitions]"""
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

L1, R1, M1, I1 = 0.29, 0.132, 1.99, 0.0161
L2, R2, M2, I2 = 0.4, 0.17, 1.10, 0.0146
KAPPA = I1 + I2 + M1 * R1**2 + M2 * (L1**2 + R2**2)
BETA = M2 * L1 * R2
CHI = I2 + M2 * R2**2
K0 = np.array([[35.0, 5.0], [5.0, 20.0]])
C0 = 0.01 * K0


def ik(p):
    c2 = (p @ p - L1**2 - L2**2) / (2 * L1 * L2)
    t2 = np.arccos(c2)
    return np.array([np.arctan2(p[1], p[0]) - np.arctan2(L2 * np.sin(t2), L1 + L2 * np.cos(t2)), t2])


TH0 = ik(np.array([0.4, 0.0]))
F_IMPULSE = 5.0 * np.array([np.cos(np.pi / 4), np.sin(np.pi / 4)])


def rhs(t, y, on):
    th, w = y[:2], y[2:]
    c2, s2 = np.cos(th[1]), np.sin(th[1])
    m = np.array([[KAPPA + 2 * BETA * c2, CHI + BETA * c2], [CHI + BETA * c2, CHI]])
    b = BETA * s2
    h = np.array([[-b * w[1], -b * (w[0] + w[1])], [b * w[0], 0.0]])
    tau = -C0 @ w - K0 @ (th - TH0)
    if on:
        s1, c1 = np.sin(th[0]), np.cos(th[0])
        s12, c12 = np.sin(th[0] + th[1]), np.cos(th[0] + th[1])
        j = np.array([[-L1 * s1 - L2 * s12, -L2 * s12], [L1 * c1 + L2 * c12, L2 * c12]])
        tau = tau + j.T @ F_IMPULSE
    return np.concatenate([w, np.linalg.solve(m, tau - h @ w)])


def simulate():
    fs, n = 4000.0, 20000
    t = np.arange(n) / fs
    out = np.zeros((n, 4))
    y = np.concatenate([TH0, np.zeros(2)])
    for a, b, on in [(0.0, 2.5, False), (2.5, 2.52, True), (2.52, t[-1], False)]:
        sel = (t >= a) & (t < b) if b < t[-1] else (t >= a)
        sol = solve_ivp(rhs, (a, b), y, method="RK45", rtol=1e-9, atol=1e-10, t_eval=t[sel],
                        args=(on,), dense_output=True)
        out[sel] = sol.y.T
        y = sol.sol(b)
    return out


def main():
    reps = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        simulate()
        times.append((time.perf_counter() - t0) * 1e3)
    print(f"scipy_arm_impulse_5s_4khz  median {np.median(times):.1f} ms")


if __name__ == "__main__":
    main()
