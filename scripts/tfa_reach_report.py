#!/usr/bin/python3
"""Issue 7's two reports on `stiffid tfa`: normalized force of the non-linear and higher-order
trials, and K(t), C(t) on movement (reach) trials against the viscoelastic and the effective truth.

  scripts/tfa_reach_report.py [--stiffid build/stiffid] [--part a|b|ab] [--seeds 1,2,3]
                              [--directions 45,90,135] [--keep DIR] [-o REPORT.md]

Needs numpy and scipy (Debian python3-numpy, python3-scipy); the tests do not use this script.
Every trial is simulated with `stiffid simulate SPEC --truth TRUTH --seed N` and identified with
`stiffid tfa TRIAL --angles th1,th2 --onset 2.5 [--method spectrogram]`, default options
otherwise; reach trials add `--baseline` = the simulator's reference angles (the unperturbed
trajectory assumed known, as Piovesan 2012 did), posture trials use the default baseline (mean of
the 0.2 s before the onset).

(a) Normalized force (Piovesan 2012 section "Normalized force in Non-Linear and Higher order
    Systems", Fig 12). Specs models/specs/piovesan_reach_duffing.json and
    piovesan_reach_poynting_thomson.json (10 dB, 5 N x 20 ms impulse along y = 90 deg) and posture
    versions (same viscoelasticity, task and impulse direction as above, posture task of
    piovesan_posture_constant.json), noise seeds --seeds. For each tfa frame t_m and mode j:
      estimate   sigma^_j = normalized_force.sigma[j] = eta_j^2 q_j + 2 Gamma_j q_j' (consistent
                 eq 49, estimators/normalized_force.hpp),
      viscoelastic truth   sigma_j = [P^T M^-1/2 tau_el]_j,
      effective truth      sigma_eff_j = -[P^T M^1/2 d'']_j,
    with P = the tfa's "eigenvectors" and M = its "M_kg_m2" (M(theta_ref(t_m))) at that frame (so
    the error measures the force, not the mode frame), d = theta - theta_ref from the truth JSON
    (noise-free, 4 kHz), d' likewise from the velocities, d'' = numpy.gradient(d') and the
    restoring torque tau_el = -f_visc of the simulated element:
      Duffing           tau_el = K d + C d' + B d.^3            (elementwise cube)
      Poynting-Thomson  tau_el = K_S (d - z),  C_P z' = K_S (d - z) - K_P z,  z(0) = 0, integrated
                        with scipy solve_ivp (DOP853) on a cubic spline of d.
    Error E_sigma_j = 100 RMS(sigma^_j - sigma_j) / RMS(sigma_j) over the frames in 2.6-4.5 s and
    2.6-3.175 s (all frames, valid or not; frames whose estimate is null are left out and counted).
    Each case is also run noise-free (one trial). Also: the eigenvalues of the linearised posture
    systems (is each mode oscillatory?).

(b) Movement trials, Kelvin-Voigt: piovesan_reach_constant.json and piovesan_reach_sigmoid.json at
    20 dB and noise-free, impulse at --directions, seed 1. Percentage RMS error
    100 RMS(est - true) / RMS(true) of k11, k12, k22, c11, c12, c22 over 2.6-3.175 s and
    2.6-4.5 s against (i) the truth JSON's stiffness_nm_per_rad / damping_nms_per_rad and (ii)
    the effective K_eff = K + sym(K_rb), C_eff = C + sym(C_rb), sym(X) = (X + X^T)/2, where
      K_rb = d/dtheta [M(theta) theta_ref'' + H(theta, theta_ref') theta_ref'] at theta_ref,
      C_rb = d/dtheta' [H(theta_ref, theta') theta'] at theta_ref',
    so that M(theta_ref) d'' + (C + C_rb) d' + (K + K_rb) d = 0 is the deviation dynamics linearised
    about the reference trajectory (central differences, step 1e-6, of an independent arm model:
    Table 1, M and H as tests/data/tfa/make_posture_trials.py; theta_ref, theta_ref',
    theta_ref'' from the reach of eqs 50-51 by inverse kinematics). K_rb is not symmetric (its
    first column is zero: nothing depends on theta1) and the tfa returns symmetric matrices, so
    the symmetric part is the reference.

Checks printed first: the arm model's reference trajectory against the truth's; the equations of
motion rebuilt from the truth and the element law (residual relative to the viscoelastic torque);
K_rb, C_rb by central differences with two steps and the closed form; K_rb = C_rb = 0 at a
posture. Conventions: SI units (rad, N m/rad, N m s/rad, kg m^2); normalized forces in
sqrt(kg) m rad/s^2; every percentage is over tfa frames (their t_s), truth interpolated linearly
from the 4 kHz samples (frames fall on samples).
"""
import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from tfa_cases import fmt, rms_error, set_impulse, set_noise

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SPECS = os.path.join(ROOT, "models", "specs")
INTERVALS = [(2.6, 4.5), (2.6, 3.175)]
COEFFICIENTS = [("k11", "K", 0, 0), ("k12", "K", 0, 1), ("k22", "K", 1, 1),
                ("c11", "C", 0, 0), ("c12", "C", 0, 1), ("c22", "C", 1, 1)]
METHODS = ["modal", "spectrogram"]
PAPER_SIGMA = {"duffing": (23.1, 19.4), "poynting_thomson": (18.4, 26.9)}


# ---------------------------------------------------------------- independent arm model (Table 1)
class Arm:
    def __init__(self, p=None):
        p = p or {}
        self.l1, self.r1 = p.get("l1_m", 0.29), p.get("r1_m", 0.132)
        self.m1, self.i1 = p.get("m1_kg", 1.99), p.get("iz1_kg_m2", 0.0161)
        self.l2, self.r2 = p.get("l2_m", 0.4), p.get("r2_m", 0.17)
        self.m2, self.i2 = p.get("m2_kg", 1.10), p.get("iz2_kg_m2", 0.0146)
        self.kappa = self.i1 + self.i2 + self.m1 * self.r1**2 + self.m2 * (self.l1**2 + self.r2**2)
        self.beta = self.m2 * self.l1 * self.r2
        self.chi = self.i2 + self.m2 * self.r2**2

    def inertia(self, th):
        c2 = np.cos(th[1])
        return np.array([[self.kappa + 2 * self.beta * c2, self.chi + self.beta * c2],
                         [self.chi + self.beta * c2, self.chi]])

    def coriolis(self, th, w):  # H(theta, theta') of eq 8
        s2 = np.sin(th[1])
        return np.array([[-self.beta * s2 * w[1], -self.beta * s2 * (w[0] + w[1])],
                         [self.beta * s2 * w[0], 0.0]])

    def jacobian(self, th):
        s1, s12 = np.sin(th[0]), np.sin(th[0] + th[1])
        c1, c12 = np.cos(th[0]), np.cos(th[0] + th[1])
        return np.array([[-self.l1 * s1 - self.l2 * s12, -self.l2 * s12],
                         [self.l1 * c1 + self.l2 * c12, self.l2 * c12]])

    def jacobian_rate(self, th, w):
        s1, s12 = np.sin(th[0]), np.sin(th[0] + th[1])
        c1, c12 = np.cos(th[0]), np.cos(th[0] + th[1])
        w12 = w[0] + w[1]
        return np.array([[-self.l1 * c1 * w[0] - self.l2 * c12 * w12, -self.l2 * c12 * w12],
                         [-self.l1 * s1 * w[0] - self.l2 * s12 * w12, -self.l2 * s12 * w12]])

    def inverse_kinematics(self, p):  # elbow-flexed branch (theta2 > 0)
        c2 = (p[0]**2 + p[1]**2 - self.l1**2 - self.l2**2) / (2 * self.l1 * self.l2)
        th2 = np.arccos(c2)
        th1 = np.arctan2(p[1], p[0]) - np.arctan2(self.l2 * np.sin(th2), self.l1 + self.l2 * np.cos(th2))
        return np.array([th1, th2])

    def torque(self, th, w, a):  # M(theta) theta'' + H(theta, theta') theta'
        return self.inertia(th) @ a + self.coriolis(th, w) @ w

    def reference(self, task, t):
        """theta_ref, theta_ref', theta_ref'' (each 2) at time t of a posture or reach task."""
        if task["kind"] == "posture":
            return self.inverse_kinematics(np.array(task["hand_m"])), np.zeros(2), np.zeros(2)
        if task["kind"] != "reach":
            raise ValueError("task kind " + task["kind"])
        d, g = np.array(task["start_m"]), np.array(task["target_m"]) - np.array(task["start_m"])
        b, q, e = task.get("rate_per_s", 4.0), task.get("q", 1.0), task.get("midpoint_s", 2.5)
        s = 1.0 / (1.0 + q * np.exp(-b * (t - e)))
        s1 = b * s * (1 - s)
        s2 = b * s1 * (1 - 2 * s)
        th = self.inverse_kinematics(d + g * s)
        jac = self.jacobian(th)
        w = np.linalg.solve(jac, g * s1)
        a = np.linalg.solve(jac, g * s2 - self.jacobian_rate(th, w) @ w)
        return th, w, a

    def rigid_body_terms(self, th, w, a, step=1e-6):
        """K_rb = d/dtheta [M(theta) a + H(theta, w) w], C_rb = d/dw [H(th, w) w] (central
        differences), both (2 x 2) at the reference (th, w, a)."""
        k, c = np.zeros((2, 2)), np.zeros((2, 2))
        for i in range(2):
            e = np.zeros(2)
            e[i] = step
            k[:, i] = (self.torque(th + e, w, a) - self.torque(th - e, w, a)) / (2 * step)
            c[:, i] = (self.coriolis(th, w + e) @ (w + e) - self.coriolis(th, w - e) @ (w - e)) / (2 * step)
        return k, c

    def rigid_body_closed_form(self, th, w, a):
        """The same from the derivative by hand: only theta2 enters M and H."""
        s2, c2, b = np.sin(th[1]), np.cos(th[1]), self.beta
        dm = np.array([[-2 * b * s2, -b * s2], [-b * s2, 0.0]])
        hw = np.array([-(2 * w[0] * w[1] + w[1]**2), w[0]**2])  # H w = b s2 hw
        k = np.zeros((2, 2))
        k[:, 1] = dm @ a + b * c2 * hw
        c = b * s2 * np.array([[-2 * w[1], -2 * (w[0] + w[1])], [2 * w[0], 0.0]])
        return k, c


def sym(x):
    return 0.5 * (x + np.swapaxes(x, -1, -2))


def spd_power(m, power):
    v, u = np.linalg.eigh(m)
    return (u * v**power) @ u.T


# ---------------------------------------------------------------- running stiffid
def run(cmd):
    done = subprocess.run(["nice"] + cmd, capture_output=True, text=True)
    return done.returncode, done.stderr.strip()


def load_spec(name):
    with open(os.path.join(SPECS, name)) as f:
        return json.load(f)


class Trial:
    """One simulated trial with its truth and the tfa results of both methods."""

    def __init__(self, stiffid, spec, seed, work, tag):
        self.spec, self.tag = spec, tag
        base = os.path.join(work, tag)
        spec_path, self.csv, truth_path = base + "_spec.json", base + ".csv", base + "_truth.json"
        with open(spec_path, "w") as f:
            json.dump(spec, f)
        rc, err = run([stiffid, "simulate", spec_path, "-o", self.csv, "--truth", truth_path,
                       "--seed", str(seed)])
        if rc != 0:
            sys.exit("stiffid simulate %s failed (%d): %s" % (tag, rc, err))
        with open(truth_path) as f:
            truth = json.load(f)
        self.t = np.array(truth["time_s"])
        self.th = np.array(truth["joint_angles_rad"])
        self.w = np.array(truth["joint_velocities_rad_per_s"])
        self.th_ref = np.array(truth["reference_joint_angles_rad"])
        self.w_ref = np.array(truth["reference_joint_velocities_rad_per_s"])
        self.k = np.array(truth["stiffness_nm_per_rad"])
        self.c = np.array(truth["damping_nms_per_rad"])
        self.series = np.array(truth["series_stiffness_nm_per_rad"]) if "series_stiffness_nm_per_rad" in truth else None
        self.cubic = np.array(truth["cubic_stiffness_nm_per_rad3"]) if "cubic_stiffness_nm_per_rad3" in truth else None
        self.kind = spec["viscoelasticity"]["kind"]
        self.d, self.dd = self.th - self.th_ref, self.w - self.w_ref
        self.ddd = np.gradient(self.dd, self.t, axis=0)
        self.tfa = {}
        self.failure = {}
        tfa_args = [self.csv, "--angles", "th1,th2", "--onset", "2.5"]
        if spec["task"]["kind"] == "reach":
            baseline = base + "_baseline.csv"
            with open(baseline, "w") as f:
                f.write("t,th1,th2\n")
                for ti, (a, b) in zip(self.t, self.th_ref):
                    f.write("%.17g,%.17g,%.17g\n" % (ti, a, b))
            tfa_args += ["--baseline", baseline]
        for method in METHODS:
            out = base + "_tfa_%s.json" % method
            rc, err = run([stiffid, "tfa"] + tfa_args + ["--method", method, "-o", out])
            if rc != 0:
                last = err.splitlines()[-1] if err else ""
                self.failure[method] = "exit %d: %s" % (rc, last.replace(os.path.dirname(self.csv) + os.sep, ""))
                continue
            with open(out) as f:
                self.tfa[method] = json.load(f)

    def as_matrix(self, x):  # [S][2][2] or [2][2] -> (S x 2 x 2)
        return np.broadcast_to(x, (self.t.size, 2, 2)) if x.ndim == 2 else x

    def elastic_torque(self):
        """tau_el = -f_visc (S x 2) of the simulated element along the true deviation (cached)."""
        if not hasattr(self, "_tau_el"):
            self._tau_el = self._elastic_torque()
        return self._tau_el

    def _elastic_torque(self):
        k, c = self.as_matrix(self.k), self.as_matrix(self.c)
        if self.kind in ("kelvin_voigt", "duffing"):
            tau = np.einsum("sij,sj->si", k, self.d) + np.einsum("sij,sj->si", c, self.dd)
            if self.kind == "duffing":
                tau += np.einsum("sij,sj->si", self.as_matrix(self.cubic), self.d**3)
            return tau
        if self.kind != "poynting_thomson":
            raise ValueError(self.kind)
        # K = K_P (parallel spring), C = C_P, series = K_S; profiles constant in eq 56
        kp, cp, ks = k[0], c[0], self.as_matrix(self.series)[0]
        if not (np.allclose(k, kp) and np.allclose(c, cp) and np.allclose(self.as_matrix(self.series), ks)):
            raise ValueError("time-varying Poynting-Thomson parameters are not handled")
        spline = CubicSpline(self.t, self.d, axis=0)
        cpi = np.linalg.inv(cp)
        sol = solve_ivp(lambda t, z: cpi @ (ks @ (spline(t) - z) - kp @ z), (self.t[0], self.t[-1]),
                        np.zeros(2), method="DOP853", t_eval=self.t, rtol=1e-10, atol=1e-14,
                        max_step=2e-3)
        self.z = sol.y.T
        return (ks @ (self.d - self.z).T).T

    def at(self, x, t):  # truth series (S x ...) at the times t, linear interpolation
        flat = x.reshape(self.t.size, -1)
        return np.stack([np.interp(t, self.t, flat[:, i]) for i in range(flat.shape[1])],
                        axis=1).reshape((t.size,) + x.shape[1:])


def frame_arrays(tfa):
    t = np.array(tfa["t_s"], dtype=float)
    p = np.moveaxis(np.array(tfa["eigenvectors"], dtype=float), 2, 0)   # (T x 2 x 2), columns = modes
    m = np.moveaxis(np.array(tfa["M_kg_m2"], dtype=float), 2, 0)
    return t, p, m


# ---------------------------------------------------------------- checks
def check_model(arm, trial, lo=2.6, hi=4.5):
    """Reference trajectory of the arm model vs the truth; the equations of motion rebuilt from
    the truth and the element law: residual M(th) th'' + H th' - tau_ff + tau_el, relative."""
    task = trial.spec["task"]
    sel = np.nonzero((trial.t >= lo) & (trial.t <= hi))[0][::20]
    ref = [arm.reference(task, ti) for ti in trial.t[sel]]
    e_th = max(np.abs(r[0] - trial.th_ref[i]).max() for r, i in zip(ref, sel))
    e_w = max(np.abs(r[1] - trial.w_ref[i]).max() for r, i in zip(ref, sel))
    tau_el = trial.elastic_torque()
    res, scale = [], []
    for r, i in zip(ref, sel):
        th, w, a = trial.th[i], trial.w[i], r[2] + trial.ddd[i]
        tau_ff = arm.torque(r[0], r[1], r[2])
        res.append(arm.torque(th, w, a) - tau_ff + tau_el[i])
        scale.append(tau_el[i])
    return e_th, e_w, 100.0 * np.sqrt(np.mean(np.square(res)) / np.mean(np.square(scale)))


def check_rigid_body(arm, task_reach, task_posture):
    worst_step, worst_closed = 0.0, 0.0
    for t in np.linspace(2.5, 4.5, 9):
        th, w, a = arm.reference(task_reach, t)
        k1, c1 = arm.rigid_body_terms(th, w, a, 1e-6)
        k2, c2 = arm.rigid_body_terms(th, w, a, 1e-4)
        k3, c3 = arm.rigid_body_closed_form(th, w, a)
        scale = max(np.abs(k3).max(), np.abs(c3).max())
        worst_step = max(worst_step, np.abs(k1 - k2).max() / scale, np.abs(c1 - c2).max() / scale)
        worst_closed = max(worst_closed, np.abs(k1 - k3).max() / scale, np.abs(c1 - c3).max() / scale)
    th, w, a = arm.reference(task_posture, 3.0)
    kp, cp = arm.rigid_body_terms(th, w, a)
    return worst_step, worst_closed, max(np.abs(kp).max(), np.abs(cp).max())


def linear_poles(arm, visc, hand=(0.4, 0.0)):
    """Eigenvalues of the posture system linearised at d = 0 (states d, d' [, z])."""
    m = arm.inertia(arm.inverse_kinematics(np.array(hand)))
    mi, z, i = np.linalg.inv(m), np.zeros((2, 2)), np.eye(2)
    k, c = np.array(visc["stiffness_nm_per_rad"]), np.array(visc["damping_nms_per_rad"])
    if visc["kind"] == "poynting_thomson":
        ks, cpi = np.array(visc["series_stiffness_nm_per_rad"]), np.linalg.inv(c)
        a = np.block([[z, i, z], [-mi @ ks, z, mi @ ks], [cpi @ ks, z, -cpi @ (ks + k)]])
    else:
        a = np.block([[z, i], [-mi @ k, -mi @ c]])
    ev = np.linalg.eigvals(a)
    return ev[np.argsort(np.abs(ev.imag) + 1e-9 * np.abs(ev.real))]


def describe_poles(ev):
    out = []
    for e in ev:
        if e.imag < -1e-9:
            continue
        if abs(e.imag) > 1e-9:
            out.append("%.2f Hz, zeta %.3f (%.2f +- %.2fi 1/s)" % (e.imag / (2 * np.pi), -e.real / abs(e), e.real, e.imag))
        else:
            out.append("real %.2f 1/s" % e.real)
    return "; ".join(out)


# ---------------------------------------------------------------- part (a)
def posture_version(spec):
    posture = load_spec("piovesan_posture_constant.json")
    out = copy.deepcopy(spec)
    out["task"] = posture["task"]
    return out


def sigma_errors(trial, method):
    """Per interval and mode: E vs the viscoelastic and the effective truth, frames used, null."""
    tfa = trial.tfa[method]
    t, p, m = frame_arrays(tfa)
    sigma_hat = np.array(tfa["normalized_force"]["sigma"], dtype=float).T    # (T x 2)
    tau = trial.at(trial.elastic_torque(), t)
    dd = trial.at(trial.ddd, t)
    m_inv_half = np.array([spd_power(x, -0.5) for x in m])
    m_half = np.array([spd_power(x, 0.5) for x in m])
    sigma_visc = np.einsum("tij,tj->ti", np.swapaxes(p, 1, 2) @ m_inv_half, tau)
    sigma_eff = -np.einsum("tij,tj->ti", np.swapaxes(p, 1, 2) @ m_half, dd)
    valid = np.array(tfa["valid"], dtype=bool).T
    out = {}
    for lo, hi in INTERVALS:
        sel = (t >= lo) & (t <= hi)
        for j in range(2):
            ok = sel & np.isfinite(sigma_hat[:, j])
            out[(lo, hi, j)] = (rms_error(sigma_hat[ok, j], sigma_visc[ok, j]),
                                rms_error(sigma_hat[ok, j], sigma_eff[ok, j]),
                                int((sel & ~np.isfinite(sigma_hat[:, j])).sum()),
                                100.0 * valid[sel, j].mean())
    f = np.array(tfa["f_hz"], dtype=float)
    sel = (t >= 2.6) & (t <= 3.175)
    out["f_hz"] = np.nanmean(f[:, sel], axis=1)
    return out


def part_a(stiffid, seeds, work, arm, lines):
    models = [("duffing", "piovesan_reach_duffing.json"),
              ("poynting_thomson", "piovesan_reach_poynting_thomson.json")]
    rows, checks, summary = [], [], {}
    for model, name in models:
        reach = load_spec(name)
        set_impulse(reach, 90.0)
        set_noise(reach, 10.0)
        for task, spec10 in (("reach", reach), ("posture", posture_version(reach))):
            free = copy.deepcopy(spec10)
            set_noise(free, None)
            for seed, spec in [(s, spec10) for s in seeds] + [(0, free)]:
                snr = "10 dB" if spec is spec10 else "none"
                tag = "a_%s_%s_%s_%d" % (model, task, snr.replace(" ", ""), seed)
                trial = Trial(stiffid, spec, max(seed, 1), work, tag)
                if spec is free:
                    e_th, e_w, res = check_model(arm, trial)
                    ratio = ""
                    if model == "duffing":
                        cub = np.abs(np.einsum("ij,sj->si", trial.as_matrix(trial.cubic)[0], trial.d**3)).max(0)
                        lin = np.abs(np.einsum("ij,sj->si", trial.as_matrix(trial.k)[0], trial.d)).max(0)
                        ratio = "; peak |B d^3| / peak |K d| = %.2f, %.2f (joints 1, 2)" % tuple(cub / lin)
                    checks.append("- %s %s (noise-free): reference angles %.1e rad, rates %.1e rad/s off "
                                  "the truth's; equations of motion rebuilt from the truth and the "
                                  "element law: residual %.2g %% of the viscoelastic torque over "
                                  "2.6-4.5 s; peak |d| = %.4f, %.4f rad%s"
                                  % (model, task, e_th, e_w, res, *np.abs(trial.d).max(0), ratio))
                for method in METHODS:
                    key = (model, task, method, snr)
                    head = "| %s | %s | %s | %s | %s | " % (model.replace("_", "-"), task, method, snr,
                                                            seed if seed else "-")
                    if method not in trial.tfa:
                        rows.append(head + " | ".join(["failed"] * 8) + " | - | - | %s |" % trial.failure[method])
                        summary.setdefault(key, []).append(None)
                        continue
                    e = sigma_errors(trial, method)
                    summary.setdefault(key, []).append(e)
                    cells = []
                    for which in (0, 1):
                        for lo, hi in INTERVALS:
                            cells += [fmt(e[(lo, hi, 0)][which]), fmt(e[(lo, hi, 1)][which])]
                    nulls = sum(e[(lo, hi, j)][2] for lo, hi in INTERVALS[:1] for j in range(2))
                    valid = "%.0f / %.0f" % (e[(2.6, 4.5, 0)][3], e[(2.6, 4.5, 1)][3])
                    note = "%d null frames left out" % nulls if nulls else ""
                    rows.append(head + " | ".join(cells) + " | %.2f / %.2f | %s | %s |"
                                % (e["f_hz"][0], e["f_hz"][1], valid, note))
                print(rows[-2] + "\n" + rows[-1], flush=True)

    lines += ["## (a) Normalized viscoelastic force, Duffing and Poynting-Thomson, 10 dB, impulse at 90 deg", "",
              "Checks:", ""] + checks + [""]
    lines += ["Eigenvalues of the posture systems linearised at d = 0 (hand at (0.4, 0) m, Table 1 "
              "inertia; Duffing: its linear part; PT states d, d', z):", ""]
    for model, name in models + [("kelvin_voigt (constant)", "piovesan_reach_constant.json")]:
        lines.append("- %s: %s" % (model, describe_poles(linear_poles(arm, load_spec(name)["viscoelasticity"]))))
    lines += ["", "Summary: mean (min-max) over the trials (10 dB: noise seeds %s; none: one trial) of "
              "E_sigma1 / E_sigma2, %%; paper (Piovesan 2012, Fig 12: reach, 10 dB, interval not "
              "stated)." % ",".join(map(str, seeds)), "",
              "| model | task | method | SNR | vs viscoelastic 2.6-4.5 | vs viscoelastic 2.6-3.175 | "
              "vs effective 2.6-4.5 | vs effective 2.6-3.175 | paper |",
              "|---|---|---|---|---|---|---|---|---|"]
    for (model, task, method, snr), results in summary.items():
        cells = []
        good = [r for r in results if r is not None]
        for which in (0, 1):
            for lo, hi in INTERVALS:
                if not good:
                    cells.append("failed")
                    continue
                parts = []
                for j in (0, 1):
                    v = np.array([r[(lo, hi, j)][which] for r in good])
                    parts.append("%s (%s-%s)" % (fmt(v.mean()), fmt(v.min()), fmt(v.max())))
                cells.append(" / ".join(parts))
        failed = len(results) - len(good)
        paper = "%.1f / %.1f" % PAPER_SIGMA[model] if task == "reach" and snr == "10 dB" else "-"
        lines.append("| %s | %s | %s%s | %s | %s | %s |" % (model.replace("_", "-"), task, method,
                                                             " (%d failed)" % failed if failed else "",
                                                             snr, " | ".join(cells), paper))
    lines += ["", "Per trial: E_sigma1, E_sigma2 (%); f = mean fitted frequencies over 2.6-3.175 s; "
              "valid = % of frames 2.6-4.5 s each mode is flagged valid.", "",
              "| model | task | method | SNR | seed | visc 2.6-4.5 s1 | s2 | visc 2.6-3.175 s1 | s2 | "
              "eff 2.6-4.5 s1 | s2 | eff 2.6-3.175 s1 | s2 | f (Hz) | valid % | note |",
              "|" + "---|" * 16] + rows + [""]


# ---------------------------------------------------------------- part (b)
def kc_errors(trial, method, arm):
    tfa = trial.tfa[method]
    t = np.array(tfa["t_s"], dtype=float)
    est = {"K": np.moveaxis(np.array(tfa["K_nm_per_rad"], dtype=float), 2, 0),
           "C": np.moveaxis(np.array(tfa["C_nms_per_rad"], dtype=float), 2, 0)}
    visc = {"K": trial.at(trial.as_matrix(trial.k), t), "C": trial.at(trial.as_matrix(trial.c), t)}
    krb, crb = [], []
    for ti in t:
        k, c = arm.rigid_body_terms(*arm.reference(trial.spec["task"], ti))
        krb.append(k)
        crb.append(c)
    krb, crb = np.array(krb), np.array(crb)
    eff = {"K": visc["K"] + sym(krb), "C": visc["C"] + sym(crb)}
    out = {}
    for lo, hi in INTERVALS:
        sel = (t >= lo) & (t <= hi)
        for name, which, r, c in COEFFICIENTS:
            e = est[which][sel, r, c]
            ok = np.isfinite(e)
            for label, ref in (("visc", visc), ("eff", eff)):
                out[(label, lo, hi, name)] = rms_error(e[ok], ref[which][sel, r, c][ok]) if ok.any() else np.nan
            out[("rb", lo, hi, name)] = rms_error(eff[which][sel, r, c], visc[which][sel, r, c])
        out[("null", lo, hi)] = int((~np.isfinite(est["K"][sel]).all(axis=(1, 2))).sum())
        if "K_valid" in tfa:
            out[("kvalid", lo, hi)] = 100.0 * np.mean(np.array(tfa["K_valid"], dtype=bool)[sel])
    skew = np.abs(krb - np.swapaxes(krb, 1, 2)).max() / 2, np.abs(crb - np.swapaxes(crb, 1, 2)).max() / 2
    out["skew"] = skew
    return out


def part_b(stiffid, directions, work, arm, lines):
    rows = {"visc": [], "eff": []}
    rb_rows = []
    for profile in ("constant", "sigmoid"):
        for snr in (20.0, None):
            for direction in directions:
                spec = load_spec("piovesan_reach_%s.json" % profile)
                set_impulse(spec, direction)
                set_noise(spec, snr)
                tag = "b_%s_%s_%g" % (profile, "none" if snr is None else "%gdB" % snr, direction)
                trial = Trial(stiffid, spec, 1, work, tag)
                for method in METHODS:
                    head = "| %s | %s | %g | %s | " % (profile, "none" if snr is None else "%g dB" % snr,
                                                      direction, method)
                    if method not in trial.tfa:
                        for label in rows:
                            rows[label].append(head + " | ".join(["failed"] * 12) + " | %s |" % trial.failure[method])
                        continue
                    e = kc_errors(trial, method, arm)
                    for label in rows:
                        cells = [fmt(e[(label, lo, hi, n)]) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS]
                        kv = e.get(("kvalid", 2.6, 4.5))
                        nulls = e[("null", 2.6, 4.5)]
                        note = ("K_valid %.0f %%" % kv if kv is not None else "") + \
                               ("; %d null frames left out" % nulls if nulls else "")
                        rows[label].append(head + " | ".join(cells) + " | %s |" % note)
                    print(rows["visc"][-1] + "\n" + rows["eff"][-1], flush=True)
                    if method == "modal" and snr is None and direction == directions[0]:
                        rb_rows.append("| %s | " % profile + " | ".join(
                            fmt(e[("rb", lo, hi, n)]) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS)
                            + " | %.2g / %.2g |" % e["skew"])
    header = ("| profile | SNR | dir (deg) | method | " +
              " | ".join("%s %g-%g" % (n, lo, hi) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS) +
              " | note |")
    rule = "|" + "---|" * (5 + 2 * len(COEFFICIENTS))
    lines += ["## (b) Movement (reach) trials, Kelvin-Voigt, seed 1", "",
              "Size of the rigid-body terms: 100 RMS(sym part of K_eff - K) / RMS(K) (same for C) over "
              "the modal method's frames, and the largest skew-symmetric part (K_rb - K_rb^T)/2, "
              "(C_rb - C_rb^T)/2 dropped (N m/rad, N m s/rad):", "",
              "| profile | " + " | ".join("%s %g-%g" % (n, lo, hi) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS)
              + " | skew K_rb / C_rb |", "|" + "---|" * (2 + 2 * len(COEFFICIENTS))] + rb_rows + [""]
    lines += ["(i) Against the simulator's viscoelastic truth (truth JSON K, C), % RMS error:", "",
              header, rule] + rows["visc"] + [""]
    lines += ["(ii) Against the effective K_eff = K + sym(K_rb), C_eff = C + sym(C_rb), % RMS error:", "",
              header, rule] + rows["eff"] + [""]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stiffid", default=os.path.join(ROOT, "build", "stiffid"))
    ap.add_argument("--part", default="ab", choices=["a", "b", "ab"])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--directions", default="45,90,135")
    ap.add_argument("--keep", default="", help="keep the trials, truths and tfa JSON in this folder")
    ap.add_argument("-o", "--output", default="")
    a = ap.parse_args()
    arm = Arm()
    lines = ["# tfa on non-linear, higher-order and movement trials (scripts/tfa_reach_report.py)", ""]
    step, closed, posture = check_rigid_body(arm, load_spec("piovesan_reach_constant.json")["task"],
                                             load_spec("piovesan_posture_constant.json")["task"])
    lines += ["Rigid-body terms along the reach (9 times 2.5-4.5 s): central differences with steps "
              "1e-6 and 1e-4 agree to %.1e, and with the closed form to %.1e, of the largest entry; "
              "at the posture max |K_rb|, |C_rb| = %.1e." % (step, closed, posture), ""]
    print("\n".join(lines), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = a.keep or tmp
        os.makedirs(work, exist_ok=True)
        if "a" in a.part:
            part_a(a.stiffid, [int(s) for s in a.seeds.split(",")], work, arm, lines)
        if "b" in a.part:
            part_b(a.stiffid, [float(d) for d in a.directions.split(",")], work, arm, lines)
    text = "\n".join(lines) + "\n"
    print(text)
    if a.output:
        tmp = a.output + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, a.output)


if __name__ == "__main__":
    main()
