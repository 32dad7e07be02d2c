#!/usr/bin/env python3
"""Fixtures for tests/fitting, made with numpy/scipy only (independent of stiffid).

Run: /usr/bin/python3 tests/data/fitting/make_fixtures.py   (writes beside this script)

1. Lumped-model trials (kv|pt|duffing, 1 and 2 DOF), 2 s at 200 Hz: band-limited random forces
   (seeded numpy generator, 4th-order Butterworth at 8 Hz, about 5 N RMS) drive
     KV      I x'' + C x' + K x = f
     PT      I x'' + KS (x - q) = f,   CP q' = KS (x - q) - KP q
     Duffing I x'' + C x' + K x + B x.^3 = f   (B diagonal, element-wise cube)
   between samples the force is linearly interpolated (first-order hold; one ZOH case). Integrated
   sample interval by sample interval with solve_ivp (DOP853, rtol 1e-12, atol 1e-15), from a
   non-zero initial state. Columns: t, f1[,f2], x1[,x2]. Truth in lumped_truth.json.
2. Regression trials of a linear endpoint model M dx'' + B dx' + K dx = dF about the posture
   hand = (0.4, 0) m of the Piovesan Table 1 arm, 1 kHz, columns t, th1, th2, x, y, fx, fy:
   - force pulses: 5 N for 200 ms in 8 directions, onsets 2.5 s and 3.0 s;
   - displacement ramp-and-hold: 8 mm, minimum-jerk 100 ms ramp up, 100 ms plateau, 100 ms
     minimum-jerk ramp down; the force is the one the servo must apply (M a + B v + K x, exact).
   Each trial runs from onset - 0.25 s to onset + 0.35 s. The model at the 3.0 s onset has K and B
   scaled by 1.5 so that the two onset groups differ. Truth in regress_truth.json.
"""
import json
import os

import numpy as np
from scipy.integrate import solve_ivp
from scipy.signal import butter, lfilter

HERE = os.path.dirname(os.path.abspath(__file__))


def band_limited_forces(rng, n, dof, fs, cutoff_hz=8.0, rms=5.0):
    b, a = butter(4, cutoff_hz / (fs / 2))
    w = rng.standard_normal((n + 400, dof))
    f = lfilter(b, a, w, axis=0)[400:]
    return f * (rms / np.sqrt(np.mean(f**2, axis=0)))


def rhs_factory(model, p, dof):
    I = np.array(p["I"])
    Iinv = np.linalg.inv(I)

    def rhs(f):
        def g(_t, s):
            x, v = s[:dof], s[dof:2 * dof]
            if model == "kv":
                acc = Iinv @ (f(_t) - np.array(p["C"]) @ v - np.array(p["K"]) @ x)
                return np.concatenate([v, acc])
            if model == "duffing":
                B = np.diag(np.array(p["B"]))
                acc = Iinv @ (f(_t) - np.array(p["C"]) @ v - np.array(p["K"]) @ x - B @ x**3)
                return np.concatenate([v, acc])
            q = s[2 * dof:]
            KS, KP, CP = (np.array(p[k]) for k in ("KS", "KP", "CP"))
            acc = Iinv @ (f(_t) - KS @ (x - q))
            qd = np.linalg.solve(CP, KS @ (x - q) - KP @ q)
            return np.concatenate([v, acc, qd])
        return g
    return rhs


def simulate(model, p, dof, forces, fs, state0, hold):
    n = forces.shape[0]
    dt = 1.0 / fs
    rhs = rhs_factory(model, p, dof)
    s = np.array(state0, dtype=float)
    out = np.zeros((n, dof))
    out[0] = s[:dof]
    for k in range(n - 1):
        t0, f0, f1 = k * dt, forces[k], forces[k + 1]
        if hold == "foh":
            f = lambda t, t0=t0, f0=f0, f1=f1: f0 + (f1 - f0) * (t - t0) / dt
        else:
            f = lambda t, f0=f0: f0
        sol = solve_ivp(rhs(f), (t0, t0 + dt), s, method="DOP853", rtol=1e-12, atol=1e-15)
        s = sol.y[:, -1]
        out[k + 1] = s[:dof]
    return out


def write_trial(path, t, columns):
    names = list(columns)
    data = np.column_stack([t] + [columns[c] for c in names])
    with open(path, "w") as fh:
        fh.write(",".join(["t"] + names) + "\n")
        for row in data:
            fh.write(",".join("%.17g" % v for v in row) + "\n")


def lumped():
    fs, n = 200.0, 401
    truth = {}
    params = {
        ("kv", 1): {"I": [[1.5]], "C": [[12.0]], "K": [[400.0]]},
        ("kv", 2): {"I": [[1.8, 0.3], [0.3, 1.2]], "C": [[15.0, 3.0], [3.0, 10.0]],
                    "K": [[500.0, 100.0], [100.0, 300.0]]},
        ("pt", 1): {"I": [[1.5]], "KS": [[1500.0]], "KP": [[300.0]], "CP": [[40.0]]},
        ("pt", 2): {"I": [[1.8, 0.3], [0.3, 1.2]], "KS": [[1750.0, 250.0], [250.0, 1000.0]],
                    "KP": [[350.0, 50.0], [50.0, 200.0]], "CP": [[40.0, 6.0], [6.0, 25.0]]},
        ("duffing", 1): {"I": [[1.5]], "C": [[12.0]], "K": [[400.0]], "B": [1.5e6]},
        ("duffing", 2): {"I": [[1.8, 0.3], [0.3, 1.2]], "C": [[15.0, 3.0], [3.0, 10.0]],
                         "K": [[500.0, 100.0], [100.0, 300.0]], "B": [2.0e6, 1.0e6]},
    }
    cases = [(m, d, "foh") for (m, d) in params] + [("kv", 2, "zoh")]
    for i, (model, dof, hold) in enumerate(cases):
        rng = np.random.default_rng(1000 + i)
        forces = band_limited_forces(rng, n, dof, fs)
        x0 = [0.004 * (j + 1) for j in range(dof)]
        v0 = [-0.02 * (j + 1) for j in range(dof)]
        q0 = [0.002 * (j + 1) for j in range(dof)] if model == "pt" else []
        x = simulate(model, params[(model, dof)], dof, forces, fs, x0 + v0 + q0, hold)
        name = "%s%d%s" % (model, dof, "" if hold == "foh" else "_zoh")
        t = np.arange(n) / fs
        cols = {}
        for j in range(dof):
            cols["f%d" % (j + 1)] = forces[:, j]
        for j in range(dof):
            cols["x%d" % (j + 1)] = x[:, j]
        write_trial(os.path.join(HERE, name + ".csv"), t, cols)
        p = dict(params[(model, dof)])
        if "B" in p:
            p["B"] = np.diag(p["B"]).tolist()
        truth[name] = {"model": model, "dof": dof, "hold": hold, "parameters": p,
                       "x0": x0, "v0": v0, "q0": q0}
    with open(os.path.join(HERE, "lumped_truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)


# Piovesan 2012 Table 1 arm (same numbers as models::ArmParameters defaults).
L1, L2 = 0.29, 0.4


def inverse_kinematics(x, y):
    c2 = (x**2 + y**2 - L1**2 - L2**2) / (2 * L1 * L2)
    th2 = np.arccos(np.clip(c2, -1, 1))
    th1 = np.arctan2(y, x) - np.arctan2(L2 * np.sin(th2), L1 + L2 * np.cos(th2))
    return th1, th2


def min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4), \
        (60 * s - 180 * s**2 + 120 * s**3)


def regress():
    fs = 1000.0
    posture = np.array([0.4, 0.0])
    M = np.array([[2.0, 0.2], [0.2, 1.5]])
    B0 = np.array([[12.0, 3.0], [3.0, 8.0]])
    K0 = np.array([[600.0, 150.0], [150.0, 400.0]])
    onsets = [2.5, 3.0]
    scale = {2.5: 1.0, 3.0: 1.5}
    truth = {"posture_m": posture.tolist(), "M_kg": M.tolist(), "groups": []}
    for onset in onsets:
        K, B = K0 * scale[onset], B0 * scale[onset]
        truth["groups"].append({"onset_s": onset, "K_n_per_m": K.tolist(),
                                "B_ns_per_m": B.tolist()})
        k0 = int(round((onset - 0.25) * fs))
        idx = np.arange(k0, int(round((onset + 0.35) * fs)) + 1)
        t = idx / fs
        for d in range(8):
            ang = d * np.pi / 4
            u = np.array([np.cos(ang), np.sin(ang)])
            # force pulse: piecewise-constant force, exact solution per piece with solve_ivp
            A = np.block([[np.zeros((2, 2)), np.eye(2)],
                          [-np.linalg.solve(M, K), -np.linalg.solve(M, B)]])
            F = np.where(((t >= onset - 1e-9) & (t < onset + 0.2 - 1e-9))[:, None], 5.0 * u, 0.0)
            dx = np.zeros((len(t), 2))
            s = np.zeros(4)
            for piece_start, piece_end, force in ((onset, onset + 0.2, 5.0 * u),
                                                   (onset + 0.2, t[-1], np.zeros(2))):
                mask = (t >= piece_start - 1e-9) & (t <= piece_end + 1e-9)
                c = np.concatenate([np.zeros(2), np.linalg.solve(M, force)])
                sol = solve_ivp(lambda _t, z, c=c: A @ z + c, (piece_start, piece_end), s,
                                method="DOP853", rtol=1e-12, atol=1e-15, t_eval=t[mask])
                dx[mask] = sol.y[:2].T
                s = sol.y[:, -1]
            xy = posture + dx
            th1, th2 = inverse_kinematics(xy[:, 0], xy[:, 1])
            write_trial(os.path.join(HERE, "pulse_%.1f_d%d.csv" % (onset, d)), t,
                        {"th1": th1, "th2": th2, "x": xy[:, 0], "y": xy[:, 1],
                         "fx": F[:, 0], "fy": F[:, 1]})
            # displacement ramp-and-hold (minimum jerk, 100 ms up, 100 ms hold, 100 ms down)
            T = 0.1
            up, upv, upa = min_jerk((t - onset) / T)
            dn, dnv, dna = min_jerk((t - onset - 2 * T) / T)
            r, rv, ra = up - dn, (upv - dnv) / T, (upa - dna) / T**2
            dx = 0.008 * np.outer(r, u)
            dv = 0.008 * np.outer(rv, u)
            da = 0.008 * np.outer(ra, u)
            F = da @ M.T + dv @ B.T + dx @ K.T
            xy = posture + dx
            th1, th2 = inverse_kinematics(xy[:, 0], xy[:, 1])
            write_trial(os.path.join(HERE, "ramp_%.1f_d%d.csv" % (onset, d)), t,
                        {"th1": th1, "th2": th2, "x": xy[:, 0], "y": xy[:, 1],
                         "fx": F[:, 0], "fy": F[:, 1]})
    with open(os.path.join(HERE, "regress_truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)


def interpolation():
    """PCHIP and Savitzky-Golay references (scipy PchipInterpolator, savgol_filter mode=interp)."""
    from scipy.interpolate import PchipInterpolator
    from scipy.signal import savgol_filter
    x = [2.6, 3.1, 3.6, 4.1, 4.6, 5.0]
    y = [[35.0, 5.0], [36.0, 5.5], [52.0, 3.0], [80.0, 3.0], [84.0, 7.0], [70.0, 9.5]]
    t = np.linspace(2.4, 5.1, 55).tolist()
    p = PchipInterpolator(np.array(x), np.array(y))
    rng = np.random.default_rng(5)
    sig = np.cumsum(rng.standard_normal(60))
    dt = 0.001
    out = {"pchip": {"x": x, "y": y, "t": t, "values": p(np.array(t)).tolist()},
           "savgol": {"x": sig.tolist(), "window": 11, "order": 4, "dt": dt,
                      "value": savgol_filter(sig, 11, 4, mode="interp").tolist(),
                      "first": savgol_filter(sig, 11, 4, deriv=1, delta=dt, mode="interp").tolist(),
                      "second": savgol_filter(sig, 11, 4, deriv=2, delta=dt,
                                              mode="interp").tolist()}}
    with open(os.path.join(HERE, "interpolation_ref.json"), "w") as fh:
        json.dump(out, fh)


if __name__ == "__main__":
    lumped()
    regress()
    interpolation()
