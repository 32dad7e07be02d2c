#!/usr/bin/python3
"""Peer of bench_anova.cpp in numpy/scipy: the same 3-way within design (20 subjects x 4 x 4 x 3,
960 rows in long format), the same work (cell means from the long table, every effect's SS, F, p,
Greenhouse-Geisser and Huynh-Feldt epsilon and corrected p, Mauchly's W). Prints the median wall
time of one analysis over `repeats` runs (argument 1, default 200). Data come from numpy's own
seeded generator, so the numbers differ from the C++ run; the work does not.
"""
import itertools
import sys
import time

import numpy as np
from scipy import stats


def design(rng):
    rows = []
    for s in range(20):
        subject = 2.0 * rng.standard_normal()
        for a in range(4):
            for b in range(4):
                for c in range(3):
                    y = 10 + subject + 0.3 * a + 0.2 * b * c + (0.5 + 0.2 * a) * rng.standard_normal()
                    rows.append((f"s{s}", f"a{a}", f"b{b}", f"c{c}", y))
    return rows


def helmert(levels):
    c = np.zeros((levels, levels - 1))
    for j in range(levels - 1):
        c[: j + 1, j] = 1.0
        c[j + 1, j] = -(j + 1)
        c[:, j] /= np.sqrt((j + 1) * (j + 2))
    return c


def analyse(rows):
    labels = list(zip(*rows))
    codes = []
    for col in labels[:4]:
        levels = {v: i for i, v in enumerate(dict.fromkeys(col))}
        codes.append(np.array([levels[v] for v in col]))
    values = np.array(labels[4])
    dims = [int(c.max()) + 1 for c in codes[1:]]
    n = int(codes[0].max()) + 1
    cell = (codes[1] * dims[1] + codes[2]) * dims[2] + codes[3]
    total = np.zeros((n, int(np.prod(dims))))
    count = np.zeros_like(total)
    np.add.at(total, (codes[0], cell), values)
    np.add.at(count, (codes[0], cell), 1)
    y = total / count
    out = []
    for size in range(1, 4):
        for term in itertools.combinations(range(3), size):
            m = np.ones((1, 1))
            for f, L in enumerate(dims):
                m = np.kron(m, helmert(L) if f in term else np.ones((L, 1)) / np.sqrt(L))
            z = y @ m
            d = z.shape[1]
            zc = z - z.mean(axis=0)
            e = zc.T @ zc
            ss = n * float(z.mean(axis=0) @ z.mean(axis=0))
            sse = float(np.trace(e))
            df1, df2 = d, d * (n - 1)
            f = (ss / df1) / (sse / df2)
            p = stats.f.sf(f, df1, df2)
            gg = np.trace(e) ** 2 / (d * np.trace(e @ e))
            hf = min(1.0, (n * d * gg - 2) / (d * (n - 1 - d * gg)))
            p_gg = stats.f.sf(f, df1 * gg, df2 * gg)
            p_hf = stats.f.sf(f, df1 * hf, df2 * hf)
            w = np.linalg.det(e) / (np.trace(e) / d) ** d if d > 1 else 1.0
            out.append((term, f, p, gg, p_gg, hf, p_hf, w))
    return out


def main():
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    rows = design(np.random.default_rng(20120330))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        analyse(rows)
        times.append((time.perf_counter() - start) * 1e3)
    times.sort()
    print(f"bench_anova.py: 3-way within 20 x 4 x 4 x 3 (960 rows), {repeats} runs: "
          f"median {times[len(times) // 2]:.3f} ms, min {times[0]:.3f} ms, max {times[-1]:.3f} ms")


if __name__ == "__main__":
    main()
