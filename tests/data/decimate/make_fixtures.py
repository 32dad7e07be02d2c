#!/usr/bin/python3
"""Makes the decimation fixture of tests/estimators/test_decimate.cpp with scipy (independent of
stiffid). Run from anywhere:
    /usr/bin/python3 tests/data/decimate/make_fixtures.py
Writes decimate.json beside this script. scipy 1.10.1, numpy 1.24 (Debian 12).

Each case: a seeded random record x (samples x channels) at rate_hz, the factor D, the filter's
half-length per factor H (so 2 H D + 1 taps), cut-off fraction and Kaiser beta as in
estimators/decimate.hpp, and the expected output: scipy.signal.firwin's Kaiser-windowed low-pass
(unit DC gain) applied zero-phase, every D-th sample from the first; where the filter reaches
past either end of the record, the taps that fall inside, renormalised to unit sum.
"""
import json
import os

import numpy as np
import scipy.signal

HERE = os.path.dirname(os.path.abspath(__file__))


def expected(x, d, half_per_factor, cutoff_fraction, beta):
    half = half_per_factor * d
    # Cut-off in units of the input Nyquist frequency: cutoff_fraction of the output Nyquist.
    h = scipy.signal.firwin(2 * half + 1, cutoff_fraction / d, window=("kaiser", beta))
    n = x.shape[0]
    out = []
    for i in range(0, n, d):
        lo, hi = max(-half, -i), min(half, n - 1 - i)
        taps = h[lo + half:hi + half + 1]
        out.append(taps @ x[i + lo:i + hi + 1] / taps.sum())
    return np.array(out)


def main():
    rng = np.random.default_rng(20261206)
    specs = [  # name, samples, channels, rate, D, H, cut-off fraction, beta
        ("short_filter_d4", 203, 2, 400.0, 4, 5, 0.8, 9.0),
        ("default_filter_d3", 160, 3, 300.0, 3, 12, 0.8, 9.0),
        ("short_filter_d20", 700, 1, 4000.0, 20, 5, 0.8, 9.0),
        ("custom_cutoff_beta", 97, 2, 100.0, 2, 7, 0.5, 5.0),
    ]
    cases = []
    for name, n, c, rate, d, half, cutoff, beta in specs:
        x = np.cumsum(rng.standard_normal((n, c)), axis=0) + rng.standard_normal((n, c))
        y = expected(x, d, half, cutoff, beta)
        cases.append({"name": name, "rate_hz": rate, "factor": d, "half_taps_per_factor": half,
                      "cutoff_fraction": cutoff, "kaiser_beta": beta, "x": x.tolist(),
                      "y": y.tolist()})
    with open(os.path.join(HERE, "decimate.json"), "w") as f:
        json.dump(cases, f)


if __name__ == "__main__":
    main()
