#!/usr/bin/env python3
"""Cramer-Rao bounds of K and C from one simulated posture trial, constant or time-varying K and C.

The most favourable model an estimator could assume: the free response after the pulse is two
damped oscillations with CONSTANT eigenvalues lambda_j and CONSTANT complex joint-space mode
shapes a_j (12 real parameters),

    delta theta(t) = sum_j Re(a_j exp(lambda_j (t - t0))),

in white Gaussian noise of the covariance the trial has before the onset (at the full sampling
rate: the low-pass of the estimators removes only out-of-band noise). K and C follow from
(lambda_j^2 M + lambda_j C + K) a_j = 0 for both modes (8 real equations, M the truth's inertia),
k12 as (k12 + k21) / 2. The bound on each coefficient is g^T F^-1 g with F the Fisher
information of the 12 parameters and g the gradient of the coefficient (central differences).
The parameters are those of the noise-free trial (true lambda_j from K, C, M; a_j by linear least
squares), so the bound holds for the trial's noise level whatever the noise draw.

An unbiased estimator of a constant K, C cannot have a smaller SD; one that lets the tracks and
shapes vary in time (the modal method) has more parameters and a larger bound. Run:

    /usr/bin/python3 scripts/tfa_crb.py [--profiles constant] [--directions 0,45,90,135] [--snr 20]

(numpy only; uses `stiffid simulate` for the trials). Prints, per direction, the relative SD
bound (%) of k11, k12, k22, c11, c12, c22 and the peak joint deviations.

Time-varying K(t), C(t) (--tracks FAMILY, e.g. poly:1, poly:3, spline:1; families as in
scripts/tfa_crb_tracks.py, numpy and scipy): alpha_j(t) and omega_j(t) are in the family's
basis over the free response, the complex mode shapes a_j constant (exact when C is proportional
to K and both change by a common factor, the most favourable case otherwise),

    delta theta(t) = sum_j Re(a_j exp(int_t0^t lambda_j(s) ds)),

the true tracks (the eigenvalues of K(t), C(t), M(t) of the truth) projected onto the basis,
a_j by linear least squares on the noise-free response. K(t), C(t) follow at each time from
lambda_j(t), a_j and the true M(t) as above. The bound is printed as 100 sqrt(mean_t SD(t)^2) /
RMS(truth) over 2.6-4.5 s, the issue's percentage RMS error, with the error of K, C from the
projected tracks (the family's bias, noise-free) and the model misfit. Run:

    /usr/bin/python3 scripts/tfa_crb.py --profiles sigmoid --directions 45 --tracks poly:3
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from tfa_cases import set_impulse, set_noise  # noqa: E402

ROOT = os.path.dirname(HERE)
NAMES = ["k11", "k12", "k22", "c11", "c12", "c22"]


def read_trial(path):
    with open(path) as f:
        header = [h.split("[")[0] for h in f.readline().strip().split(",")]
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: data[:, k] for k, name in enumerate(header)}


def eigen_modes(K, C, M):
    """The two complex eigenvalues (positive imaginary part) and joint-space eigenvectors."""
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -Minv @ C]])
    w, v = np.linalg.eig(A)
    keep = np.argsort(w.imag)[-2:]
    keep = keep[np.argsort(w[keep].imag)]
    return w[keep], v[:2, keep]


def central_gradient(fn, x, rel_step=1e-6):
    """Jacobian of the vector function fn at x by central differences (steps rel_step max(1, |x|))."""
    columns = []
    for p in range(x.size):
        h = rel_step * max(1.0, abs(x[p]))
        up, dn = x.copy(), x.copy()
        up[p] += h
        dn[p] -= h
        columns.append((fn(up) - fn(dn)) / (2 * h))
    return np.stack(columns, axis=-1)


def basis(lam, tau):
    """(N x 2) columns exp(lambda_j tau)."""
    return np.exp(np.outer(tau, lam))


def response(theta, tau):
    """(N x 2 channels) model for theta = [Re l1, Im l1, Re l2, Im l2, a (2 modes x 2 ch, re/im)]."""
    lam = theta[0:4:2] + 1j * theta[1:4:2]
    a = (theta[4::2] + 1j * theta[5::2]).reshape(2, 2)  # [mode, channel]
    return (basis(lam, tau) @ a).real


def coefficients(theta, M):
    """k11, k12 (mean of the two off-diagonals), k22, c11, c12, c22 from lambda_j and a_j."""
    lam = theta[0:4:2] + 1j * theta[1:4:2]
    a = (theta[4::2] + 1j * theta[5::2]).reshape(2, 2)
    rows, rhs = [], []
    # unknowns: K (row-major 4), C (row-major 4); (K + lam C) a = -lam^2 M a
    for j in range(2):
        for r in range(2):
            coef = np.zeros(8, dtype=complex)
            for c in range(2):
                coef[2 * r + c] = a[j, c]
                coef[4 + 2 * r + c] = lam[j] * a[j, c]
            value = -(lam[j] ** 2) * (M[r] @ a[j])
            rows += [coef.real, coef.imag]
            rhs += [value.real, value.imag]
    x = np.linalg.solve(np.array(rows), np.array(rhs))
    K, C = x[:4].reshape(2, 2), x[4:].reshape(2, 2)
    return np.array([K[0, 0], 0.5 * (K[0, 1] + K[1, 0]), K[1, 1],
                     C[0, 0], 0.5 * (C[0, 1] + C[1, 0]), C[1, 1]])


def bound(trial, truth, onset_s, free_s):
    t = trial["t"]
    th = np.column_stack([trial["th1"], trial["th2"]])
    pre = (t >= onset_s - 2.0) & (t < onset_s)
    posture = th[pre].mean(axis=0)
    noise = np.cov((th[pre] - posture).T)  # per-sample covariance, rad^2
    tt = np.array(truth["time_s"])
    i0 = np.argmin(abs(tt - (onset_s + 0.1)))
    K = np.array(truth["stiffness_nm_per_rad"])[i0]
    C = np.array(truth["damping_nms_per_rad"])[i0]
    M = np.array(truth["inertia_kg_m2"])[i0]
    return noise, K, C, M, posture


def crb(clean, noise, K, C, M, onset_s, free_s):
    t = clean["t"]
    th = np.column_stack([clean["th1"], clean["th2"]])
    pre = (t >= onset_s - 0.2) & (t < onset_s)
    dev = th - th[pre].mean(axis=0)
    m = t >= free_s
    tau = t[m] - free_s
    lam, _ = eigen_modes(K, C, M)
    B = basis(lam, tau)
    # a_j by least squares on the noise-free response: Re(B a) per channel
    design = np.hstack([B.real, -B.imag])
    sol, *_ = np.linalg.lstsq(design, dev[m], rcond=None)
    a = sol[:2] + 1j * sol[2:]  # [mode, channel]
    theta = np.concatenate([[lam[0].real, lam[0].imag, lam[1].real, lam[1].imag],
                            np.column_stack([a.real.ravel(), a.imag.ravel()]).ravel()])
    fit_rel = np.sqrt(np.mean((response(theta, tau) - dev[m]) ** 2) / np.mean(dev[m] ** 2))
    # Fisher information: sum over samples of J_t^T Sigma^-1 J_t (J_t: 2 x 12)
    h = 1e-7 * np.maximum(1.0, np.abs(theta))
    J = np.empty((tau.size, 2, theta.size))
    for p in range(theta.size):
        up, dn = theta.copy(), theta.copy()
        up[p] += h[p]
        dn[p] -= h[p]
        J[:, :, p] = (response(up, tau) - response(dn, tau)) / (2 * h[p])
    W = np.linalg.inv(noise)
    F = np.einsum("tip,ij,tjq->pq", J, W, J)
    cov = np.linalg.inv(F)
    g = central_gradient(lambda x: coefficients(x, M), theta)
    true = coefficients(theta, M)
    sd = np.sqrt(np.einsum("kp,pq,kq->k", g, cov, g))
    peak = np.max(np.abs(dev[m]), axis=0)
    return sd, true, fit_rel, peak


def modal_coefficients(local, M):
    """k11, k12, k22, c11, c12, c22 as the modal method maps its fit (eqs 45-48, estimators/
    modal_analysis.cpp): local = per mode [alpha, alpha_dot, omega, omega_dot], then per mode the
    shape a_j (re, im per channel); real shapes from the phase-projected components, P the
    nearest orthonormal matrix to the M^1/2-weighted shapes."""
    w_m, v_m = np.linalg.eigh(M)
    root = v_m @ np.diag(np.sqrt(w_m)) @ v_m.T
    a = (local[8::2] + 1j * local[9::2]).reshape(2, 2)
    P = np.empty((2, 2))
    eta2, two_gamma = np.empty(2), np.empty(2)
    for j in range(2):
        alpha, alpha_dot, omega, omega_dot = local[4 * j:4 * j + 4]
        two_gamma[j] = 2.0 * (-alpha - omega_dot / (2.0 * omega))
        eta2[j] = omega ** 2 + alpha ** 2 + alpha * omega_dot / omega - alpha_dot
        ref = np.argmax(np.abs(a[j]))
        phi = np.abs(a[j]) * np.cos(np.angle(a[j] * np.conj(a[j, ref])))
        p = root @ (phi / np.linalg.norm(phi))
        P[:, j] = p / np.linalg.norm(p)
    U, _, Vt = np.linalg.svd(P)
    P = U @ Vt
    K = root @ P @ np.diag(eta2) @ P.T @ root
    C = root @ P @ np.diag(two_gamma) @ P.T @ root
    return np.array([K[0, 0], 0.5 * (K[0, 1] + K[1, 0]), K[1, 1],
                     C[0, 0], 0.5 * (C[0, 1] + C[1, 0]), C[1, 1]])


def track_model(coef, a, extra, strong, I):
    """exp(Phi_j(t)) [time, mode] and the response [time, channel]: Re(sum_j a_j exp(Phi_j)),
    plus (as the modal method fits them) an offset o_k and the strongest mode's quadratic
    distortion s_k exp(2 Re Phi_J) + Re(h_k exp(2 Phi_J)); extra = [o (2), s (2), h (re, im
    per channel)]."""
    e = np.exp(np.column_stack([I @ c for c in coef]))
    e2 = e[:, strong] ** 2
    x = (e @ a).real + extra[0:2] + np.outer(np.abs(e2), extra[2:4])
    x += (np.outer(e2, extra[4::2] + 1j * extra[5::2])).real
    return e, x


def track_jacobian(coef, a, extra, strong, I):
    """d response / d parameters [time, channel, parameter]: per mode the alpha coefficients,
    the omega coefficients, a_j (re, im per channel); then the extra terms."""
    from tfa_crb_tracks import mode_jacobian
    e, _ = track_model(coef, a, extra, strong, I)
    e2 = e[:, strong] ** 2
    h = extra[4::2] + 1j * extra[5::2]
    n = I.shape[1]
    blocks = []
    for j in range(2):
        d = mode_jacobian(a[j], e[:, j], I)
        if j == strong:  # the quadratic terms move with the strongest mode's phase
            for k, unit in enumerate((1.0, 1j)):
                d[:, :, k * n:(k + 1) * n] += np.stack(
                    [(2.0 * unit * I * (extra[2 + c] * np.abs(e2)[:, None]
                                        if unit == 1.0 else 0.0)).real +
                     (2.0 * unit * h[c] * e2[:, None] * I).real for c in range(2)], axis=1)
        blocks.append(d)
    for column in (np.ones(I.shape[0]), np.abs(e2)):
        for c in range(2):
            block = np.zeros((I.shape[0], 2, 1))
            block[:, c, 0] = column
            blocks.append(block)
    for c in range(2):
        for unit in (1.0, 1j):
            block = np.zeros((I.shape[0], 2, 1))
            block[:, c, 0] = (unit * e2).real
            blocks.append(block)
    return np.concatenate(blocks, axis=2)


def crb_tracks(clean, truth, noise, family, onset_s, free_s, score=(2.6, 4.5)):
    """Bound of K(t), C(t) with alpha_j(t), omega_j(t) in the family's basis and constant
    complex shapes a_j, mapped as the modal method maps them (modal_coefficients).

    The model's truth: the true eigenvalue tracks (K(t), C(t), M(t) of the truth) with the
    adiabatic amplitude term, alpha_j = Re lambda_j - omega_j' / (2 omega_j) (eq 45), projected
    onto the basis, then Gauss-Newton on the noise-free response. Returns (RMS SD % of the six
    coefficients, RMS error % of K, C from the model's truth, relative RMS misfit of the
    noise-free response)."""
    from tfa_crb_tracks import family_basis, inverse_information  # needs scipy (B-splines)
    t = clean["t"]
    th = np.column_stack([clean["th1"], clean["th2"]])
    pre = (t >= onset_s - 0.2) & (t < onset_s)
    dev = th - th[pre].mean(axis=0)
    m = t >= free_s
    tf = t[m]
    y = dev[m]
    dt = tf[1] - tf[0]
    tt = np.array(truth["time_s"])
    Ks, Cs, Ms = (np.array(truth[k]) for k in ("stiffness_nm_per_rad", "damping_nms_per_rad",
                                                 "inertia_kg_m2"))
    rows = np.searchsorted(tt, tf - 0.5 * dt)
    lam_true = np.array([eigen_modes(Ks[i], Cs[i], Ms[i])[0] for i in rows])  # [time, mode]
    B = family_basis(family, tf)
    dB = np.gradient(B, dt, axis=0)
    n = B.shape[1]
    I = np.cumsum(B, axis=0) * dt
    I -= I[0]
    omega_true = lam_true.imag
    alpha_true = lam_true.real - np.gradient(omega_true, dt, axis=0) / (2.0 * omega_true)
    coef = [np.linalg.lstsq(B, alpha_true[:, j] + 1j * omega_true[:, j], rcond=None)[0]
            for j in range(2)]
    L = np.linalg.cholesky(np.linalg.inv(noise))  # W = L L^T

    def pack(coef, a, extra):
        return np.concatenate([np.concatenate([c.real, c.imag, np.column_stack(
            [a[j].real, a[j].imag]).ravel()]) for j, c in enumerate(coef)] + [extra])

    def unpack(theta):
        coef, a = [], np.empty((2, 2), dtype=complex)
        for j in range(2):
            block = theta[j * (2 * n + 4):(j + 1) * (2 * n + 4)]
            coef.append(block[:n] + 1j * block[n:2 * n])
            a[j] = block[2 * n::2] + 1j * block[2 * n + 1::2]
        return coef, a, theta[4 * n + 8:]

    # shapes (and the extra terms at zero) by linear least squares, the strongest mode first
    e, _ = track_model(coef, np.zeros((2, 2)), np.zeros(8), 0, I)
    sol, *_ = np.linalg.lstsq(np.hstack([e.real, -e.imag]), y, rcond=None)
    a = sol[:2] + 1j * sol[2:]
    strong = int(np.argmax(np.linalg.norm(a, axis=1)))
    theta = pack(coef, a, np.zeros(8))
    cost = np.sum((track_model(coef, a, np.zeros(8), strong, I)[1] - y) ** 2)
    for _ in range(50):  # Gauss-Newton (Levenberg damping) on the noise-free response
        coef, a, extra = unpack(theta)
        J = track_jacobian(coef, a, extra, strong, I).reshape(-1, theta.size)
        r = (track_model(coef, a, extra, strong, I)[1] - y).reshape(-1)
        A, g = J.T @ J, J.T @ r
        for mu in (1e-9, 1e-6, 1e-3, 1.0):
            step = np.linalg.solve(A + mu * np.diag(np.diag(A)) + 1e-300 * np.eye(theta.size), -g)
            cost2 = np.sum((track_model(*unpack(theta + step), strong, I)[1] - y) ** 2)
            if cost2 < cost:
                break
        if cost2 >= cost:
            break
        done = cost - cost2 < 1e-12 * cost
        theta, cost = theta + step, cost2
        if done:
            break
    coef, a, extra = unpack(theta)
    misfit = np.sqrt(cost / np.sum(y ** 2))
    J = track_jacobian(coef, a, extra, strong, I)
    cov = inverse_information(np.einsum("ij,tip->tjp", L, J).reshape(-1, J.shape[2]))
    # the coefficients and their gradients every 10 ms of the scored interval
    stride = max(1, int(round(0.01 / dt)))
    at = np.nonzero((tf >= score[0]) & (tf <= score[1]))[0][::stride]
    var, est, true = [], [], []
    for i in at:
        Mi = Ms[rows[i]]
        local = np.concatenate(
            [np.concatenate([[B[i] @ c.real, dB[i] @ c.real, B[i] @ c.imag, dB[i] @ c.imag]
                             for c in coef]),
             np.column_stack([a.real.ravel(), a.imag.ravel()]).ravel()])
        g_local = central_gradient(lambda x: modal_coefficients(x, Mi), local)
        g = np.zeros((len(NAMES), cov.shape[0]))  # the extra terms do not enter K, C
        for j in range(2):
            o = j * (2 * n + 4)
            g[:, o:o + n] = np.outer(g_local[:, 4 * j], B[i]) + np.outer(g_local[:, 4 * j + 1], dB[i])
            g[:, o + n:o + 2 * n] = (np.outer(g_local[:, 4 * j + 2], B[i]) +
                                     np.outer(g_local[:, 4 * j + 3], dB[i]))
            g[:, o + 2 * n:o + 2 * n + 4] = g_local[:, 8 + 4 * j:12 + 4 * j]
        var.append(np.einsum("kp,pq,kq->k", g, cov, g))
        est.append(modal_coefficients(local, Mi))
        Kt, Ct = Ks[rows[i]], Cs[rows[i]]
        true.append([Kt[0, 0], 0.5 * (Kt[0, 1] + Kt[1, 0]), Kt[1, 1],
                     Ct[0, 0], 0.5 * (Ct[0, 1] + Ct[1, 0]), Ct[1, 1]])
    var, est, true = np.array(var), np.array(est), np.array(true)
    scale = np.sqrt(np.mean(true ** 2, axis=0))
    sd = 100.0 * np.sqrt(np.mean(var, axis=0)) / scale
    bias = 100.0 * np.sqrt(np.mean((est - true) ** 2, axis=0)) / scale
    return sd, bias, misfit


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--stiffid", default=os.path.join(ROOT, "build", "stiffid"))
    p.add_argument("--profiles", default="constant")
    p.add_argument("--directions", default="0,45,90,135")
    p.add_argument("--snr", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--tracks", default="constant",
                   help="constant (eigenvalues and shapes at 2.6 s), or a family of time-varying "
                   "tracks, poly:DEGREE or spline:KNOT_SPACING_S (constant shapes)")
    a = p.parse_args()
    onset_s, free_s = 2.5, 2.52
    if a.tracks == "constant":
        print("| trial | dir (deg) | SNR | " + " | ".join("SD %s %%" % n for n in NAMES) +
              " | peak |dth1|, |dth2| (mrad) | model misfit (noise-free) % |")
        print("|" + "---|" * (len(NAMES) + 5))
    else:
        print("| trial | dir (deg) | SNR | tracks | " +
              " | ".join("SD %s %%" % n for n in NAMES) + " | " +
              " | ".join("bias %s %%" % n for n in NAMES) + " | model misfit (noise-free) % |")
        print("|" + "---|" * (2 * len(NAMES) + 5))
    with tempfile.TemporaryDirectory() as work:
        for profile in a.profiles.split(","):
            base = json.load(open(os.path.join(ROOT, "models", "specs",
                                               "piovesan_posture_%s.json" % profile)))
            for direction in (float(d) for d in a.directions.split(",")):
                trials = {}
                for snr in (a.snr, None):
                    spec = json.loads(json.dumps(base))
                    set_impulse(spec, direction)
                    spec["seed"] = a.seed
                    set_noise(spec, snr)
                    spec_path = os.path.join(work, "spec.json")
                    json.dump(spec, open(spec_path, "w"))
                    csv = os.path.join(work, "trial%s.csv" % ("" if snr else "_clean"))
                    truth = os.path.join(work, "truth.json")
                    subprocess.run([a.stiffid, "simulate", spec_path, "-o", csv, "--truth", truth],
                                   check=True)
                    trials[snr] = (read_trial(csv), json.load(open(truth)))
                noise, K, C, M, _ = bound(*trials[a.snr], onset_s, free_s)
                if a.tracks != "constant":
                    sd, bias, misfit = crb_tracks(trials[None][0], trials[None][1], noise,
                                                  a.tracks, onset_s, free_s)
                    print("| %s | %g | %g dB | %s | " % (profile, direction, a.snr, a.tracks) +
                          " | ".join("%.2g" % v for v in sd) + " | " +
                          " | ".join("%.2g" % v for v in bias) + " | %.2g |" % (100 * misfit))
                    continue
                sd, true, misfit, peak = crb(trials[None][0], noise, K, C, M, onset_s, free_s)
                reference = np.array([K[0, 0], K[0, 1], K[1, 1], C[0, 0], C[0, 1], C[1, 1]])
                rel = 100.0 * sd / np.abs(reference)
                print("| %s | %g | %g dB | " % (profile, direction, a.snr) +
                      " | ".join("%.2g" % v for v in rel) +
                      " | %.1f, %.1f | %.2g |" % (1e3 * peak[0], 1e3 * peak[1], 100 * misfit))


if __name__ == "__main__":
    main()
