#!/usr/bin/python3
"""Spread of ordinary and partial coherence estimates around their closed forms, used to justify
the tolerance of test_frf.cpp (coherences_match_their_closed_forms_for_independent_inputs).

Simulates, with scipy.signal.lfilter, the 3-input 2-output IIR system of test_frf.cpp driven by
independent unit white noise plus output noise of sd 0.5 (2^16 samples, Welch nperseg 256, 50 %
overlap, Hann: n_d = 511), six times, estimates coherences with bench/peer_frf.py's scipy code, and
prints the standardized errors (estimate - truth) / sd with Bendat & Piersol's
sd = sqrt(2) (1 - g^2) |g| / sqrt(n) (n = n_d ordinary, n_d - q + 1 partial) for bins with true
g^2 > 0.02. Observed (seed 1): sd 1.03 for both, 99.9 % of |z| below 3.4, largest 4.4 and 6.0.
Run: /usr/bin/python3 tests/data/spectra/coherence_spread.py
"""
import importlib
import os
import sys

import numpy as np
import scipy.signal as ss

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../bench"))
peer = importlib.import_module("peer_frf")

SYSTEM = [[([0.5, 0.25], [1, -0.5]), ([0, 0, 0.6], [1]), ([0.2, 0.3, 0.1], [1, 0.4])],
          [([0.7], [1, 0.3, 0.3]), ([0.4, -0.4], [1, -0.2]), ([1, 0, -0.3], [1])]]
rng = np.random.default_rng(1)
z = {"ordinary": [], "partial": []}
n, nd, noise_var = 3, 511, 0.25
for rep in range(6):
    samples = 1 << 16
    x = rng.standard_normal((n, samples))
    y = [sum(ss.lfilter(b, a, x[i]) for i, (b, a) in enumerate(row))
         + 0.5 * rng.standard_normal(samples) for row in SYSTEM]
    f, g = peer.spectra(list(x) + y, 1.0, 256, 128, "hann", "constant")
    for j in range(2):
        power = np.array([np.abs(ss.freqz(b, a, worN=f * 2 * np.pi)[1]) ** 2 for b, a in SYSTEM[j]])
        total = power.sum(0) + noise_var
        gyy = g[:, n + j, n + j].real
        for i in range(n):
            est = np.abs(g[:, i, n + j]) ** 2 / (g[:, i, i].real * gyy)
            true = power[i] / total
            sd = np.sqrt(2) * (1 - true) * np.sqrt(true) / np.sqrt(nd)
            z["ordinary"] += list(((est - true) / sd)[true > 0.02])
            s = peer.conditioned(g, [i, n + j], [k for k in range(n) if k != i])
            est = np.abs(s[:, 0, 1]) ** 2 / (s[:, 0, 0].real * s[:, 1, 1].real)
            true = power[i] / (power[i] + noise_var)
            sd = np.sqrt(2) * (1 - true) * np.sqrt(true) / np.sqrt(nd - n + 1)
            z["partial"] += list(((est - true) / sd)[true > 0.02])
for name, values in z.items():
    v = np.abs(np.array(values))
    print(f"{name}: {len(v)} bins, sd {np.std(values):.3f}, 99.9% {np.percentile(v, 99.9):.2f}, "
          f"max {v.max():.2f}")
