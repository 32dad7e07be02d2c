#!/usr/bin/python3
"""Both `stiffid tfa` methods side by side on stiffid's simulated posture trials.

  scripts/tfa_method_table.py [--stiffid build/stiffid] [--seed 1] [--snr 20,inf]
                              [--directions 0,45,90,135] [--profiles constant,sigmoid,sharp]
                              [-o TABLE.md]

For every profile (Piovesan's posture specs in models/specs/), impulse direction and SNR (dB; inf
= noise-free): `stiffid simulate` (the spec's impulse turned to the direction, the given noise
seed), `stiffid tfa --method modal` and `--method spectrogram` (default options otherwise), and the
percentage RMS error 100 RMS(est - true) / RMS(true) of k11, k12, k22, c11, c12, c22 over
2.6-3.175 s and 2.6-4.5 s against the simulator's truth (all frames, valid or not), with the share
of frames the modal method flags K_valid. Prints a Markdown table (and writes it with -o).
Needs numpy (Debian python3-numpy); the tests do not use this script.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
COEFFICIENTS = [("k11", "K", 0, 0), ("k12", "K", 0, 1), ("k22", "K", 1, 1),
                ("c11", "C", 0, 0), ("c12", "C", 0, 1), ("c22", "C", 1, 1)]
INTERVALS = [(2.6, 3.175), (2.6, 4.5)]


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        return done.stderr.strip()
    return None


def errors(tfa, truth):
    t = np.array(tfa["t_s"])
    tt = np.array(truth["time_s"])
    est = {"K": np.array(tfa["K_nm_per_rad"], dtype=float),
           "C": np.array(tfa["C_nms_per_rad"], dtype=float)}
    true = {"K": np.array(truth["stiffness_nm_per_rad"]),
            "C": np.array(truth["damping_nms_per_rad"])}
    out = {}
    for lo, hi in INTERVALS:
        m = (t >= lo) & (t <= hi)
        for name, which, r, c in COEFFICIENTS:
            ref = np.interp(t[m], tt, true[which][:, r, c])
            e = est[which][r][c][m]
            bad = ~np.isfinite(e)
            value = 100.0 * np.sqrt(np.mean((e - ref) ** 2) / np.mean(ref ** 2)) if not bad.any() else np.inf
            out[(lo, hi, name)] = value
    if "K_valid" in tfa:
        m = (t >= 2.6) & (t <= 4.5)
        out["valid"] = 100.0 * np.mean(np.array(tfa["K_valid"])[m])
    return out


def fmt(v):
    if not np.isfinite(v):
        return "n/a"
    return "%.1f" % v if v < 1000 else "%.0e" % v


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--stiffid", default=os.path.join(ROOT, "build", "stiffid"))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--snr", default="20,inf")
    p.add_argument("--directions", default="0,45,90,135")
    p.add_argument("--profiles", default="constant,sigmoid,sharp")
    p.add_argument("-o", "--output", default="")
    a = p.parse_args()
    lines = ["| profile | dir (deg) | SNR | method | " +
             " | ".join("%s %g-%g" % (n, lo, hi) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS) +
             " | K_valid % |",
             "|" + "---|" * (5 + len(INTERVALS) * len(COEFFICIENTS))]
    with tempfile.TemporaryDirectory() as work:
        for profile in a.profiles.split(","):
            for direction in (float(d) for d in a.directions.split(",")):
                for snr in a.snr.split(","):
                    spec = json.load(open(os.path.join(ROOT, "models", "specs",
                                                       "piovesan_posture_%s.json" % profile)))
                    pulse = spec["perturbations"][0]
                    pulse.pop("random_octant", None)
                    pulse.pop("octant", None)
                    pulse["direction_deg"] = direction
                    spec["seed"] = a.seed
                    if snr != "inf":
                        spec["noise"] = {"snr_db": float(snr)}
                    spec_path = os.path.join(work, "spec.json")
                    json.dump(spec, open(spec_path, "w"))
                    trial, truth = os.path.join(work, "trial.csv"), os.path.join(work, "truth.json")
                    failure = run([a.stiffid, "simulate", spec_path, "-o", trial, "--truth", truth])
                    if failure:
                        sys.exit("simulate failed: " + failure)
                    truth_json = json.load(open(truth))
                    for method in ("modal", "spectrogram"):
                        out = os.path.join(work, "tfa.json")
                        failure = run([a.stiffid, "tfa", trial, "--angles", "th1,th2", "--onset",
                                       "2.5", "--method", method, "-o", out])
                        row = "| %s | %g | %s | %s | " % (profile, direction,
                                                          "none" if snr == "inf" else snr + " dB",
                                                          method)
                        if failure:
                            row += " | ".join(["failed"] * (len(INTERVALS) * len(COEFFICIENTS))) + " | - |"
                        else:
                            e = errors(json.load(open(out)), truth_json)
                            row += " | ".join(fmt(e[(lo, hi, n)]) for lo, hi in INTERVALS
                                              for n, *_ in COEFFICIENTS)
                            row += " | %s |" % (fmt(e["valid"]) if "valid" in e else "-")
                        lines.append(row)
                        print(row, flush=True)
    text = "\n".join(lines) + "\n"
    if a.output:
        tmp = a.output + ".tmp"
        open(tmp, "w").write(text)
        os.replace(tmp, a.output)


if __name__ == "__main__":
    main()
