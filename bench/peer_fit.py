#!/usr/bin/env python3
"""Peer of bench_fit: the same fits with scipy.optimize.least_squares and solve_ivp.

  peer_fit.py fit DIR [kv|pt|duffing|all]   fits DIR/{kv,pt,duffing}.csv (written by bench_fit make)
  peer_fit.py regress DIR                   force-pulse full regression over DIR/reg/*.csv

Same residual as bench_fit (single shooting): parameters theta (Cholesky factors with log
diagonals, B diagonal) and the initial state; residuals (x_sim - x) / RMS(x) per output; forces
linearly interpolated between samples; solve_ivp RK45 at rtol 1e-8 with max_step one sample.
Same start: diagonals 1.3 x the truth, off-diagonals 0, states from the data. The regression:
postural baseline over 0.2 s before the detected onset, Savitzky-Golay (21 samples, order 4,
mode interp) derivatives over the first 200 ms, numpy lstsq.
"""
import glob
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

I0 = np.array([[1.8, 0.3], [0.3, 1.2]])
C0 = np.array([[15.0, 3.0], [3.0, 10.0]])
K0 = np.array([[500.0, 100.0], [100.0, 300.0]])
TRUTH = {
    "kv": [("I", I0), ("C", C0), ("K", K0)],
    "pt": [("I", I0), ("KS", np.array([[1750.0, 250.0], [250.0, 1000.0]])),
           ("KP", np.array([[350.0, 50.0], [50.0, 200.0]])),
           ("CP", np.array([[40.0, 6.0], [6.0, 25.0]]))],
    "duffing": [("I", I0), ("C", C0), ("K", K0), ("B", np.diag([2e6, 1e6]))],
}


def read(path):
    with open(path) as fh:
        names = fh.readline().strip().split(",")
    return names, np.loadtxt(path, delimiter=",", skiprows=1)


def spd(th, n=2):
    L = np.zeros((n, n))
    k = 0
    for i in range(n):
        for j in range(i + 1):
            L[i, j] = np.exp(th[k]) if i == j else th[k]
            k += 1
    return L @ L.T


def unpack(model, th):
    mats = []
    k = 0
    for name, _ in TRUTH[model]:
        if name == "B":
            mats.append(np.diag(th[k:k + 2]))
            k += 2
        else:
            mats.append(spd(th[k:k + 3]))
            k += 3
    return mats, k


def start(model):
    th = []
    for name, m in TRUTH[model]:
        d = 1.3 * m[0, 0]
        if name == "B":
            th += [d, d]
        else:
            th += [0.5 * np.log(d), 0.0, 0.5 * np.log(d)]
    return np.array(th)


def simulate(model, mats, z0, f, dt):
    n = f.shape[0]
    Iinv = np.linalg.inv(mats[0])
    t_end = (n - 1) * dt

    def force(t):
        k = min(int(t / dt), n - 2)
        a = t / dt - k
        return (1 - a) * f[k] + a * f[k + 1]

    if model == "pt":
        KS, KP, CP = mats[1], mats[2], mats[3]
        CPinv = np.linalg.inv(CP)

        def rhs(t, z):
            x, v, q = z[:2], z[2:4], z[4:]
            return np.concatenate([v, Iinv @ (force(t) - KS @ (x - q)),
                                   CPinv @ (KS @ (x - q) - KP @ q)])
    else:
        C, K = mats[1], mats[2]
        B = mats[3] if model == "duffing" else np.zeros((2, 2))

        def rhs(t, z):
            x, v = z[:2], z[2:4]
            return np.concatenate([v, Iinv @ (force(t) - C @ v - K @ x - B @ x**3)])

    sol = solve_ivp(rhs, (0.0, t_end), z0, rtol=1e-8, atol=1e-12, max_step=dt,
                    t_eval=np.arange(n) * dt)
    return sol.y[:2].T


def fit(directory, which):
    for model in ("kv", "pt", "duffing"):
        if which not in ("all", model):
            continue
        t0 = time.perf_counter()
        _, d = read(os.path.join(directory, model + ".csv"))
        dt = d[1, 0] - d[0, 0]
        f, y = d[:, 1:3], d[:, 3:5]
        w = 1.0 / np.sqrt(np.mean(y**2, axis=0))
        v0 = (y[1] - y[0]) / dt
        th0 = start(model)
        mats0, p = unpack(model, th0)
        z0 = np.concatenate([y[0], v0])
        if model == "pt":
            z0 = np.concatenate([z0, np.linalg.solve(mats0[1] + mats0[2], mats0[1] @ y[0])])

        def residual(par):
            mats, _ = unpack(model, par[:p])
            return ((simulate(model, mats, par[p:], f, dt) - y) * w).ravel()

        r = least_squares(residual, np.concatenate([th0, z0]), method="lm", xtol=1e-12,
                          ftol=1e-12, gtol=1e-14)
        mats, _ = unpack(model, r.x[:p])
        err = max(np.max(np.abs(m - t)) / np.max(np.abs(t))
                  for m, (_, t) in zip(mats, TRUTH[model]))
        print("fit %-8s %8.3f s  evaluations %4d  max rel error %.2e  status %d"
              % (model, time.perf_counter() - t0, r.nfev, err, r.status), flush=True)


def regress(directory):
    t0 = time.perf_counter()
    groups = {}
    for path in sorted(glob.glob(os.path.join(directory, "reg", "*.csv"))):
        names, d = read(path)
        col = {n: d[:, i] for i, n in enumerate(names)}
        t = col["t"]
        fs = 1.0 / (t[1] - t[0])
        F = np.column_stack([col["fx"], col["fy"]])
        X = np.column_stack([col["x"], col["y"]])
        ref = int(round(0.05 * fs))
        dev = np.linalg.norm(F - F[:ref].mean(axis=0), axis=1)
        floor = max(5 * np.sqrt(np.mean(dev[:ref] ** 2)), 1e-6 * dev.max())
        i = int(np.argmax(dev > max(floor, 0.05 * dev.max())))
        while i > 0 and dev[i - 1] > floor:
            i -= 1
        nb = int(round(0.2 * fs))
        dx = X[i:i + nb] - X[i - nb:i].mean(axis=0)
        dF = F[i:i + nb] - F[i - nb:i].mean(axis=0)
        dt = 1.0 / fs
        v = savgol_filter(dx, 21, 4, deriv=1, delta=dt, axis=0, mode="interp")
        a = savgol_filter(dx, 21, 4, deriv=2, delta=dt, axis=0, mode="interp")
        key = round(t[i], 1)
        groups.setdefault(key, []).append((np.hstack([a, v, dx]), dF))
    worst = 0.0
    for key in sorted(groups):
        phi = np.vstack([g[0] for g in groups[key]])
        tgt = np.vstack([g[1] for g in groups[key]])
        theta = np.linalg.lstsq(phi, tgt, rcond=None)[0]
        K = theta[4:6].T
        worst = max(worst, np.max(np.abs(K - K0)) / 500.0)
    print("regress force-pulse %d groups  %6.3f s  max rel K error %.2e"
          % (len(groups), time.perf_counter() - t0, worst))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit("usage: peer_fit.py fit DIR [model] | regress DIR")
    if sys.argv[1] == "fit":
        fit(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "all")
    else:
        regress(sys.argv[2])
