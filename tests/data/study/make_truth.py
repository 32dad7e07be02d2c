#!/usr/bin/python3
"""True compliance IRF and FRF of a linear endpoint model, computed with scipy, independently of
stiffid, for tests/validation/test_perreault1999.cpp.

The model I x'' + B x' + K x = f is discretized with scipy.signal.cont2discrete(method='foh')
(inputs linearly interpolated between samples); its impulse response g(k) = D for k = 0 and
C A^(k-1) B for k >= 1 gives y(k) = sum g(j) f(k - j); in stiffid's physical-units IRF convention
y = dt * sum h f, so h = g / dt. The FRF is H(f) = C (z I - A)^-1 B + D at z = exp(i 2 pi f dt).
Writes truth.json next to this script.
"""
import json
import os

import numpy as np
from scipy.signal import cont2discrete

FS = 50.0
DT = 1.0 / FS
cases = {
    # The shared reference case's endpoint model (kg, N s/m, N/m).
    "reference": ([[1.2, 0.1], [0.1, 0.9]], [[10.0, 1.0], [1.0, 7.0]], [[250.0, 40.0], [40.0, 180.0]]),
    # A lighter, stiffer, less damped one (resonances near 4-6 Hz).
    "stiff": ([[0.6, -0.05], [-0.05, 0.4]], [[3.0, 0.5], [0.5, 2.0]], [[600.0, -80.0], [-80.0, 450.0]]),
}
out = {"sample_rate_hz": FS, "lags": list(range(0, 41)), "frequency_hz": [0.0, 0.5, 1.0, 2.3, 5.0, 9.0, 20.0]}
for name, (I, B, K) in cases.items():
    I, B, K = np.array(I), np.array(B), np.array(K)
    n = 2
    Iinv = np.linalg.inv(I)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Iinv @ K, -Iinv @ B]])
    G = np.vstack([np.zeros((n, n)), Iinv])
    C = np.hstack([np.eye(n), np.zeros((n, n))])
    D = np.zeros((n, n))
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, G, C, D), DT, method="foh")
    g = [Dd]
    power = np.eye(2 * n)
    for _ in range(1, 41):
        g.append(Cd @ power @ Bd)
        power = power @ Ad
    h = [(gk / DT).tolist() for gk in g]  # h[k][j][i]: output j, input i, m/(N s)
    frf = []
    for f in out["frequency_hz"]:
        z = np.exp(1j * 2 * np.pi * f * DT)
        H = Cd @ np.linalg.solve(z * np.eye(2 * n) - Ad, Bd) + Dd
        frf.append({"re": H.real.tolist(), "im": H.imag.tolist()})
    out[name] = {"inertia_kg": I.tolist(), "damping_ns_per_m": B.tolist(),
                 "stiffness_n_per_m": K.tolist(), "h": h, "frf": frf}
path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "truth.json")
with open(path, "w") as fh:
    json.dump(out, fh)
    fh.write("\n")
