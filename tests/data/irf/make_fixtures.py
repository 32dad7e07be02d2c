#!/usr/bin/python3
"""Makes the IRF test fixtures in this folder with numpy/scipy (independent of stiffid).

Run from anywhere: /usr/bin/python3 tests/data/irf/make_fixtures.py
Outputs (all deterministic, numpy.random.default_rng seeds below):

correlation_signals.csv   3 channels a,b,c, 300 samples at 100 Hz (t column), random walks + noise
correlation_expected.csv  lag (samples, -25..25) and phi_<p><q> for every ordered pair of channels:
                          phi_pq(d) = 1/N sum_k p(k) q(k+d), means removed, by direct slicing sums.

endpoint_<case>.csv       60 s at 50 Hz of the 2-D endpoint model I x'' + B x' + K x = f
                          (I, B, K as the shared reference case), zero-order-hold discretised with
                          scipy.signal.cont2discrete, forces = 4th-order Butterworth 9 Hz low-pass of
                          white noise (analog prototype, ZOH;
                          about 1 N peak to peak), columns t,fx,fy,x,y (N and m).
    c75        75 % input coupling (fy = sqrt(.75) fx' + sqrt(.25) w, i.e. 75 % of the variance of fy
               is linearly related to fx), no output noise.
    c75_snr20  the same forces, output noise at 20 dB SNR (noise RMS = signal RMS / 10).
    snr10      independent inputs, output noise at 10 dB SNR (noise RMS = signal RMS / sqrt(10)).
endpoint_true_irf.csv     lag_s (-0.1..1.0 s) and h_<out>_<in> in m/(N s): impulse response of the
                          discretised system divided by dt, so y(t) = dt sum_tau h(tau) f(t - tau).
endpoint_cases.json       per case: the noise actually added, and the best achievable R^2 in %
                          (1 - sum noise^2 / sum y^2 with y the noisy outputs, means removed).
"""
import json
import os

import numpy as np
from scipy import signal

HERE = os.path.dirname(os.path.abspath(__file__))

I_KG = np.array([[1.2, 0.1], [0.1, 0.9]])
B_NS_PER_M = np.array([[10.0, 1.0], [1.0, 7.0]])
K_N_PER_M = np.array([[250.0, 40.0], [40.0, 180.0]])
FS_HZ = 50.0
DURATION_S = 60.0
LAG_FIRST, LAG_LAST = -5, 50  # samples: -0.1 .. 1.0 s at 50 Hz


def write_csv(path, header, columns):
    data = np.column_stack(columns)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt="%.17g")


def correlation_fixture():
    rng = np.random.default_rng(20261123)
    n = 300
    walk = np.cumsum(rng.standard_normal((n, 3)), axis=0) * 0.1
    x = walk + rng.standard_normal((n, 3)) + np.array([2.0, -1.0, 0.5])
    t = np.arange(n) / 100.0
    write_csv(os.path.join(HERE, "correlation_signals.csv"), ["t", "a", "b", "c"],
              [t, x[:, 0], x[:, 1], x[:, 2]])
    xc = x - x.mean(axis=0)
    max_lag = 25
    names = "abc"
    header, columns = ["lag"], [np.arange(-max_lag, max_lag + 1)]
    for p in range(3):
        for q in range(3):
            phi = []
            for d in range(-max_lag, max_lag + 1):
                if d >= 0:
                    phi.append(np.dot(xc[: n - d, p], xc[d:, q]) / n)
                else:
                    phi.append(np.dot(xc[-d:, p], xc[: n + d, q]) / n)
            header.append("phi_" + names[p] + names[q])
            columns.append(np.array(phi))
    write_csv(os.path.join(HERE, "correlation_expected.csv"), header, columns)


def endpoint_system():
    """ZOH-discretised state space of I x'' + B x' + K x = f; state (x, x'), output x (m)."""
    inv_i = np.linalg.inv(I_KG)
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv_i @ K_N_PER_M, -inv_i @ B_NS_PER_M]])
    b = np.vstack([np.zeros((2, 2)), inv_i])
    c = np.hstack([np.eye(2), np.zeros((2, 2))])
    d = np.zeros((2, 2))
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), 1.0 / FS_HZ, method="zoh")
    return ad, bd, cd, dd


def simulate(system, forces):
    ad, bd, cd, dd = system
    _, y, _ = signal.dlsim((ad, bd, cd, dd, 1.0 / FS_HZ), forces)
    return y


def band_limited_forces(rng, n, coupling):
    """Two forces in N: 4th-order Butterworth 9 Hz low-pass of white noise, about 1 N p-p."""
    # The paper simulated in continuous time (Simulink), so the filter is the analog Butterworth,
    # ZOH-discretised like the mechanics. (The bilinear digital design, signal.butter(4, 9, fs=50),
    # has a zero at Nyquist that makes the input correlation matrix singular to ~1e-9.)
    ba, aa = signal.butter(4, 2 * np.pi * 9.0, analog=True)
    bd, ad, _ = signal.cont2discrete((ba, aa), 1.0 / FS_HZ, method="zoh")
    bb, ab = bd.ravel(), ad
    w = signal.lfilter(bb, ab, rng.standard_normal((n, 2)), axis=0)
    w /= w.std(axis=0)
    fx = w[:, 0]
    fy = np.sqrt(coupling) * fx + np.sqrt(1.0 - coupling) * w[:, 1]
    return 0.25 * np.column_stack([fx, fy])  # std 0.25 N: about 1 N peak to peak


def true_irf(system):
    ad, bd, cd, _ = system
    dt = 1.0 / FS_HZ
    lags = np.arange(LAG_FIRST, LAG_LAST + 1)
    h = np.zeros((len(lags), 2, 2))  # [lag, out, in]
    for idx, k in enumerate(lags):
        if k >= 1:  # g[k] = C Ad^(k-1) Bd, g[0] = D = 0
            h[idx] = cd @ np.linalg.matrix_power(ad, k - 1) @ bd / dt
    return lags, h


def endpoint_fixtures():
    system = endpoint_system()
    n = int(DURATION_S * FS_HZ)
    t = np.arange(n) / FS_HZ
    cases = {}
    for name, coupling, snr_db, seed in [("c75", 0.75, None, 75), ("c75_snr20", 0.75, 20.0, 75),
                                         ("snr10", 0.0, 10.0, 10)]:
        rng = np.random.default_rng(seed)
        f = band_limited_forces(rng, n, coupling)
        y_clean = simulate(system, f)
        noise = rng.standard_normal((n, 2))
        if snr_db is None:
            noise[:] = 0.0
        else:
            noise *= (y_clean.std(axis=0) / 10 ** (snr_db / 20.0)) / noise.std(axis=0)
        y = y_clean + noise
        write_csv(os.path.join(HERE, "endpoint_" + name + ".csv"), ["t", "fx", "fy", "x", "y"],
                  [t, f[:, 0], f[:, 1], y[:, 0], y[:, 1]])
        yc = y - y.mean(axis=0)
        nc = noise - noise.mean(axis=0)
        cases[name] = {
            "coupling": coupling,
            "snr_db": snr_db,  # None (null): no noise
            "input_coupling_measured": float(np.corrcoef(f[:, 0], f[:, 1])[0, 1] ** 2),
            "best_r2_percent": float(100.0 * (1.0 - np.sum(nc**2) / np.sum(yc**2))),
        }
    lags, h = true_irf(system)
    write_csv(os.path.join(HERE, "endpoint_true_irf.csv"),
              ["lag_s", "h_x_fx", "h_x_fy", "h_y_fx", "h_y_fy"],
              [lags / FS_HZ, h[:, 0, 0], h[:, 0, 1], h[:, 1, 0], h[:, 1, 1]])
    meta = {"fs": FS_HZ, "lag_samples": [LAG_FIRST, LAG_LAST], "I": I_KG.tolist(),
            "B": B_NS_PER_M.tolist(), "K": K_N_PER_M.tolist(), "cases": cases}
    with open(os.path.join(HERE, "endpoint_cases.json"), "w") as out:
        json.dump(meta, out, indent=2)
        out.write("\n")


if __name__ == "__main__":
    correlation_fixture()
    endpoint_fixtures()
