#!/usr/bin/env python3
"""Cramer-Rao bounds of K and C from one simulated posture trial with constant K and C.

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
    g = np.empty((len(NAMES), theta.size))
    for p in range(theta.size):
        hp = 1e-6 * max(1.0, abs(theta[p]))
        up, dn = theta.copy(), theta.copy()
        up[p] += hp
        dn[p] -= hp
        g[:, p] = (coefficients(up, M) - coefficients(dn, M)) / (2 * hp)
    true = coefficients(theta, M)
    sd = np.sqrt(np.einsum("kp,pq,kq->k", g, cov, g))
    peak = np.max(np.abs(dev[m]), axis=0)
    return sd, true, fit_rel, peak


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--stiffid", default=os.path.join(ROOT, "build", "stiffid"))
    p.add_argument("--profiles", default="constant")
    p.add_argument("--directions", default="0,45,90,135")
    p.add_argument("--snr", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args()
    onset_s, free_s = 2.5, 2.52
    print("| trial | dir (deg) | SNR | " + " | ".join("SD %s %%" % n for n in NAMES) +
          " | peak |dth1|, |dth2| (mrad) | model misfit (noise-free) % |")
    print("|" + "---|" * (len(NAMES) + 5))
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
                sd, true, misfit, peak = crb(trials[None][0], noise, K, C, M, onset_s, free_s)
                reference = np.array([K[0, 0], K[0, 1], K[1, 1], C[0, 0], C[0, 1], C[1, 1]])
                rel = 100.0 * sd / np.abs(reference)
                print("| %s | %g | %g dB | " % (profile, direction, a.snr) +
                      " | ".join("%.2g" % v for v in rel) +
                      " | %.1f, %.1f | %.2g |" % (1e3 * peak[0], 1e3 * peak[1], 100 * misfit))


if __name__ == "__main__":
    main()
