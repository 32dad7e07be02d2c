#!/usr/bin/env python3
"""Independent reference trials for tests/models/test_simulate.cpp (scipy 1.10, numpy 1.24).

Written from the papers, not from the C++ code: the two-link arm of Piovesan et al. 2012 eqs 8-10
(Table 1 parameters), integrated in ABSOLUTE joint angles (the C++ simulator integrates deviations
from the reference) with solve_ivp DOP853 at rtol 1e-11, atol 1e-13, split at every discontinuity
of the force or the profiles (and at every knot of a matrix table: the rotating-stiffness case
reads its tables from arm_posture_rotating_table.json, which this script writes and the C++ test
reads as its spec).  Also: scipy.signal.butter/sosfilt outputs and lsim (first-order
hold) of the linear endpoint model.  Run: /usr/bin/python3 make_fixtures.py (writes the CSVs here).
"""
import json

import numpy as np
from scipy.integrate import solve_ivp
from scipy import signal

L1, R1, M1, I1 = 0.29, 0.132, 1.99, 0.0161
L2, R2, M2, I2 = 0.4, 0.17, 1.10, 0.0146
KAPPA = I1 + I2 + M1 * R1**2 + M2 * (L1**2 + R2**2)
BETA = M2 * L1 * R2
CHI = I2 + M2 * R2**2
K0 = np.array([[35.0, 5.0], [5.0, 20.0]])
C0 = 0.01 * K0


def mass(th):
    c2 = np.cos(th[1])
    return np.array([[KAPPA + 2 * BETA * c2, CHI + BETA * c2], [CHI + BETA * c2, CHI]])


def coriolis(th, w):
    b = BETA * np.sin(th[1])
    return np.array([[-b * w[1], -b * (w[0] + w[1])], [b * w[0], 0.0]])


def hand(th):
    return np.array([L1 * np.cos(th[0]) + L2 * np.cos(th[0] + th[1]),
                     L1 * np.sin(th[0]) + L2 * np.sin(th[0] + th[1])])


def jac(th):
    s1, c1 = np.sin(th[0]), np.cos(th[0])
    s12, c12 = np.sin(th[0] + th[1]), np.cos(th[0] + th[1])
    return np.array([[-L1 * s1 - L2 * s12, -L2 * s12], [L1 * c1 + L2 * c12, L2 * c12]])


def ik(p):
    c2 = (p @ p - L1**2 - L2**2) / (2 * L1 * L2)
    t2 = np.arccos(c2)
    t1 = np.arctan2(p[1], p[0]) - np.arctan2(L2 * np.sin(t2), L1 + L2 * np.cos(t2))
    return np.array([t1, t2])


def reference(task, t):
    """theta, theta', theta'' of the task; hand velocity by the Jacobian, acceleration by
    numerically differentiating J^-1 would be inexact, so use the closed form J' = dJ/dt."""
    if task["kind"] == "posture":
        th = ik(np.array(task["hand"]))
        return th, np.zeros(2), np.zeros(2)
    start, target = np.array(task["start"]), np.array(task["target"])
    b, q, e = task["rate"], task["q"], task["mid"]
    s = 1 / (1 + q * np.exp(-b * (t - e)))
    sd = b * s * (1 - s)
    sdd = b * sd * (1 - 2 * s)
    g = target - start
    th = ik(start + s * g)
    j = jac(th)
    w = np.linalg.solve(j, sd * g)
    # dJ/dt by the chain rule
    s1, c1 = np.sin(th[0]), np.cos(th[0])
    s12, c12 = np.sin(th[0] + th[1]), np.cos(th[0] + th[1])
    w12 = w[0] + w[1]
    jd = np.array([[-L1 * c1 * w[0] - L2 * c12 * w12, -L2 * c12 * w12],
                   [-L1 * s1 * w[0] - L2 * s12 * w12, -L2 * s12 * w12]])
    a = np.linalg.solve(j, sdd * g - jd @ w)
    return th, w, a


def profile(kind, t, start, horizon):
    if kind == "constant" or t < start:
        return 1.0
    if kind == "sigmoid":
        return 4 / (1 + np.exp(-4 * (t - 0.75 * horizon))) + 1
    if kind == "sharp":
        return 4 / (1 + np.exp(-30 * (t - 0.75 * horizon))) + 1
    if kind == "sinlin":
        return np.sin(0.8 * np.pi * t) + 1.6 * t - 4
    raise ValueError(kind)


def simulate(case):
    fs, dur = case["fs"], case["duration"]
    n = int(round(dur * fs))
    times = np.arange(n) / fs
    task = case["task"]
    kp, cp = case["kprof"], case["cprof"]
    start, horizon = case["profile_start"], case["horizon"]
    kind = case["element"]
    ks = 5 * 2 * K0
    kpar, cpar = 2 * K0, np.abs(K0)
    bcub = 2e5 * K0

    def force(t, th, w, branch):
        f = np.zeros(2)
        for p in case["pulses"]:
            if p["onset"] <= branch < p["onset"] + p["duration"]:
                f += p["amp"] * np.array([np.cos(p["dir"]), np.sin(p["dir"])])
        r = case.get("ramp")
        if r is not None:
            tau = branch - r["onset"]
            if 0 <= tau < r["ramp"] + r["plateau"] + r["ret"]:
                u = np.array([np.cos(r["dir"]), np.sin(r["dir"])]) * r["amp"]
                tt = t - r["onset"]
                if tau < r["ramp"]:
                    s, sd = tt / r["ramp"], 1 / r["ramp"]
                elif tau < r["ramp"] + r["plateau"]:
                    s, sd = 1.0, 0.0
                else:
                    s, sd = 1 - (tt - r["ramp"] - r["plateau"]) / r["ret"], -1 / r["ret"]
                thr, wr, _ = reference(task, t)
                x, xd = hand(th), jac(th) @ w
                pr = hand(thr)
                prd = jac(thr) @ wr
                f += r["k"] * (pr + s * u - x) + r["c"] * (prd + sd * u - xd)
        return f

    tables = case.get("tables")

    def table_matrix(table, t):
        """Entry by entry np.interp of the knots (held constant outside, as np.interp does)."""
        times, values = np.array(table[0]), np.array(table[1])
        return np.array([[np.interp(t, times, values[:, i, j]) for j in range(2)]
                         for i in range(2)])

    def rhs(t, y, branch):
        th, w, z = y[0:2], y[2:4], y[4:6]
        thr, wr, ar = reference(task, t)
        # exact feedforward torque along the reference (eq 8, no gravity)
        tff = mass(thr) @ ar + coriolis(thr, wr) @ wr
        # eq 53: the profile acts from `start` on; the segment (branch) decides the side
        uk = profile(kp, max(t, start), start, horizon) if branch >= start else 1.0
        uc = profile(cp, max(t, start), start, horizon) if branch >= start else 1.0
        d, dd = th - thr, w - wr
        if kind == "kv":
            fv = -uc * C0 @ dd - uk * K0 @ d
            zr = np.zeros(2)
        elif kind == "duffing":
            fv = -uc * C0 @ dd - uk * K0 @ d - bcub @ d**3
            zr = np.zeros(2)
        elif kind == "kv_table":
            fv = -table_matrix(tables["damping"], t) @ dd - table_matrix(tables["stiffness"], t) @ d
            zr = np.zeros(2)
        elif kind == "pt":
            fv = -ks @ (d - z)
            zr = np.linalg.solve(uc * cpar, ks @ (d - z) - uk * kpar @ z)
        tau = tff + fv + jac(th).T @ force(t, th, w, branch)
        acc = np.linalg.solve(mass(th), tau - coriolis(th, w) @ w)
        return np.concatenate([w, acc, zr])

    bps = {0.0, times[-1]}
    for p in case["pulses"]:
        bps |= {p["onset"], p["onset"] + p["duration"]}
    r = case.get("ramp")
    if r is not None:
        bps |= {r["onset"], r["onset"] + r["ramp"], r["onset"] + r["ramp"] + r["plateau"],
                r["onset"] + r["ramp"] + r["plateau"] + r["ret"]}
    if kp != "constant" or cp != "constant":
        bps.add(start)
    if tables is not None:
        bps |= set(tables["stiffness"][0]) | set(tables["damping"][0])
    bps = sorted(b for b in bps if 0 <= b <= times[-1])
    th0, w0, _ = reference(task, 0.0)
    y = np.concatenate([th0, w0, np.zeros(2)])
    out = np.zeros((n, 6))
    for a, b in zip(bps[:-1], bps[1:]):
        branch = 0.5 * (a + b)
        sel = (times >= a) & (times < b) if b < times[-1] else (times >= a)
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-11, atol=1e-13,
                        t_eval=times[sel], args=(branch,), dense_output=False)
        assert sol.success, sol.message
        out[sel, :] = sol.y.T
        y = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-11, atol=1e-13,
                      args=(branch,)).y[:, -1]
    fx = np.zeros(n)
    fy = np.zeros(n)
    for i, t in enumerate(times):
        f = force(t, out[i, 0:2], out[i, 2:4], t + 1e-12)
        fx[i], fy[i] = f
    return times, out, fx, fy


def rotating_tables():
    """K(t) = R(phi) K0 R(phi)^T, phi from 0 to 30 deg along a normalised logistic over 0.2-1 s
    (knots every 50 ms from 0.2 s), and C(t) = C0 with c22 rising linearly to 3 x from 0.2 s
    (knots every 73.5 ms, between the 1 kHz samples): neither is a common factor of K0, C0."""
    tk = 0.2 + 0.05 * np.arange(17)
    sig = lambda t: 1 / (1 + np.exp(-12 * (t - 0.55)))
    phi = np.radians(30) * (sig(tk) - sig(0.2)) / (sig(1.0) - sig(0.2))
    k = []
    for a in phi:
        r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        k.append(r @ K0 @ r.T)
    tc = 0.2 + 0.0735 * np.arange(11)
    c = []
    for t in tc:
        m = C0.copy()
        m[1, 1] *= 1 + 2 * (t - 0.2) / (tc[-1] - 0.2)
        c.append(m)
    return {"stiffness": (list(tk), [x.tolist() for x in k]),
            "damping": (list(tc), [x.tolist() for x in c])}


def write_table_spec(tables, path):
    """The C++ side of the rotating-table case, as a stiffid spec (json writes doubles exactly)."""
    spec = {"model": "arm", "duration_s": 1.0, "sample_rate_hz": 1000.0,
            "task": {"kind": "posture", "hand_m": [0.4, 0.0]},
            "viscoelasticity": {
                "kind": "kelvin_voigt",
                "stiffness_table": {"time_s": tables["stiffness"][0],
                                    "stiffness_nm_per_rad": tables["stiffness"][1]},
                "damping_table": {"time_s": tables["damping"][0],
                                  "damping_nms_per_rad": tables["damping"][1]}},
            "perturbations": [{"kind": "impulse", "onset_s": 0.2, "amplitude_n": 5.0,
                               "duration_s": 0.02, "direction_deg": 135.0}],
            "integrator": {"absolute_tolerance_rad": 1e-12, "relative_tolerance": 1e-11}}
    with open(path, "w") as f:
        json.dump(spec, f, indent=1)
        f.write("\n")


CASES = {
    "arm_posture_impulse_sigmoid": dict(
        fs=1000.0, duration=1.0, task=dict(kind="posture", hand=[0.4, 0.0]), kprof="sigmoid",
        cprof="constant", profile_start=0.2, horizon=1.0, element="kv",
        pulses=[dict(onset=0.2, duration=0.02, amp=5.0, dir=np.pi / 4)]),
    "arm_reach_pulse_sharp": dict(
        fs=1000.0, duration=2.0, task=dict(kind="reach", start=[0.25, 0.0], target=[0.55, 0.0],
                                           rate=4.0, q=1.0, mid=1.0),
        kprof="sharp", cprof="sharp", profile_start=1.0, horizon=2.0, element="kv",
        pulses=[dict(onset=1.0, duration=0.2, amp=5.0, dir=3 * np.pi / 4)]),
    "arm_posture_ramp": dict(
        fs=1000.0, duration=0.8, task=dict(kind="posture", hand=[0.4, 0.0]), kprof="constant",
        cprof="constant", profile_start=2.5, horizon=5.0, element="kv", pulses=[],
        ramp=dict(onset=0.1, amp=0.008, ramp=0.1, plateau=0.1, ret=0.1, dir=np.pi / 2,
                  k=2e4, c=250.0)),
    "arm_posture_duffing": dict(
        fs=1000.0, duration=0.6, task=dict(kind="posture", hand=[0.4, 0.0]), kprof="constant",
        cprof="constant", profile_start=2.5, horizon=5.0, element="duffing",
        pulses=[dict(onset=0.1, duration=0.02, amp=5.0, dir=np.pi)]),
    "arm_posture_poynting_thomson": dict(
        fs=1000.0, duration=0.6, task=dict(kind="posture", hand=[0.4, 0.0]), kprof="constant",
        cprof="constant", profile_start=2.5, horizon=5.0, element="pt",
        pulses=[dict(onset=0.1, duration=0.02, amp=5.0, dir=-np.pi / 2)]),
    "arm_posture_rotating_table": dict(
        fs=1000.0, duration=1.0, task=dict(kind="posture", hand=[0.4, 0.0]), kprof="constant",
        cprof="constant", profile_start=2.5, horizon=5.0, element="kv_table",
        tables=rotating_tables(),
        pulses=[dict(onset=0.2, duration=0.02, amp=5.0, dir=np.radians(135.0))]),
}

if __name__ == "__main__":
    import sys
    only = sys.argv[1:]  # case names to (re)make; all, with the filters and lsim, when empty
    write_table_spec(CASES["arm_posture_rotating_table"]["tables"], "arm_posture_rotating_table.json")
    for name, case in CASES.items():
        if only and name not in only:
            continue
        t, y, fx, fy = simulate(case)
        data = np.column_stack([t, fx, fy, y[:, 0], y[:, 1]])
        np.savetxt(f"{name}.csv", data, delimiter=",", header="t,fx,fy,th1,th2", comments="",
                   fmt="%.17g")
    if only:
        sys.exit(0)
    # Butterworth designs and a filtered test signal.
    n = 400
    k = np.arange(n)
    x = np.sin(0.07 * k) + 0.5 * np.cos(0.9 * k) + ((k * 7919) % 101) / 101.0 - 0.5
    rows = []
    for order, fc, fs in [(4, 9.0, 50.0), (3, 100.0, 4000.0), (5, 20.0, 1000.0)]:
        sos = signal.butter(order, fc, fs=fs, output="sos")
        rows.append(signal.sosfilt(sos, x))
    np.savetxt("butterworth.csv", np.column_stack([x] + rows), delimiter=",",
               header="x,y_4_9_50,y_3_100_4000,y_5_20_1000", comments="", fmt="%.17g")
    # Linear endpoint model by lsim (first-order hold on the input) and the ZOH discretization.
    i_m = np.array([[1.2, 0.1], [0.1, 0.9]])
    b_m = np.array([[10.0, 1.0], [1.0, 7.0]])
    k_m = np.array([[250.0, 40.0], [40.0, 180.0]])
    ii = np.linalg.inv(i_m)
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-ii @ k_m, -ii @ b_m]])
    bb = np.vstack([np.zeros((2, 2)), ii])
    c = np.hstack([np.eye(2), np.zeros((2, 2))])
    fs = 50.0
    tt = np.arange(300) / fs
    u = np.column_stack([np.sin(2 * np.pi * 1.3 * tt) + 0.3 * np.cos(2 * np.pi * 7.1 * tt),
                         np.cos(2 * np.pi * 2.9 * tt) * np.exp(-0.2 * tt)])
    x0 = np.array([0.002, -0.001, 0.01, 0.0])
    _, y_foh, _ = signal.lsim((a, bb, c, np.zeros((2, 2))), u, tt, X0=x0, interp=True)
    ad, bd, cd, dd, _ = signal.cont2discrete((a, bb, c, np.zeros((2, 2))), 1 / fs, method="zoh")
    _, y_zoh, _ = signal.dlsim((ad, bd, cd, dd, 1 / fs), u, x0=x0)
    np.savetxt("endpoint_lsim.csv", np.column_stack([tt, u, y_foh, y_zoh]), delimiter=",",
               header="t,fx,fy,x_foh,y_foh,x_zoh,y_zoh", comments="", fmt="%.17g")
