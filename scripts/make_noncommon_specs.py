#!/usr/bin/python3
"""Writes the three posture trials of issue 7 whose stiffness and damping do NOT change by a
common factor, as stiffid specs in models/specs/:

  piovesan_posture_k22_only.json         K(t) = [35 5; 5 20 u2(t)] N m/rad (only k22 follows the
                                         sigmoid u2 of Piovesan eq 54, 1 -> ~5 from 2.5 s),
                                         C(t) = 0.01 K(t)
  piovesan_posture_damping_nonprop.json  K(t) = K0 u2(t), C = C0 = 0.01 K0 constant (the existing
                                         stiffness_profile / damping_profile keys; no table)
  piovesan_posture_rotating.json         K(t) = R(phi) K0 R(phi)^T, phi from 0 to 30 deg along the
                                         normalised sigmoid (u2(t) - u2(2.5)) / (u2(5) - u2(2.5)):
                                         the joint stiffness ellipse turns by 30 deg, its axes
                                         keep their lengths; C(t) = 0.01 K(t)

Otherwise as piovesan_posture_sigmoid.json (5 s at 4 kHz, hand at (0.4, 0) m, 5 N / 20 ms impulse
at 2.5 s in a random octant) with 20 dB noise. K0 = [35 5; 5 20] N m/rad (eq 52). The tables
sample K(t), C(t) every 10 ms from 2.5 to 5 s (held before the first knot, as stiffid does):
linear interpolation of u2 errs by at most h^2/8 max|u2''| = 7.7e-5 (k22: 1.5e-3 N m/rad against
20-100), of the rotation by 1.8e-4 N m/rad per entry (measured at 4 kHz), far below what the
estimators resolve. k22_only carries one extra knot a sample (0.25 ms) before 2.5 s holding
K0, so that K = K0 before the start and u2's jump to 1.027 at 2.5 s is kept (the arm rests until
the impulse at 2.5 s, so the 0.25 ms ramp between those knots moves nothing).

  scripts/make_noncommon_specs.py [--grid-s 0.01] [--out-dir models/specs]
Needs numpy (Debian python3-numpy).
"""
import argparse
import json
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
K0 = np.array([[35.0, 5.0], [5.0, 20.0]])
START_S, HORIZON_S, SAMPLE_S = 2.5, 5.0, 1.0 / 4000.0


def u2(t):
    """Piovesan eq 54 sigmoid, T = 5 s (u = 1 before START_S is applied by the callers)."""
    return 4.0 / (1.0 + np.exp(-4.0 * (t - 0.75 * HORIZON_S))) + 1.0


def normalised_sigmoid(t):
    return (u2(t) - u2(START_S)) / (u2(HORIZON_S) - u2(START_S))


def rotation(phi):
    return np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])


def symmetric(m):
    m = np.array(m, dtype=float)
    m[1, 0] = m[0, 1]  # exactly symmetric after rounding
    return m


def base_spec():
    spec = json.load(open(os.path.join(ROOT, "models", "specs", "piovesan_posture_sigmoid.json")))
    spec["noise"] = {"snr_db": 20}
    return spec


def table(times, matrices, key):
    return {"time_s": [float("%.12g" % t) for t in times],
            key: [[[float("%.12g" % x) for x in row] for row in m] for m in matrices]}


def k22_only(grid):
    times = [START_S - SAMPLE_S] + list(grid)
    ks = [K0.copy()]
    for t in grid:
        k = K0.copy()
        k[1, 1] *= u2(t)
        ks.append(k)
    return ks, times


def rotating(grid):
    ks = [symmetric(rotation(np.radians(30.0) * normalised_sigmoid(t)) @ K0 @
                    rotation(np.radians(30.0) * normalised_sigmoid(t)).T) for t in grid]
    return ks, list(grid)


def write(spec, path):
    """JSON with one knot matrix per line (json.dumps, then the tables' innermost lists joined)."""
    shown = json.loads(json.dumps(spec))
    compact = {}
    for key in ("stiffness_table", "damping_table"):
        if key in spec["viscoelasticity"]:
            t = spec["viscoelasticity"][key]
            (vkey,) = [k for k in t if k != "time_s"]
            compact[key] = ("{\n      \"time_s\": [" + ", ".join(json.dumps(x) for x in t["time_s"]) +
                            "],\n      \"%s\": [\n        " % vkey +
                            ",\n        ".join(json.dumps(m) for m in t[vkey]) + "\n      ]\n    }")
            shown["viscoelasticity"][key] = "@@%s@@" % key
    text = json.dumps(shown, indent=2)
    for key, block in compact.items():
        text = text.replace("\"@@%s@@\"" % key, block)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text + "\n")
    os.replace(tmp, path)


def tabled_spec(ks, times):
    """The base spec with K(t) = ks at `times` and C(t) = 0.01 K(t) as matrix tables."""
    spec = base_spec()
    v = spec["viscoelasticity"]
    for k in ("stiffness_nm_per_rad", "damping_nms_per_rad", "stiffness_profile", "damping_profile"):
        v.pop(k)
    v["stiffness_table"] = table(times, ks, "stiffness_nm_per_rad")
    v["damping_table"] = table(times, [0.01 * k for k in ks], "damping_nms_per_rad")
    return spec


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--grid-s", type=float, default=0.01)
    p.add_argument("--out-dir", default=os.path.join(ROOT, "models", "specs"))
    a = p.parse_args()
    n = int(round((HORIZON_S - START_S) / a.grid_s))
    grid = START_S + a.grid_s * np.arange(n + 1)

    write(tabled_spec(*k22_only(grid)), os.path.join(a.out_dir, "piovesan_posture_k22_only.json"))

    spec = base_spec()  # K0 u2(t), C0 constant: the existing keys do it
    spec["viscoelasticity"]["damping_profile"] = {"kind": "constant"}
    write(spec, os.path.join(a.out_dir, "piovesan_posture_damping_nonprop.json"))

    write(tabled_spec(*rotating(grid)), os.path.join(a.out_dir, "piovesan_posture_rotating.json"))


if __name__ == "__main__":
    main()
