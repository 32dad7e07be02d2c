#!/usr/bin/env python3
"""numpy/scipy peer of `stiffid tfa --method spectrogram` (Piovesan 2012 time-frequency
identification, docs/tfa.md): the same stages with the same defaults -- deviations from the
pre-onset posture, zero-phase FIR decimation to 400 Hz, STFTs with h, t h and h' (Kaiser beta 3,
0.75 s, 2.5 ms hop, edge steps, windows cut at the free-response region), reassignment, joint DP
ridges, per-frame Gauss-Newton fit of the damped modes, Savitzky-Golay smoothing, modal analysis
(eqs 45-48). Prints K(t) statistics as JSON.

    python3 peer_tfa.py TRIAL.csv --onset 2.5          # identify
    python3 peer_tfa.py --make-trial TRIAL.csv         # write a 5 s, 4 kHz posture trial
"""
import argparse
import json
import sys

import numpy as np
from scipy.special import i0, i1

ARM = dict(l1=0.29, r1=0.132, m1=1.99, i1=0.0161, l2=0.4, r2=0.17, m2=1.10, i2=0.0146)


def inertia(th2):
    a = ARM
    kappa = a["i1"] + a["i2"] + a["m1"] * a["r1"] ** 2 + a["m2"] * (a["l1"] ** 2 + a["r2"] ** 2)
    beta, chi = a["m2"] * a["l1"] * a["r2"], a["i2"] + a["m2"] * a["r2"] ** 2
    c2 = np.cos(th2)
    return np.array([[kappa + 2 * beta * c2, chi + beta * c2], [chi + beta * c2, chi]])


def posture():
    a = ARM
    x, y = 0.4, 0.0
    c2 = (x * x + y * y - a["l1"] ** 2 - a["l2"] ** 2) / (2 * a["l1"] * a["l2"])
    th2 = np.arccos(c2)
    th1 = np.arctan2(y, x) - np.arctan2(a["l2"] * np.sin(th2), a["l1"] + a["l2"] * np.cos(th2))
    return np.array([th1, th2])


def make_trial(path):
    """Linearised posture trial: free response after an ideal 5 N x 20 ms push, closed form."""
    fs, th0 = 4000.0, posture()
    m = inertia(th0[1])
    k = np.array([[35.0, 5.0], [5.0, 20.0]])
    c = 0.01 * k
    a = ARM
    s1, s12 = np.sin(th0[0]), np.sin(th0.sum())
    c1, c12 = np.cos(th0[0]), np.cos(th0.sum())
    jac = np.array([[-a["l1"] * s1 - a["l2"] * s12, -a["l2"] * s12], [a["l1"] * c1 + a["l2"] * c12, a["l2"] * c12]])
    f = 5.0 * np.array([np.cos(np.pi / 4), np.sin(np.pi / 4)])
    v0 = np.linalg.solve(m, jac.T @ f * 0.02)
    state = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(m, k), -np.linalg.solve(m, c)]])
    lam, vec = np.linalg.eig(state)
    b = np.linalg.solve(vec, np.concatenate([[0, 0], v0]))
    t = np.arange(int(5 * fs)) / fs
    tau = np.clip(t - 2.5, 0, None)
    x = np.real(vec[:2] @ (b[:, None] * np.exp(lam[:, None] * tau[None, :]))).T
    x[t < 2.5] = 0
    force = np.where(((t >= 2.5) & (t < 2.52))[:, None], f[None, :], 0.0)
    data = np.column_stack([t, th0[0] + x[:, 0], th0[1] + x[:, 1], force])
    np.savetxt(path, data, delimiter=",", header="t,th1,th2,fx,fy", comments="", fmt="%.12g")


def kaiser_shape(beta, x):
    r = np.sqrt(np.clip(1 - x * x, 0, None))
    value = i0(beta * r) / i0(beta)
    with np.errstate(invalid="ignore", divide="ignore"):
        i1_over_r = np.where(r < 1e-8, beta / 2, i1(beta * r) / np.where(r < 1e-8, 1, r))
    return value, -beta * x * i1_over_r / i0(beta)


def cut_window(value, slope, lo, hi, half, dt):
    h = value[lo + half:hi + half + 1].copy()
    dh = slope[lo + half:hi + half + 1].copy()
    if h.size > 1:
        h[[0, -1]] *= 0.5
        dh[[0, -1]] *= 0.5
    dh[0] += value[lo + half] / dt
    dh[-1] -= value[hi + half] / dt
    u = np.arange(lo, hi + 1) * dt
    return u, h, dh


def identify(path, onset_s, window_s=0.75, hop_s=0.0025, fmin=0.5, fmax=20.0, penalty=2.0,
             max_jump=0.5, sg_window_s=0.25, pulse_s=0.02):
    from scipy.signal import savgol_filter  # here: make_trial's importers (peer_modal) skip it
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    t, ang = raw[:, 0], raw[:, 1:3]
    fs = 1.0 / (t[1] - t[0])
    onset = int(np.ceil((onset_s - t[0]) * fs - 1e-9))
    pre = int(round(0.2 * fs))
    th0 = ang[onset - pre:onset].mean(axis=0)
    dev = ang[onset:] - th0
    hop = int(round(hop_s * fs))
    d = next(c for c in range(hop, 0, -1) if hop % c == 0 and fs / c >= 8 * fmax)
    # Zero-phase FIR decimation (Kaiser-windowed sinc, beta 9, 12 D taps each side).
    half_f = 12 * d
    n = np.arange(-half_f, half_f + 1)
    fc = 0.8 * 0.5 / d
    taps = np.sinc(2 * fc * n) * i0(9.0 * np.sqrt(1 - (n / half_f) ** 2)) / i0(9.0)
    taps /= taps.sum()
    idx = np.arange(0, dev.shape[0], d)
    padded = np.pad(dev, ((half_f, half_f), (0, 0)))
    gain = np.convolve(np.pad(np.ones(dev.shape[0]), half_f), taps, mode="same")
    filt = np.column_stack([np.convolve(padded[:, c], taps, mode="same") for c in range(2)])
    x = (filt[half_f:-half_f] / gain[half_f:-half_f, None])[idx]
    fa, dt = fs / d, d / fs
    edge = (half_f + d - 1) // d
    begin = int(np.ceil((pulse_s + half_f / fs) / dt - 1e-9))
    end = x.shape[0] - edge
    half = max(1, int(round(window_s / (2 * dt))))
    nfft = 1 << int(np.ceil(np.log2(2 * half + 1)))
    xs = np.arange(-half, half + 1) / half
    value, slope = kaiser_shape(3.0, xs)
    slope = slope / (half * dt)
    centres = np.arange(begin, end, 1)
    frames = centres.size
    df = fa / nfft
    kmax = int(np.floor(min(fa / 2, 2 * fmax) / df + 1e-9))
    freqs = np.arange(kmax + 1) * df
    windows = [cut_window(value, slope, max(-half, begin - c), min(half, end - 1 - c), half, dt) for c in centres]
    buf = np.zeros((3, 2, frames, nfft))
    for m, (c, (u, h, dh)) in enumerate(zip(centres, windows)):
        off = np.round(u / dt).astype(int)
        seg = x[c + off]
        pos = off % nfft
        buf[0, :, m, pos] = (h[:, None] * seg)
        buf[1, :, m, pos] = ((u * h)[:, None] * seg)
        buf[2, :, m, pos] = (dh[:, None] * seg)
    spec = np.fft.rfft(buf, axis=-1)[..., :kmax + 1]
    xh, xt, xd = spec[0], spec[1], spec[2]
    power = (np.abs(xh) ** 2).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        f_hat = freqs[None, None, :] - np.imag(xd / xh) / (2 * np.pi)
        t_hat = (centres * dt)[None, :, None] + np.real(xt / xh)
    mm = np.rint((t_hat - centres[0] * dt) / dt).astype(np.int64)
    kk = np.rint(np.nan_to_num(f_hat, nan=-1) / df).astype(np.int64)
    ok = (mm >= 0) & (mm < frames) & (kk >= 0) & (kk <= kmax)
    rmap = np.zeros((frames, kmax + 1))
    np.add.at(rmap, (mm[ok], kk[ok]), (np.abs(xh) ** 2)[ok])
    # Joint DP over ridge pairs b0 < b1 in the band.
    band = np.where((freqs >= fmin - 1e-9) & (freqs <= fmax + 1e-9))[0]
    logmap = np.log(rmap[:, band] + max(1e-300, rmap.max() * 1e-12))
    width = band.size
    jmax = max(1, int(np.floor(max_jump / df)))
    valid = np.triu(np.ones((width, width), bool), 1)
    score = np.where(valid, logmap[0][:, None] + logmap[0][None, :], -np.inf)
    back = np.zeros((frames, width, width, 2), np.int16)
    for m in range(1, frames):
        best = np.full((width, width), -np.inf)
        arg = np.zeros((width, width, 2), np.int16)
        for d0 in range(-jmax, jmax + 1):
            for d1 in range(-jmax, jmax + 1):
                shifted = np.full((width, width), -np.inf)
                src = score[max(0, -d0):width - max(0, d0), max(0, -d1):width - max(0, d1)]
                shifted[max(0, d0):width - max(0, -d0), max(0, d1):width - max(0, -d1)] = src
                cand = shifted - penalty * df * (abs(d0) + abs(d1))
                better = cand > best
                best = np.where(better, cand, best)
                arg[better] = (d0, d1)
        score = np.where(valid, best + logmap[m][:, None] + logmap[m][None, :], -np.inf)
        back[m] = arg
    b0, b1 = np.unravel_index(np.argmax(score), score.shape)
    path_bins = np.zeros((frames, 2), int)
    for m in range(frames - 1, -1, -1):
        path_bins[m] = band[[b0, b1]]
        if m:
            d0, d1 = back[m, b0, b1]
            b0, b1 = b0 - d0, b1 - d1

    def transforms(u, h, dh, s):
        e = np.exp(np.multiply.outer(s, u))
        return e @ h, e @ dh, e @ (u * h), e @ (u * dh)

    def gauss_newton(m, lam, coef):
        u, h, dh = windows[m]
        bins = np.unique(np.clip(np.concatenate([path_bins[m] + q for q in (-1, 0, 1)]), 0, kmax))
        nu = 2 * np.pi * freqs[bins]
        wd_weight = (u[-1] - u[0]) / (2 * np.pi)
        data = np.concatenate([xh[:, m, bins].T.ravel(), wd_weight * xd[:, m, bins].T.ravel()])

        def model(lam, coef, jac=False):
            s = np.concatenate([lam, np.conj(lam)])[:, None] - 1j * nu[None, :]  # (4, B)
            w, wd, wt, wdt = transforms(u, h, dh, s)
            cc = np.concatenate([coef, np.conj(coef)])  # (4, C)
            mh = np.einsum("ib,ic->bc", w, cc)
            md = np.einsum("ib,ic->bc", wd, cc)
            out = np.concatenate([mh.ravel(), wd_weight * md.ravel()])
            if not jac:
                return out
            cols = []
            for j in range(2):
                for dp in (1.0, 1j):
                    dh_ = np.outer(wt[j], coef[j]) * dp + np.outer(wt[j + 2], np.conj(coef[j])) * np.conj(dp)
                    dd_ = np.outer(wdt[j], coef[j]) * dp + np.outer(wdt[j + 2], np.conj(coef[j])) * np.conj(dp)
                    cols.append(np.concatenate([dh_.ravel(), wd_weight * dd_.ravel()]))
            for j in range(2):
                for c in range(2):
                    for dc in (1.0, 1j):
                        mh_ = np.zeros((bins.size, 2), complex)
                        md_ = np.zeros((bins.size, 2), complex)
                        mh_[:, c] = w[j] * dc + w[j + 2] * np.conj(dc)
                        md_[:, c] = wd[j] * dc + wd[j + 2] * np.conj(dc)
                        cols.append(np.concatenate([mh_.ravel(), wd_weight * md_.ravel()]))
            return out, np.array(cols).T

        for _ in range(10):
            mod, jac = model(lam, coef, True)
            r = data - mod
            cost = np.vdot(r, r).real
            a = np.vstack([jac.real, jac.imag])
            step = np.linalg.lstsq(a, np.concatenate([r.real, r.imag]), rcond=None)[0]
            scale, improved = 1.0, False
            while scale > 1e-2 and not improved:
                nl = lam + scale * (step[0:4:2] + 1j * step[1:4:2])
                nc = coef + scale * (step[4::2] + 1j * step[5::2]).reshape(2, 2)
                r2 = data - model(nl, nc)
                improved = np.vdot(r2, r2).real <= cost
                scale *= 0.5
            if not improved:
                break
            lam, coef = nl, nc
            if cost - np.vdot(r2, r2).real <= 1e-14 * cost:
                break
        return lam, coef

    def initial(m):
        lam = np.zeros(2, complex)
        for j in range(2):
            k = path_bins[m, j]
            r = (np.conj(xh[:, m, k]) * xd[:, m, k]).sum() / (np.abs(xh[:, m, k]) ** 2).sum()
            lam[j] = -r + 1j * 2 * np.pi * freqs[k]
        u, h, dh = windows[m]
        bins = path_bins[m]
        nu = 2 * np.pi * freqs[bins]
        w1 = transforms(u, h, dh, lam[:, None] - 1j * nu[None, :])[0]
        w2 = transforms(u, h, dh, np.conj(lam)[:, None] - 1j * nu[None, :])[0]
        a = np.zeros((4, 4))
        for i in range(2):
            for j in range(2):
                cre, cim = w1[j, i] + w2[j, i], 1j * (w1[j, i] - w2[j, i])
                a[2 * i:2 * i + 2, 2 * j] = [cre.real, cre.imag]
                a[2 * i:2 * i + 2, 2 * j + 1] = [cim.real, cim.imag]
        b = np.vstack([np.vstack([xh[:, m, bins[i]].real, xh[:, m, bins[i]].imag]) for i in range(2)])
        sol = np.linalg.solve(a, b)
        return lam, sol[0::2] + 1j * sol[1::2]

    lam_all = np.zeros((frames, 2), complex)
    coef_all = np.zeros((frames, 2, 2), complex)
    mid = frames // 2
    lam, coef = gauss_newton(mid, *initial(mid))
    lam_all[mid], coef_all[mid] = lam, coef
    for rng, sign in ((range(mid + 1, frames), 1), (range(mid - 1, -1, -1), -1)):
        lam, coef = lam_all[mid], coef_all[mid]
        for m in rng:
            coef = coef * np.exp(lam * sign * dt)[:, None]
            lam, coef = gauss_newton(m, lam, coef)
            lam_all[m], coef_all[m] = lam, coef
    amp = 2 * coef_all  # (T, mode, channel)
    omega = lam_all.imag
    ln_a = 0.5 * np.log((np.abs(amp) ** 2).sum(axis=2))
    w_sg = 2 * int(round(sg_window_s / dt / 2)) + 1
    sg = lambda v, d: savgol_filter(v, w_sg, 3, deriv=d, delta=dt, axis=0, mode="interp")
    w, wdot = sg(omega, 0), sg(omega, 1)
    alpha, adot = sg(ln_a, 1), sg(ln_a, 2)
    eta2 = w * w + alpha * alpha + alpha * wdot / w - adot
    gamma = -alpha - wdot / (2 * w)
    mass = inertia(th0[1])
    ev, evec = np.linalg.eigh(mass)
    root = evec @ np.diag(np.sqrt(ev)) @ evec.T
    ref = np.argmax(np.abs(amp), axis=2)
    phase = np.angle(amp * np.conj(np.take_along_axis(amp, ref[:, :, None], axis=2)))
    shapes = np.abs(amp) * np.cos(phase)
    shapes /= np.linalg.norm(shapes, axis=2, keepdims=True)
    for j in range(2):
        sign = np.sign(np.einsum("tc,c->t", shapes[:, j], shapes[mid, j]))
        shapes[:, j] *= sign[:, None]
    shapes = savgol_filter(shapes, w_sg, 3, axis=0, mode="interp")
    k = np.zeros((frames, 2, 2))
    c = np.zeros((frames, 2, 2))
    for m in range(frames):
        p = root @ shapes[m].T
        p /= np.linalg.norm(p, axis=0)
        uu, _, vv = np.linalg.svd(p)
        p = uu @ vv
        k[m] = root @ p @ np.diag(eta2[m]) @ p.T @ root
        c[m] = root @ p @ np.diag(2 * gamma[m]) @ p.T @ root
    times = onset_s + centres * dt
    return {"frames": int(frames), "t_s": [float(times[0]), float(times[-1])],
            "K_median_nm_per_rad": np.median(k, axis=0).tolist(),
            "C_median_nms_per_rad": np.median(c, axis=0).tolist()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("trial", nargs="?")
    ap.add_argument("--onset", type=float, default=2.5)
    ap.add_argument("--make-trial")
    a = ap.parse_args()
    if a.make_trial:
        make_trial(a.make_trial)
        return
    json.dump(identify(a.trial, a.onset), sys.stdout)
    print()


if __name__ == "__main__":
    main()
