#!/usr/bin/python3
"""Makes the window and Welch-spectra fixtures of tests/estimators/test_window.cpp and
test_spectra.cpp with scipy (independent of stiffid). Run from anywhere:
    /usr/bin/python3 tests/data/spectra/make_fixtures.py
Writes windows.json and welch.json beside this script. scipy 1.10.1, numpy 1.24 (Debian 12).
"""
import json
import os

import numpy as np
import scipy.signal

HERE = os.path.dirname(os.path.abspath(__file__))


def windows():
    cases = []
    specs = [("hann", "hann"), ("hamming", "hamming"), ("rect", "boxcar"),
             ("kaiser:0", ("kaiser", 0.0)), ("kaiser:8.6", ("kaiser", 8.6)),
             ("kaiser:14", ("kaiser", 14.0))]
    for text, spec in specs:
        for n in [1, 2, 7, 8, 31, 64]:
            for periodic in [True, False]:
                w = scipy.signal.get_window(spec, n, fftbins=periodic)
                cases.append({"window": text, "n": n, "periodic": periodic, "w": w.tolist()})
    return cases


def welch():
    rng = np.random.default_rng(20261123)
    n, c = 300, 3
    # Three correlated channels with a trend and an offset, so detrending matters.
    e = rng.standard_normal((n, c))
    t = np.arange(n)
    x = np.column_stack([e[:, 0] + 0.02 * t + 1.5,
                         0.6 * e[:, 0] + e[:, 1] - 0.01 * t,
                         np.convolve(e[:, 2], [1.0, 0.5, 0.25], mode="same") + 0.3 * e[:, 1]])
    # name, window text, scipy window, detrend, nperseg, nfft, overlap, fs
    specs = [
        ("hann_constant_even", "hann", "hann", "constant", 64, 64, 0.5, 1.0),
        ("hamming_linear_trunc", "hamming", "hamming", "linear", 100, 100, 0.29, 200.0),
        ("kaiser_none_odd", "kaiser:8.6", ("kaiser", 8.6), "none", 33, 33, 0.7, 50.0),
        ("rect_constant_no_overlap", "rect", "boxcar", "constant", 40, 40, 0.0, 10.0),
        ("hann_linear_odd", "hann", "hann", "linear", 31, 31, 0.57, 1000.0),
        ("hann_constant_zero_padded", "hann", "hann", "constant", 48, 64, 0.5, 1.0),
        ("hann_constant_one_segment", "hann", "hann", "constant", 300, 300, 0.5, 2.0),
    ]
    cases = []
    for name, text, win, detrend, nperseg, nfft, overlap, fs in specs:
        # stiffid's convention: noverlap = floor(overlap * nperseg) of the double product, which
        # is Python's int() for these non-negative values (0.29 * 100 = 28.999999999999996 -> 28).
        noverlap = int(overlap * nperseg)
        g_re = [[None] * c for _ in range(c)]
        g_im = [[None] * c for _ in range(c)]
        for a in range(c):
            for b in range(c):
                f, p = scipy.signal.csd(x[:, a], x[:, b], fs=fs, window=win, nperseg=nperseg,
                                        noverlap=noverlap, nfft=nfft,
                                        detrend=False if detrend == "none" else detrend,
                                        return_onesided=True, scaling="density", average="mean")
                g_re[a][b] = p.real.tolist()
                g_im[a][b] = p.imag.tolist()
        _, pxx = scipy.signal.welch(x[:, 0], fs=fs, window=win, nperseg=nperseg,
                                    noverlap=noverlap, nfft=nfft,
                                    detrend=False if detrend == "none" else detrend)
        cases.append({"name": name, "window": text, "detrend": detrend, "nperseg": nperseg,
                      "nfft": nfft, "overlap": overlap, "noverlap": noverlap, "fs": fs,
                      "segments": (n - noverlap) // (nperseg - noverlap),
                      "frequency_hz": f.tolist(), "g_re": g_re, "g_im": g_im,
                      "welch_psd_0": pxx.tolist()})
    return {"signals": x.T.tolist(), "cases": cases}


def dump(name, value):
    with open(os.path.join(HERE, name), "w") as f:
        json.dump(value, f, separators=(",", ":"))  # repr of doubles: round-trips exactly
        f.write("\n")


if __name__ == "__main__":
    dump("windows.json", windows())
    dump("welch.json", welch())
