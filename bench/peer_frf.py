#!/usr/bin/python3
"""Peer of `stiffid frf` in Python (scipy.signal.csd + numpy.linalg.solve), for benchmarks.

Same arguments and the same core JSON keys as the C++ command:
  peer_frf.py TRIAL.csv --inputs fx,fy --outputs x,y [--nfft 256] [--overlap 0.5]
              [--window hann|hamming|kaiser:BETA|rect] [--detrend constant|linear|none]
              [--fs HZ] [-o OUT.json]
Welch spectra: nperseg = nfft, noverlap = int(overlap * nfft) (truncation, as stiffid),
one-sided density, Gxy[i][j] = mean(conj(X_i) Y_j). H1 MIMO FRF from Gxx H_j = Gxy_j; ordinary,
multiple and partial coherence (Bendat & Piersol conditioned spectra, any number of inputs);
Bendat & Piersol random-error bands as stiffid writes them under "random_error" (n_d = segments,
n_d - N + 1 for the conditioned quantities, bands value (1 -/+ 2 eps) clipped to [0, 1] for
coherences and [0, inf) for |H|). Non-finite values are written as null, as stiffid does.
"""
import argparse
import json
import sys

import numpy as np
import scipy.signal


def read_trial(path, fs_flag):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, comments="#", ndmin=2)
    names = [h.split("[")[0].split("(")[0].strip() for h in header]
    cols = {n: data[:, k] for k, n in enumerate(names)}
    if "t" in cols:
        t = cols.pop("t")
        fs = 1.0 / ((t[-1] - t[0]) / (len(t) - 1))
    else:
        fs = fs_flag
    if fs_flag:
        fs = fs_flag
    return cols, fs


def window_arg(text):
    if text.startswith("kaiser:"):
        return ("kaiser", float(text.split(":", 1)[1]))
    return {"rect": "boxcar", "rectangular": "boxcar"}.get(text, text)


def spectra(signals, fs, nfft, noverlap, window, detrend):
    """Cross-spectral matrix G[f, a, b] = E[conj(S_a) S_b] of all channels (F x C x C): csd for the
    pairs a <= b, and G[f, b, a] = conj(G[f, a, b])."""
    c = len(signals)
    freqs = None
    g = None
    for a in range(c):
        for b in range(a, c):
            f, p = scipy.signal.csd(signals[a], signals[b], fs=fs, window=window, nperseg=nfft,
                                    noverlap=noverlap, detrend=detrend, scaling="density")
            if g is None:
                freqs = f
                g = np.zeros((len(f), c, c), dtype=complex)
            g[:, a, b] = p
            g[:, b, a] = np.conj(p)
    return freqs, g


def conditioned(g, keep, given):
    """Conditioned spectral matrix of channels `keep` given channels `given` (F x k x k)."""
    gkk = g[:, keep][:, :, keep]
    if not given:
        return gkk
    gkr = g[:, keep][:, :, given]
    grr = g[:, given][:, :, given]
    grk = g[:, given][:, :, keep]
    return gkk - gkr @ np.linalg.solve(grr, grk)


def normalized_error(g2, dof, factor, power):
    """eps = factor (1 - g2)^power / (|g| sqrt(dof)); inf where g2 <= 0 (Bendat & Piersol)."""
    g2 = np.asarray(g2, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        eps = factor * np.maximum(0.0, 1.0 - g2) ** power / (np.sqrt(g2) * np.sqrt(dof))
    return np.where(g2 > 0.0, eps, np.inf)


def band(value, eps, c, cap):
    value = np.asarray(value, dtype=float)
    ok = np.isfinite(eps) & np.isfinite(value)
    with np.errstate(invalid="ignore"):
        lower = np.where(ok, np.maximum(0.0, value * (1.0 - c * eps)), 0.0)
        upper = np.where(ok, np.minimum(cap, value * (1.0 + c * eps)), cap)
    return {"eps": eps, "lower": lower, "upper": upper}


def equivalent_independent_segments(segments, nperseg, noverlap, window):
    """Welch's number of independent segments for overlapped, windowed segments."""
    if segments <= 1:
        return float(segments)
    w = scipy.signal.get_window(window, nperseg)
    step = nperseg - noverlap
    energy = np.dot(w, w)
    total = 0.0
    m = 1
    while m < segments and m * step < nperseg:
        shared = nperseg - m * step
        rho = np.dot(w[:shared], w[-shared:]) / energy
        total += (1.0 - m / segments) * rho * rho
        m += 1
    return segments / (1.0 + 2.0 * total)


def finite_or_none(x):
    """Nested lists and dicts of numbers with inf and NaN replaced by None (JSON null)."""
    if isinstance(x, dict):
        return {k: finite_or_none(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return [v if np.isfinite(v) else None for v in x.tolist()]
    return x


def main(argv):
    p = argparse.ArgumentParser()
    p.add_argument("trial")
    p.add_argument("--inputs", required=True)
    p.add_argument("--outputs", required=True)
    p.add_argument("--nfft", type=int, default=256)
    p.add_argument("--overlap", type=float, default=0.5)
    p.add_argument("--window", default="hann")
    p.add_argument("--detrend", default="constant")
    p.add_argument("--fs", type=float, default=0.0)
    p.add_argument("-o", "--output", default="")
    a = p.parse_args(argv)
    cols, fs = read_trial(a.trial, a.fs)
    inputs = a.inputs.split(",")
    outputs = a.outputs.split(",")
    n, m = len(inputs), len(outputs)
    noverlap = int(a.overlap * a.nfft)
    detrend = False if a.detrend == "none" else a.detrend
    signals = [cols[k] for k in inputs + outputs]
    freqs, g = spectra(signals, fs, a.nfft, noverlap, window_arg(a.window), detrend)
    gxx = g[:, :n, :n]
    gxy = g[:, :n, n:]
    h = np.linalg.solve(gxx, gxy)  # (F x N x M): column j solves Gxx H_j = Gxy_j
    out = {"fs": fs, "nfft": a.nfft,
           "segments": (len(signals[0]) - noverlap) // (a.nfft - noverlap),
           "inputs": inputs, "outputs": outputs, "frequency_hz": freqs.tolist(),
           "frf": {}, "coherence": {"ordinary": {}, "multiple": {}, "partial": {}},
           "condition_number": np.linalg.cond(gxx).tolist()}
    for j, yo in enumerate(outputs):
        gyy = g[:, n + j, n + j].real
        out["frf"][yo] = {xi: {"re": h[:, i, j].real.tolist(), "im": h[:, i, j].imag.tolist()}
                          for i, xi in enumerate(inputs)}
        out["coherence"]["ordinary"][yo] = {
            xi: (np.abs(gxy[:, i, j]) ** 2 / (gxx[:, i, i].real * gyy)).tolist()
            for i, xi in enumerate(inputs)}
        out["coherence"]["multiple"][yo] = (
            np.einsum("fi,fi->f", np.conj(h[:, :, j]), gxy[:, :, j]).real / gyy).tolist()
        partial = {}
        for i, xi in enumerate(inputs):
            others = [k for k in range(n) if k != i]
            s = conditioned(g, [i, n + j], others)
            partial[xi] = (np.abs(s[:, 0, 1]) ** 2 / (s[:, 0, 0].real * s[:, 1, 1].real)).tolist()
        out["coherence"]["partial"][yo] = partial
    segments = out["segments"]
    nd, c = float(segments), 2.0
    ndc = nd - n + 1
    err = {"averages": nd, "confidence_factor": c,
           "equivalent_independent_segments": equivalent_independent_segments(
               segments, a.nfft, noverlap, window_arg(a.window)),
           "frf_magnitude": {}, "coherence": {"ordinary": {}, "multiple": {}, "partial": {}}}
    for j, yo in enumerate(outputs):
        multiple = np.array(out["coherence"]["multiple"][yo])
        err["coherence"]["multiple"][yo] = band(
            multiple, normalized_error(multiple, ndc, np.sqrt(2.0), 1.0), c, 1.0)
        err["frf_magnitude"][yo], err["coherence"]["ordinary"][yo] = {}, {}
        err["coherence"]["partial"][yo] = {}
        for i, xi in enumerate(inputs):
            ordinary = np.array(out["coherence"]["ordinary"][yo][xi])
            partial = np.array(out["coherence"]["partial"][yo][xi])
            err["coherence"]["ordinary"][yo][xi] = band(
                ordinary, normalized_error(ordinary, nd, np.sqrt(2.0), 1.0), c, 1.0)
            err["coherence"]["partial"][yo][xi] = band(
                partial, normalized_error(partial, ndc, np.sqrt(2.0), 1.0), c, 1.0)
            err["frf_magnitude"][yo][xi] = band(
                np.abs(h[:, i, j]), normalized_error(partial, 2.0 * ndc, 1.0, 0.5), c, np.inf)
    out["random_error"] = finite_or_none(err)
    text = json.dumps(out, indent=2)
    if a.output and a.output != "-":
        with open(a.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
