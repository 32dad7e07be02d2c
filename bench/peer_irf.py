#!/usr/bin/python3
"""Peer of `stiffid irf` in Python (numpy FFT correlations + scipy.linalg.solve), for benchmarks.

  peer_irf.py TRIAL.csv --inputs fx,fy --outputs x,y --lags A:B [--pinv mdl] [--fs HZ] [-o OUT.json]

Same conventions and core JSON keys as the C++ command: biased correlations with means removed,
phi_xy(d) = 1/S sum_k x(k) y(k + d), all from one batched zero-padded real FFT of every channel;
the block-Toeplitz system Psi H = Phi_xy (Perreault et al. 1999 eq 11) solved with
Cholesky (scipy.linalg.cho_factor / cho_solve with LAPACK dpocon for the reciprocal condition
number: what scipy.linalg.solve(assume_a="pos") does inside, with the condition kept for the
output; scipy has no block-Toeplitz solver, solve_toeplitz is for scalar Toeplitz matrices only), or with --pinv mdl the Westwick & Kearney pseudo-inverse as
stiffid computes it (numpy.linalg.eigh of Psi; eigenvectors above n eps max(w), ordered by their
contribution to the output variance, as many as minimise MDL(m) = (1 + m M ln(n)/n) V(m),
n = S M); h = H / dt; predicted outputs by FFT convolution; VAF per
output and R^2 from the predicted outputs.
"""
import argparse
import json
import sys

import numpy as np
import scipy.fft
import scipy.linalg
import scipy.linalg.lapack


def read_trial(path, fs_flag):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, comments="#", ndmin=2)
    names = [h.split("[")[0].split("(")[0].strip() for h in header]
    cols = {n: data[:, k] for k, n in enumerate(names)}
    fs = fs_flag
    if "t" in cols:
        t = cols.pop("t")
        fs = fs_flag or 1.0 / ((t[-1] - t[0]) / (len(t) - 1))
    return cols, fs


def pseudo_inverse(psi, phi_xy, output_power, samples):
    """dt * h by the MDL pseudo-inverse of Westwick & Kearney 1997 (the rule of stiffid's mdl)."""
    w, v = np.linalg.eigh(psi)  # ascending
    proj = v.T @ phi_xy
    usable = np.flatnonzero(w > len(w) * np.finfo(float).eps * w[-1])
    total = (proj[usable] ** 2 / w[usable, None] / output_power[None, :]).sum(axis=1)
    order = usable[np.lexsort((-w[usable], -total))]  # decreasing contribution, then eigenvalue
    n_out = phi_xy.shape[1]
    n = float(samples) * n_out
    residual = np.maximum(n_out - np.cumsum(np.sort(total)[::-1]), 0.0)
    m = np.arange(1, len(order) + 1)
    keep = int(np.argmin((1.0 + m * n_out * np.log(n) / n) * residual)) + 1
    kept = order[:keep]
    return v[:, kept] @ (proj[kept] / w[kept, None])


def main(argv):
    p = argparse.ArgumentParser()
    p.add_argument("trial")
    p.add_argument("--inputs", required=True)
    p.add_argument("--outputs", required=True)
    p.add_argument("--lags", required=True)
    p.add_argument("--pinv", choices=["mdl"], default=None)
    p.add_argument("--fs", type=float, default=0.0)
    p.add_argument("-o", "--output", default="")
    a = p.parse_args(argv)
    cols, fs = read_trial(a.trial, a.fs)
    inputs, outputs = a.inputs.split(","), a.outputs.split(",")
    n_in, n_out = len(inputs), len(outputs)
    first_s, last_s = (float(v) for v in a.lags.split(":"))
    first, last = int(round(first_s * fs)), int(round(last_s * fs))
    lags = last - first + 1
    max_lag = max(lags - 1, abs(first), abs(last))

    x = np.column_stack([cols[k] for k in inputs])
    y = np.column_stack([cols[k] for k in outputs])
    s = x.shape[0]
    x = x - x.mean(axis=0)
    y = y - y.mean(axis=0)
    nfft = scipy.fft.next_fast_len(s + max_lag, real=True)
    spec = scipy.fft.rfft(np.column_stack([x, y]), nfft, axis=0)
    pairs = [(i, k) for i in range(n_in) for k in range(i, n_in)]
    pairs += [(i, n_in + j) for j in range(n_out) for i in range(n_in)]
    prod = np.conj(spec[:, [p_[0] for p_ in pairs]]) * spec[:, [p_[1] for p_ in pairs]]
    circ = scipy.fft.irfft(prod, nfft, axis=0) / s
    phi = np.concatenate([circ[nfft - max_lag:], circ[: max_lag + 1]])  # rows d + max_lag

    diff = np.arange(lags)[:, None] - np.arange(lags)[None, :] + max_lag
    psi = np.empty((n_in * lags, n_in * lags))
    for c, (i, k) in enumerate(pairs[: n_in * (n_in + 1) // 2]):
        block = phi[diff, c]
        psi[i * lags:(i + 1) * lags, k * lags:(k + 1) * lags] = block
        psi[k * lags:(k + 1) * lags, i * lags:(i + 1) * lags] = block.T
    off = n_in * (n_in + 1) // 2
    phi_xy = np.empty((n_in * lags, n_out))
    for j in range(n_out):
        for i in range(n_in):
            phi_xy[i * lags:(i + 1) * lags, j] = phi[first + max_lag:first + max_lag + lags,
                                                     off + i + n_in * j]
    if a.pinv:
        coef = pseudo_inverse(psi, phi_xy, (y**2).mean(axis=0), s)
    else:
        factor = scipy.linalg.cho_factor(psi, lower=False, check_finite=False)
        rcond, info = scipy.linalg.lapack.dpocon(factor[0], np.linalg.norm(psi, 1), uplo="U")
        condition = 1.0 / rcond if rcond > 0 else float("inf")
        coef = scipy.linalg.cho_solve(factor, phi_xy, check_finite=False)  # dt * h
    h = coef * fs

    kernels = np.zeros((nfft, n_in * n_out))
    idx = np.arange(first, last + 1) % nfft
    for j in range(n_out):
        for i in range(n_in):
            kernels[idx, i + n_in * j] = coef[i * lags:(i + 1) * lags, j]
    kspec = scipy.fft.rfft(kernels, axis=0)
    yspec = np.stack([(spec[:, :n_in] * kspec[:, n_in * j:n_in * (j + 1)]).sum(axis=1)
                      for j in range(n_out)], axis=1)
    yhat = scipy.fft.irfft(yspec, nfft, axis=0)[:s]
    e = y - yhat
    vaf = 100.0 * (1.0 - e.var(axis=0) / y.var(axis=0))
    r2 = 100.0 * (1.0 - np.sum(e**2) / np.sum(y**2))
    explained = (phi_xy * coef).sum(axis=0)  # eqs 12-13 from the correlations
    power = (y**2).mean(axis=0)

    out = {"fs": fs, "inputs": inputs, "outputs": outputs,
           "lag_s": (np.arange(first, last + 1) / fs).tolist(),
           "irf": {yo: {xi: h[i * lags:(i + 1) * lags, j].tolist() for i, xi in enumerate(inputs)}
                   for j, yo in enumerate(outputs)},
           "vaf_percent": {yo: float(vaf[j]) for j, yo in enumerate(outputs)},
           "r2_percent": float(r2),
           "vaf_correlation_percent": {yo: float(100.0 * explained[j] / power[j])
                                       for j, yo in enumerate(outputs)},
           "r2_correlation_percent": float(100.0 * explained.sum() / power.sum())}
    if not a.pinv:
        out["condition_number"] = condition
    text = json.dumps(out, indent=2)
    if a.output and a.output != "-":
        with open(a.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
