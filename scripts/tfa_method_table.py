#!/usr/bin/python3
"""Both `stiffid tfa` methods side by side on stiffid's simulated posture trials.

  scripts/tfa_method_table.py [--stiffid build/stiffid] [--seed 1 | --seeds 1,2,3] [--snr 20,inf]
                              [--directions 0,45,90,135] [--profiles constant,sigmoid,sharp]
                              [--methods modal,spectrogram]
                              [--specs [NAME=]SPEC.json,...] [--summary] [-o TABLE.md]
                              [--intervals 2.6-3.175,2.6-4.5] [--valid-only]
                              [--set KEY=JSON ...]

For every profile (Piovesan's posture specs in models/specs/) or every spec file given with
--specs (named NAME, or the file name without "piovesan_posture_" and ".json"), impulse direction,
SNR (dB; inf = noise-free) and noise seed: `stiffid simulate` (the spec's first perturbation, an
impulse, turned to the direction, the given noise seed), `stiffid tfa --method modal` and `--method
spectrogram` (default options otherwise), and the percentage RMS error 100 RMS(est - true) /
RMS(true) of k11, k12, k22, c11, c12, c22 over 2.6-3.175 s and 2.6-4.5 s (--intervals: others,
e.g. 2.5-5,2.6-3.175,2.6-4.5 for issue 6's three) against the simulator's
truth (all frames, valid or not; with --valid-only the K and C errors over the frames the method
vouches for, defined below, instead), with the share of frames the modal method flags K_valid, and
the blow-up ratios max |k_ij(t)| / max |k_true_ij(t)| (and the same for C) over the frames in
2.6-4.5 s (1 when every frame stays within the truth's range) and the share of those frames whose
largest |k_ij| exceeds 2 x the truth's largest at that frame ("blown"), and the share of the
frames a method vouches for (K_valid for modal, every mode valid for spectrogram) that are blown
("valid K blown": values returned silently; the summary gives the worst run). --summary adds the means
over seeds per trial, direction and method, and over directions and seeds per trial and method,
with the count of runs meeting issue 7's targets (--targets K11,K22,K12 in % over 2.6-4.5 s,
default 10,10,25 for the non-common-factor trials; 15,15,20 for the 10 dB sigmoid case; and no
blown K frame). --set KEY=JSON (repeatable) changes every spec before the run, KEY a dotted path
whose integer parts index lists, e.g. --set task.hand_m=[0.45,-0.1] --set sample_rate_hz=1000
--set perturbations.0.amplitude_n=2 (a robustness sweep: docs/tfa_modal.md, "Cancelling
modes"). The tfa onset is the first perturbation's onset_s, and the intervals (those of the
targets too) are given for an onset at 2.5 s and move with it.
Prints Markdown tables (and writes them with -o).
Needs numpy (Debian python3-numpy); the tests do not use this script.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

from tfa_cases import fmt, rms_error, set_impulse, set_noise

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
COEFFICIENTS = [("k11", "K", 0, 0), ("k12", "K", 0, 1), ("k22", "K", 1, 1),
                ("c11", "C", 0, 0), ("c12", "C", 0, 1), ("c22", "C", 1, 1)]
INTERVALS = [(2.6, 3.175), (2.6, 4.5)]
TARGETS = [10.0, 10.0, 25.0]  # k11, k22, k12 % over 2.6-4.5 s (--targets)
VALID_ONLY = False  # errors over the frames the method vouches for only (--valid-only)
BLOWUP = 2.0  # a frame whose largest |K| (|C|) entry exceeds 2 x the truth's is blown up


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        return done.stderr.strip()
    return None


def set_key(spec, key, value):
    """spec[k1][k2]... = value for KEY k1.k2...; integer parts index lists."""
    parts = key.split(".")
    node = spec
    for i, part in enumerate(parts):
        index = int(part) if isinstance(node, list) else part
        if isinstance(node, list) and not -len(node) <= index < len(node):
            raise KeyError("no item %d in a list of %d" % (index, len(node)))
        if i == len(parts) - 1:
            node[index] = value
        else:
            if not isinstance(node, list) and part not in node:
                node[part] = {}
            node = node[index]


def errors(tfa, truth, shift=0.0):
    t = np.array(tfa["t_s"])
    tt = np.array(truth["time_s"])
    est = {"K": np.array(tfa["K_nm_per_rad"], dtype=float),
           "C": np.array(tfa["C_nms_per_rad"], dtype=float)}
    true = {"K": np.array(truth["stiffness_nm_per_rad"]),
            "C": np.array(truth["damping_nms_per_rad"])}
    # Frames the method vouches for: K_valid (modal), or every mode valid (spectrogram).
    k_valid = (np.array(tfa["K_valid"], dtype=bool) if "K_valid" in tfa
               else np.all(np.array(tfa["valid"], dtype=bool), axis=0))
    out = {}
    t = t - shift  # the intervals are given for an onset at 2.5 s (--set)
    tt = tt - shift
    for lo, hi in INTERVALS + [(2.6, 4.5)]:  # 2.6-4.5 s always: the targets are over it
        m = (t >= lo) & (t <= hi)
        if VALID_ONLY:
            m &= k_valid
        for name, which, r, c in COEFFICIENTS:
            ref = np.interp(t[m], tt, true[which][:, r, c])
            e = est[which][r][c][m]
            bad = ~np.isfinite(e)
            value = (np.nan if not m.any() else rms_error(e, ref) if not bad.any() else np.inf)
            out[(lo, hi, name)] = value
    m = (t >= 2.6) & (t <= 4.5)
    out["valid"] = 100.0 * np.mean(k_valid[m])
    # Blow-ups: the largest estimated entry of any frame against the largest true entry, and the
    # share of frames whose largest entry exceeds BLOWUP x the largest true entry at that frame.
    for which in ("K", "C"):
        e = np.abs(np.array([[est[which][r][c][m] for c in range(2)] for r in range(2)]))
        ref = np.abs(true[which][(tt >= 2.6) & (tt <= 4.5)])
        out["blowup_" + which] = np.max(e) / np.max(ref) if np.all(np.isfinite(e)) else np.inf
        frame_true = np.max(np.abs(np.array([[np.interp(t[m], tt, true[which][:, r, c])
                                              for c in range(2)] for r in range(2)])), axis=(0, 1))
        frame_est = np.max(np.where(np.isfinite(e), e, np.inf), axis=(0, 1))
        blown = frame_est > BLOWUP * frame_true
        out["blown_" + which] = 100.0 * np.mean(blown)
        # blown frames among those flagged valid: values returned silently
        out["valid_blown_" + which] = (100.0 * np.mean(blown[k_valid[m]]) if k_valid[m].any()
                                       else np.nan)
    k = [out[(2.6, 4.5, n)] for n in ("k11", "k22", "k12")]
    out["meets"] = (k[0] <= TARGETS[0] and k[1] <= TARGETS[1] and k[2] <= TARGETS[2] and
                    out["blown_K"] == 0.0)
    return out


def trials(a):
    """(name, spec dict) of every trial: --specs files, or the profiles' posture specs."""
    if a.specs:
        out = []
        for item in a.specs.split(","):
            name, _, path = item.rpartition("=")
            if not name:
                name = os.path.basename(path)[:-len(".json")].replace("piovesan_posture_", "")
            out.append((name, path))
    else:
        out = [(profile, os.path.join(ROOT, "models", "specs", "piovesan_posture_%s.json" % profile))
               for profile in a.profiles.split(",")]
    return [(name, json.load(open(path))) for name, path in out]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--stiffid", default=os.path.join(ROOT, "build", "stiffid"))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--seeds", default="", help="noise seeds, e.g. 1,2,3 (overrides --seed)")
    p.add_argument("--snr", default="20,inf")
    p.add_argument("--directions", default="0,45,90,135")
    p.add_argument("--profiles", default="constant,sigmoid,sharp")
    p.add_argument("--methods", default="modal,spectrogram", help="tfa methods to run")
    p.add_argument("--specs", default="", help="[NAME=]SPEC.json,... instead of --profiles")
    p.add_argument("--summary", action="store_true", help="add the means over directions and seeds")
    p.add_argument("--targets", default="10,10,25",
                   help="k11,k22,k12 limits in %% over 2.6-4.5 s for the runs-meeting count")
    p.add_argument("--intervals", default="2.6-3.175,2.6-4.5",
                   help="error intervals LO-HI in s, comma-separated")
    p.add_argument("--valid-only", action="store_true",
                   help="K and C errors over the frames the method vouches for only")
    p.add_argument("--set", action="append", default=[], metavar="KEY=JSON",
                   help="change every spec: KEY a dotted path (integer parts index lists)")
    p.add_argument("-o", "--output", default="")
    a = p.parse_args()
    changes = []
    for item in a.set:
        key, eq, value = item.partition("=")
        if not eq or not key:
            p.error("--set: expected KEY=JSON, got " + item)
        try:
            changes.append((key, json.loads(value)))
        except ValueError as e:
            p.error("--set %s: the value is not JSON (%s)" % (item, e))
    global TARGETS, INTERVALS, VALID_ONLY
    VALID_ONLY = a.valid_only
    try:
        INTERVALS = [tuple(float(v) for v in item.split("-")) for item in a.intervals.split(",")]
    except ValueError:
        p.error("--intervals: expected LO-HI,... in s, got " + a.intervals)
    if any(len(i) != 2 or not i[0] < i[1] for i in INTERVALS):
        p.error("--intervals: expected LO-HI,... with LO < HI, got " + a.intervals)
    TARGETS = [float(v) for v in a.targets.split(",")]
    if len(TARGETS) != 3:
        p.error("--targets: expected three numbers k11,k22,k12 (percent)")
    seeds = [int(x) for x in a.seeds.split(",")] if a.seeds else [a.seed]
    columns = ["%s %g-%g" % (n, lo, hi) for lo, hi in INTERVALS for n, *_ in COEFFICIENTS]
    lines = ["| trial | dir (deg) | SNR | seed | method | " + " | ".join(columns) +
             " | K_valid % | max|K|/max|K_true| | max|C|/max|C_true| | K blown % | C blown % |"
             " valid K blown % |",
             "|" + "---|" * (11 + len(columns))]
    results = {}  # (trial, snr, method) -> list of error dicts
    with tempfile.TemporaryDirectory() as work:
        for name, base in trials(a):
            for direction in (float(d) for d in a.directions.split(",")):
                for snr in a.snr.split(","):
                    for seed in seeds:
                        spec = json.loads(json.dumps(base))
                        for key, value in changes:
                            try:
                                set_key(spec, key, value)
                            except (KeyError, IndexError, TypeError, ValueError) as e:
                                sys.exit("--set %s: %s (trial %s)"
                                         % (key, e.args[0] if e.args else e, name))
                        set_impulse(spec, direction)
                        onset = float(spec["perturbations"][0]["onset_s"])
                        spec["seed"] = seed
                        set_noise(spec, None if snr == "inf" else float(snr))
                        spec_path = os.path.join(work, "spec.json")
                        json.dump(spec, open(spec_path, "w"))
                        trial = os.path.join(work, "trial.csv")
                        truth = os.path.join(work, "truth.json")
                        failure = run([a.stiffid, "simulate", spec_path, "-o", trial, "--truth", truth])
                        if failure:
                            sys.exit("simulate failed: " + failure)
                        truth_json = json.load(open(truth))
                        snr_text = "none" if snr == "inf" else snr + " dB"
                        for method in a.methods.split(","):
                            out = os.path.join(work, "tfa.json")
                            failure = run([a.stiffid, "tfa", trial, "--angles", "th1,th2", "--onset",
                                           "%.17g" % onset, "--method", method, "-o", out])
                            row = "| %s | %g | %s | %d | %s | " % (name, direction, snr_text, seed,
                                                                   method)
                            if failure:
                                row += " | ".join(["failed"] * len(columns)) + " | - | - | - | - | - | - |"
                                results.setdefault((name, direction, snr_text, method), []).append(None)
                            else:
                                e = errors(json.load(open(out)), truth_json, onset - 2.5)
                                results.setdefault((name, direction, snr_text, method), []).append(e)
                                row += " | ".join(fmt(e[(lo, hi, n)]) for lo, hi in INTERVALS
                                                  for n, *_ in COEFFICIENTS)
                                row += " | %s | %s | %s | %s | %s | %s |" % (
                                    fmt(e["valid"]), "%.2f" % e["blowup_K"],
                                    "%.2f" % e["blowup_C"], fmt(e["blown_K"]), fmt(e["blown_C"]),
                                    fmt(e["valid_blown_K"]))
                            lines.append(row)
                            print(row, flush=True)
    if a.summary:
        for title, by_direction in (("Means over seeds", True), ("Means over directions and seeds", False)):
            lines += ["", title + " (failed runs counted apart); worst blow-up ratio; runs meeting "
                      "the issue-7 targets:", "",
                      "| trial | dir (deg) | SNR | method | runs | " + " | ".join(columns) +
                      " | K_valid % | worst max|K|/max|K_true| | worst max|C|/max|C_true| | "
                      "K blown % | valid K blown % | runs meeting targets |",
                      "|" + "---|" * (11 + len(columns))]
            groups = {}
            for (name, direction, snr_text, method), runs in results.items():
                key = (name, direction if by_direction else "all", snr_text, method)
                groups.setdefault(key, []).extend(runs)
            for (name, direction, snr_text, method), runs in groups.items():
                ok = [e for e in runs if e is not None]
                row = "| %s | %s | %s | %s | %d%s | " % (
                    name, direction if isinstance(direction, str) else "%g" % direction, snr_text,
                    method, len(ok), "" if len(ok) == len(runs) else " (+%d failed)" % (len(runs) - len(ok)))
                if ok:
                    row += " | ".join(fmt(np.mean([e[(lo, hi, n)] for e in ok]))
                                      for lo, hi in INTERVALS for n, *_ in COEFFICIENTS)
                    silent = [e["valid_blown_K"] for e in ok if np.isfinite(e["valid_blown_K"])]
                    row += " | %s | %.2f | %.2f | %s | %s | %d / %d |" % (
                        fmt(np.mean([e["valid"] for e in ok])), max(e["blowup_K"] for e in ok),
                        max(e["blowup_C"] for e in ok), fmt(np.mean([e["blown_K"] for e in ok])),
                        fmt(max(silent)) if silent else "-", sum(e["meets"] for e in ok),
                        len(runs))
                else:
                    row += (" | ".join(["failed"] * len(columns)) +
                            " | - | - | - | - | - | 0 / %d |" % len(runs))
                lines.append(row)
                print(row, flush=True)
    text = "\n".join(lines) + "\n"
    if a.output:
        tmp = a.output + ".tmp"
        open(tmp, "w").write(text)
        os.replace(tmp, a.output)


if __name__ == "__main__":
    main()
