#!/usr/bin/env python3
"""numpy/scipy peer of `stiffid tfa --method spectrogram` (Piovesan 2012 time-frequency
identification, docs/tfa.md): the same stages with the same defaults -- deviations from the
pre-onset posture, zero-phase FIR decimation to 400 Hz, STFTs with h, t h and h' (Kaiser beta 3,
0.75 s, 2.5 ms hop, edge steps, windows cut at the free-response region), reassignment, joint DP
ridges, the chirped frame fits (Gauss-Newton on the damped modes; pass 1 every 10 ms with the
chirp rates kept where an F-type test against the pre-onset noise asks for them, the start the
best of three frames, the fit bins following the fits; pass 2 with the rates held at the
Savitzky-Golay slopes of pass 1's tracks; the frames between moved from the nearest), Savitzky-
Golay smoothing, modal analysis (eqs 45-48, eq 43 weighted by the modes' amplitude-to-noise
ratios). No validity flags or bridging. Prints K(t) statistics as JSON; its medians agree with
stiffid's (K to 5e-9, C to 4e-8 relative) on the scipy constant- and sigmoid-K posture fixtures
(tests/data/tfa), and differ where stiffid bridges invalid frames (sharp K).

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
    # Pre-onset noise (up to 1 s, 50 ms off the onset), filtered and decimated like the response.
    used = min(onset - int(round(0.05 * fs)), int(round(1.0 * fs)))
    before = np.column_stack([np.convolve(ang[onset - used:onset, c] - th0[c], taps, mode="same") for c in range(2)])
    noise = before[half_f:used - half_f:d]
    noise_cov = np.atleast_2d(np.cov(noise.T)) if noise.shape[0] > 16 else np.zeros((2, 2))
    noise_trace = np.trace(noise_cov)
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

    def transforms(u, h, dh, s, g):
        """Window transforms of exp(s u + g u^2 / 2) (g shaped like s) and their u, u^2 moments."""
        e = np.exp(np.multiply.outer(s, u) + 0.5 * np.multiply.outer(g, u * u))
        uh, udh = u * h, u * dh
        return e @ h, e @ dh, e @ uh, e @ udh, e @ (u * uh), e @ (u * udh)

    def fit_bins(centres):
        return np.unique(np.clip(np.concatenate([np.asarray(centres) + q for q in (-1, 0, 1)]), 0, kmax))

    def gauss_newton(m, lam, g, coef, centres, mode):
        """Frame m's modes by Gauss-Newton on X_h and the weighted X_dh at the fit bins; mode
        'none' (stationary), 'fitted' (chirp rates g among the unknowns) or 'held'."""
        u, h, dh = windows[m]
        bins = fit_bins(centres)
        nu = 2 * np.pi * freqs[bins]
        wd_weight = (u[-1] - u[0]) / (2 * np.pi)
        data = np.concatenate([xh[:, m, bins].T.ravel(), wd_weight * xd[:, m, bins].T.ravel()])
        fitted = mode == "fitted"
        if mode == "none":
            g = np.zeros(2, complex)

        def model(lam, g, coef, jac=False):
            s = np.concatenate([lam, np.conj(lam)])[:, None] - 1j * nu[None, :]  # (4, B)
            gg = np.concatenate([g, np.conj(g)])[:, None] * np.ones((1, nu.size))
            w, wd, wt, wdt, wtt, wdtt = transforms(u, h, dh, s, gg)
            cc = np.concatenate([coef, np.conj(coef)])  # (4, C)
            mh = np.einsum("ib,ic->bc", w, cc)
            md = np.einsum("ib,ic->bc", wd, cc)
            out = np.concatenate([mh.ravel(), wd_weight * md.ravel()])
            if not jac:
                return out
            cols = []
            moments = [(wt, wdt, 1.0)] + ([(wtt, wdtt, 0.5)] if fitted else [])
            for j in range(2):
                for mh_, md_, f in moments:
                    for dp in (1.0, 1j):
                        dh_ = f * (np.outer(mh_[j], coef[j]) * dp + np.outer(mh_[j + 2], np.conj(coef[j])) * np.conj(dp))
                        dd_ = f * (np.outer(md_[j], coef[j]) * dp + np.outer(md_[j + 2], np.conj(coef[j])) * np.conj(dp))
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

        nl = 4 if fitted else 2
        r = data - model(lam, g, coef)
        cost = np.vdot(r, r).real
        for _ in range(10):
            mod, jac = model(lam, g, coef, True)
            r = data - mod
            cost = np.vdot(r, r).real
            a = np.vstack([jac.real, jac.imag])
            step = np.linalg.lstsq(a, np.concatenate([r.real, r.imag]), rcond=None)[0]
            ps = step[:nl * 2].reshape(2, nl)
            scale, improved = 1.0, False
            while scale > 1e-2 and not improved:
                nl_ = lam + scale * (ps[:, 0] + 1j * ps[:, 1])
                ng = g + scale * (ps[:, 2] + 1j * ps[:, 3]) if fitted else g
                nc = coef + scale * (step[2 * nl::2] + 1j * step[2 * nl + 1::2]).reshape(2, 2)
                r2 = data - model(nl_, ng, nc)
                improved = np.vdot(r2, r2).real <= cost
                scale *= 0.5
            if not improved:
                break
            lam, g, coef = nl_, ng, nc
            new_cost = np.vdot(r2, r2).real
            if cost - new_cost <= 1e-14 * cost:
                cost = new_cost
                break
            cost = new_cost
        noise_row = noise_trace * ((h * h).sum() + wd_weight ** 2 * (dh * dh).sum()) / 8.0
        # degenerate: out of order, or a mode's own part of X_h far above the data there
        s = np.concatenate([lam, np.conj(lam)])[:, None] - 1j * nu[None, :]
        gg = np.concatenate([g, np.conj(g)])[:, None] * np.ones((1, nu.size))
        w = transforms(u, h, dh, s, gg)[0]
        own = [np.sum(np.abs(np.outer(w[j], coef[j]) + np.outer(w[j + 2], np.conj(coef[j]))) ** 2) for j in range(2)]
        energy = np.sum(np.abs(xh[:, m, bins]) ** 2)
        degenerate = not lam[0].imag < lam[1].imag or max(own) > 10 ** 0.6 * energy
        return dict(lam=lam, g=g, coef=coef, cost=cost, rel=cost / np.vdot(data, data).real,
                    noise=noise_row, degenerate=degenerate, ok=bool(np.isfinite(cost)))

    def initial(m):
        lam = np.zeros(2, complex)
        for j in range(2):
            k = path_bins[m, j]
            r = (np.conj(xh[:, m, k]) * xd[:, m, k]).sum() / (np.abs(xh[:, m, k]) ** 2).sum()
            lam[j] = -r + 1j * 2 * np.pi * freqs[k]
        u, h, dh = windows[m]
        bins = path_bins[m]
        nu = 2 * np.pi * freqs[bins]
        zero = np.zeros((2, 2))
        w1 = transforms(u, h, dh, lam[:, None] - 1j * nu[None, :], zero)[0]
        w2 = transforms(u, h, dh, np.conj(lam)[:, None] - 1j * nu[None, :], zero)[0]
        a = np.zeros((4, 4))
        for i in range(2):
            for j in range(2):
                cre, cim = w1[j, i] + w2[j, i], 1j * (w1[j, i] - w2[j, i])
                a[2 * i:2 * i + 2, 2 * j] = [cre.real, cre.imag]
                a[2 * i:2 * i + 2, 2 * j + 1] = [cim.real, cim.imag]
        b = np.vstack([np.vstack([xh[:, m, bins[i]].real, xh[:, m, bins[i]].imag]) for i in range(2)])
        sol = np.linalg.solve(a, b)
        return lam, sol[0::2] + 1j * sol[1::2]

    def moved(fit, shift):
        f = dict(fit)
        f["coef"] = fit["coef"] * np.exp(fit["lam"] * shift + 0.5 * fit["g"] * shift * shift)[:, None]
        f["lam"] = fit["lam"] + fit["g"] * shift
        return f

    def nearest_bins(lam):
        return np.clip(np.rint(lam.imag / (2 * np.pi) / df).astype(int), 0, kmax)

    full_length = 2 * half
    chirp_window = np.array([(u[-1] - u[0]) / dt >= 0.9 * full_length - 1e-9 for u, _, _ in windows])

    def fit_frame(m, warm, shift):
        """Pass 1: stationary fit, and the chirped one kept when the F-type test asks for it."""
        fit = None
        if warm is not None and warm["ok"]:
            w = moved(warm, shift)
            centres = nearest_bins(w["lam"])
            fit = gauss_newton(m, w["lam"], w["g"], w["coef"], centres, "none")
            if not fit["ok"]:
                fit = None
        else:
            centres = path_bins[m]
            w = None
        if fit is None:
            centres = path_bins[m]
            lam0, coef0 = initial(m)
            fit = gauss_newton(m, lam0, np.zeros(2, complex), coef0, centres, "none")
            w = fit
        if chirp_window[m]:
            ch = gauss_newton(m, w["lam"], w["g"], w["coef"], centres, "fitted")
            if ch["ok"] and (not fit["ok"] or fit["cost"] - ch["cost"] > 30.0 * 4 * ch["noise"]):
                fit = ch
        return fit

    stride = max(1, int(round(0.01 / dt)))  # pass-1 frames about 10 ms apart
    mid = frames // 2
    full_frames = [m for m, (u, _, _) in enumerate(windows) if round((u[-1] - u[0]) / dt) == full_length]
    first_full = full_frames[0] if full_frames else mid
    start = fit_frame(mid, None, 0.0)
    for m in (first_full, (first_full + frames // 2) // 2):
        if m == mid or m >= frames // 2:
            continue
        f = fit_frame(m, None, 0.0)
        if f["ok"] and not f["degenerate"] and (not start["ok"] or start["degenerate"] or f["rel"] < start["rel"]):
            start, mid = f, m
    fits = [None] * frames
    fits[mid] = start
    for step in (stride, -stride):
        frm = mid
        for m in range(mid + step, frames if step > 0 else -1, step):
            fits[m] = fit_frame(m, fits[frm], (m - frm) * dt)
            if fits[m]["ok"] and not fits[m]["degenerate"]:
                frm = m
    # Pass 2: chirp rates held at the Savitzky-Golay slopes of pass 1's lambda tracks.
    grid = np.arange(mid % stride, frames, stride)
    good = [p for p, m in enumerate(grid) if fits[m]["ok"] and not fits[m]["degenerate"]]
    full = [p for p in good if chirp_window[grid[p]]]
    slope = np.zeros((grid.size, 2), complex)
    if len(full) >= 3:
        lam_full = np.array([fits[grid[p]]["lam"] for p in full])
        span = np.arange(full[0], full[-1] + 1)
        track = np.column_stack([np.interp(span, full, lam_full[:, j].real) for j in range(2)] +
                                [np.interp(span, full, lam_full[:, j].imag) for j in range(2)])
        rate = 1.0 / (stride * dt)
        win = 2 * int(round(0.5 * rate / 2)) + 1
        if win > span.size:
            win = span.size if span.size % 2 else span.size - 1
        if win >= 3:
            sl = savgol_filter(track, win, 2, deriv=1, delta=1.0 / rate, axis=0, mode="interp")
            slope[span] = sl[:, :2] + 1j * sl[:, 2:]
            slope[:span[0]] = slope[span[0]]
            slope[span[-1] + 1:] = slope[span[-1]]
    starts = np.array(full if full else good)
    refit = []
    for p, m in enumerate(grid):
        near = starts[np.argmin(np.abs(starts - p))]
        f = dict(fits[grid[near]])
        f["g"] = slope[p]
        f = moved(f, (m - grid[near]) * dt)
        refit.append(gauss_newton(m, f["lam"], f["g"], f["coef"], nearest_bins(f["lam"]), "held"))
    lam_all = np.zeros((frames, 2), complex)
    coef_all = np.zeros((frames, 2, 2), complex)
    for m in range(frames):
        p = int(np.clip(np.floor((m - grid[0]) / stride + 0.5), 0, grid.size - 1))  # as lround
        f = moved(refit[p], (m - grid[p]) * dt)
        lam_all[m], coef_all[m] = f["lam"], f["coef"]
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
    # Eq 43 weighted by the modes' amplitude-to-noise power 0.5 a^H (Sigma + floor I)^-1 a, the
    # floor 100 dB below the strongest mode's peak power per channel (ridge.cpp, modal_analysis.cpp):
    # P is the polar factor of the unit shapes times diag(weights).
    floor = 1e-10 * (0.5 * (np.abs(amp) ** 2).sum(axis=2) / 2).max() + 1e-300
    inv = np.linalg.inv(noise_cov + floor * np.eye(2))
    weight = 0.5 * np.einsum("tjc,cd,tjd->tj", amp.conj(), inv, amp).real
    for m in range(frames):
        p = root @ shapes[m].T
        p /= np.linalg.norm(p, axis=0)
        uu, _, vv = np.linalg.svd(p * (weight[m] / weight[m].max()))
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
