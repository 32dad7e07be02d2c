#!/usr/bin/env python3
"""Draws the reassigned spectrogram written by `stiffid tfa --spectrogram MAP.csv -o OUT.json`
with the tracked ridges, like Piovesan et al. 2012 Figs 4-6: one panel per joint, the STFT
spectrogram (left) and the reassigned points (right), power in dB, ridges f_j(t) in black.

    python3 scripts/plot_spectrogram.py MAP.csv OUT.json [FIGURE.png]

Needs numpy and matplotlib (Debian: python3-numpy python3-matplotlib)."""
import csv
import json
import sys
from collections import defaultdict

import numpy as np


def read_map(path):
    rows = defaultdict(list)
    with open(path) as f:
        for r in csv.DictReader(f):
            rows[r["channel"]].append([float(r["t_s"]), float(r["f_hz"]), float(r["power"]),
                                       float(r["t_reassigned_s"]), float(r["f_reassigned_hz"])])
    return {k: np.array(v) for k, v in rows.items()}


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    maps = read_map(sys.argv[1])
    with open(sys.argv[2]) as f:
        result = json.load(f)
    t = np.array(result["t_s"], dtype=float)
    ridges = [np.array([np.nan if v is None else v for v in f], dtype=float) for f in result["f_ridge_hz"]]
    peak = max(m[:, 2].max() for m in maps.values())
    fig, axes = plt.subplots(len(maps), 2, figsize=(11, 3.5 * len(maps)), squeeze=False)
    for row, (name, m) in enumerate(maps.items()):
        db = 10 * np.log10(m[:, 2] / peak)
        for col, (tt, ff, title) in enumerate([(m[:, 0], m[:, 1], "STFT spectrogram"),
                                              (m[:, 3], m[:, 4], "reassigned spectrogram")]):
            ax = axes[row][col]
            order = np.argsort(db)
            sc = ax.scatter(tt[order], ff[order], c=db[order], s=2, cmap="viridis", vmin=-60, vmax=0)
            for f in ridges:
                ax.plot(t, f, "k-", lw=1)
            ax.set_title(f"{name}: {title}")
            ax.set_xlabel("t (s)")
            ax.set_ylabel("f (Hz)")
            ax.set_ylim(0, result["options"]["fmax_hz"])
            fig.colorbar(sc, ax=ax, label="power (dB re peak)")
    fig.tight_layout()
    out = sys.argv[3] if len(sys.argv) > 3 else "spectrogram.png"
    fig.savefig(out, dpi=120)
    print(out)


if __name__ == "__main__":
    main()
