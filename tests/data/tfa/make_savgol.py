#!/usr/bin/env python3
"""Savitzky-Golay reference values for tests/estimators/test_savitzky_golay.cpp, made with scipy
(scipy.signal.savgol_coeffs / savgol_filter, mode="interp"). Run: python3 make_savgol.py"""
import json

import numpy as np
import scipy
from scipy.signal import savgol_coeffs, savgol_filter

rng = np.random.default_rng(20261123)
fs = 400.0
t = np.arange(257) / fs
x = np.sin(2 * np.pi * 3.0 * t) * np.exp(-1.3 * t) + 0.05 * rng.standard_normal(t.size)
cases = []
for window, order in [(101, 3), (21, 2), (7, 4)]:
    case = {"window": window, "order": order, "delta": 1 / fs}
    for d in range(3):
        case[f"coeffs_d{d}"] = savgol_coeffs(window, order, deriv=d, delta=1 / fs, use="dot").tolist()
        case[f"filter_d{d}"] = savgol_filter(x, window, order, deriv=d, delta=1 / fs, mode="interp").tolist()
    case["coeffs_pos2_d1"] = savgol_coeffs(window, order, deriv=1, delta=1 / fs, pos=2, use="dot").tolist()
    cases.append(case)
json.dump({"scipy": scipy.__version__, "fs": fs, "x": x.tolist(), "cases": cases},
          open("savgol.json", "w"), indent=None)
