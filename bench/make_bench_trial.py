#!/usr/bin/python3
"""Writes the MIMO benchmark trial: 10 minutes at 1 kHz of the 2-D endpoint model.

  make_bench_trial.py OUT.csv [--seconds 600] [--fs 1000] [--force-hz 9] [--seed 2026]

I x'' + B x' + K x = f with the reference values (I = [[1.2, 0.1], [0.1, 0.9]] kg,
B = [[10, 1], [1, 7]] N s/m, K = [[250, 40], [40, 180]] N/m), zero-order-hold discretised
(scipy.signal.cont2discrete); forces fx, fy in N: 4th-order Butterworth low-pass of white
noise at --force-hz (analog prototype, ZOH; 9 Hz as in Perreault et al. 1999), std 0.25 N,
25 % coupling (25 % of the variance of fy linearly related to fx); positions x, y in m with output noise at 20 dB SNR. Columns t,fx,fy,x,y.
Deterministic (numpy default_rng(seed)). Not committed: the file is ~45 MB.
"""
import argparse
import os

import numpy as np
from scipy import signal

I_KG = np.array([[1.2, 0.1], [0.1, 0.9]])
B_NS_PER_M = np.array([[10.0, 1.0], [1.0, 7.0]])
K_N_PER_M = np.array([[250.0, 40.0], [40.0, 180.0]])


def main():
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--fs", type=float, default=1000.0)
    p.add_argument("--force-hz", type=float, default=9.0)
    p.add_argument("--seed", type=int, default=2026)
    a = p.parse_args()
    dt = 1.0 / a.fs
    n = int(round(a.seconds * a.fs))
    rng = np.random.default_rng(a.seed)

    ba, aa = signal.butter(4, 2 * np.pi * a.force_hz, analog=True)
    bf, af, _ = signal.cont2discrete((ba, aa), dt, method="zoh")
    w = signal.lfilter(bf.ravel(), af, rng.standard_normal((n, 2)), axis=0)
    w /= w.std(axis=0)
    coupling = 0.25
    f = 0.25 * np.column_stack([w[:, 0], np.sqrt(coupling) * w[:, 0] + np.sqrt(1 - coupling) * w[:, 1]])

    inv_i = np.linalg.inv(I_KG)
    a_c = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv_i @ K_N_PER_M, -inv_i @ B_NS_PER_M]])
    b_c = np.vstack([np.zeros((2, 2)), inv_i])
    c_c = np.hstack([np.eye(2), np.zeros((2, 2))])
    ad, bd, cd, dd, _ = signal.cont2discrete((a_c, b_c, c_c, np.zeros((2, 2))), dt, method="zoh")
    y = np.zeros((n, 2))
    for i in range(2):  # superpose the two inputs, each as a transfer function (fast lfilter)
        num, den = signal.ss2tf(ad, bd, cd, dd, input=i)
        for j in range(2):
            y[:, j] += signal.lfilter(num[j], den, f[:, i])
    noise = rng.standard_normal((n, 2))
    y += noise * (y.std(axis=0) / 10.0) / noise.std(axis=0)

    t = np.arange(n) * dt
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    tmp = a.out + ".tmp"
    np.savetxt(tmp, np.column_stack([t, f, y]), delimiter=",", header="t,fx,fy,x,y",
               comments="", fmt="%.10g")
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
