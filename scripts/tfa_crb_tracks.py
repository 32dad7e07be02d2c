#!/usr/bin/env python3
"""Cramer-Rao bounds of time-varying decay and frequency tracks: issue 7's closed-form case.

The case (tests/estimators/test_damped_modes.cpp, close_modes(0.26)): two damped oscillations,
2.4 and 3.4 Hz, in two channels sampled at 4 kHz, free from t = 2.52 s, the 3.4 Hz one with 5 % of
the energy; both decay rates double during the record,

    sigmoid: alpha_j(tau) = alpha_j0 (1 + 1 / (1 + exp(-4 (tau - 1))))   (tau = t - 2.52 s)
    linear:  alpha_j(tau) = alpha_j0 (1 + tau / 2),

alpha_10 = -1.0, alpha_20 = -1.3 1/s; white Gaussian noise at SNR dB against the RMS of the
response after 2.5 s over both channels (as the test's add_noise).

An estimator must assume some family for the tracks. For each family the bound is computed for
the most favourable model: alpha_j(t) and omega_j(t) in the family's basis, constant complex
amplitudes per mode and channel (4 real numbers per mode and channel pair), the true tracks (or
their least-squares projection onto the basis, whose representation error is printed as
`bias`), fitted over 2.525-5 s. Fisher information F = J^T J / sigma^2 at the full 4 kHz rate
(the estimators' low-pass removes only out-of-band noise). The bound on alpha_j(t) is
b(t)^T F^-1 b(t), b(t) the basis at t; printed as the RMS over 2.6-4.5 s of SD / |alpha_j(t)|
(and of SD(f_j) / f_j), in percent, the issue's measure.

An unbiased estimator of tracks in the family cannot do better. A prior (the modal method's
roughness prior, a decay tie) can trade variance for bias; only a prior that holds (a tie on a
ratio that is constant) brings information the data lack.

Families: poly:D (polynomial of degree D over the record), spline:S (cubic B-splines, knots S s
apart, as the modal method's tracks without their roughness prior).

With --stiffid BIN, also runs `BIN tfa` (default options, or those after --) on --seeds noisy
draws (numpy's default_rng(seed); the test uses std::mt19937_64) and prints the errors of its
tracks in the same measure. Run:

    /usr/bin/python3 scripts/tfa_crb_tracks.py [--profile sigmoid|linear] [--snr 20]
        [--families poly:0,poly:1,poly:3,spline:1,spline:0.5,spline:0.1]
        [--stiffid build/stiffid --seeds 12 [-- --decay-tie -1]]

numpy and scipy (B-splines) only.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.interpolate import BSpline

RATE_HZ = 4000.0
ONSET_S = 2.5
FREE_S = 2.52        # end of the 20 ms pulse
FIT_FROM_S = 2.525   # onset + the modal method's skip_s
FIT_TO_S = 5.0
SCORE = (2.6, 4.5)   # the issue's interval
WEAK = 0.26          # close_modes(0.26): the weak mode's amplitude, 5 % of the energy
# (frequency Hz, alpha_0 1/s, complex amplitude per channel at tau = 0)
MODES = [(2.4, -1.0, np.array([1.0, 0.45 + 0.05j])),
         (3.4, -1.3, np.array([(-0.4 + 0.1j) * WEAK, WEAK]))]


def profile_functions(name):
    """(shape(tau), its integral from 0): alpha_j(tau) = alpha_j0 shape(tau)."""
    if name == "sigmoid":
        def sig(tau):
            return 1.0 / (1.0 + np.exp(-4.0 * (tau - 1.0)))

        def sig_int(tau):
            return (np.log1p(np.exp(4.0 * (tau - 1.0))) - np.log1p(np.exp(-4.0))) / 4.0
        return (lambda tau: 1.0 + sig(tau)), (lambda tau: tau + sig_int(tau))
    if name == "linear":
        return (lambda tau: 1.0 + 0.5 * tau), (lambda tau: tau + 0.25 * tau * tau)
    raise SystemExit(f"--profile: expected sigmoid or linear, got '{name}'")


def response(t, shape_int):
    """Noise-free channels (len(t) x 2), rad; zero before the free response."""
    tau = t - FREE_S
    x = np.zeros((len(t), 2))
    free = tau >= 0.0
    for f, alpha0, a in MODES:
        e = np.exp(alpha0 * shape_int(tau[free]) + 2j * np.pi * f * tau[free])
        for c in range(2):
            x[free, c] += np.real(a[c] * e)
    return x


def noise_sd(x, t, snr_db):
    after = t >= ONSET_S
    return np.sqrt(np.mean(x[after] ** 2)) * 10.0 ** (-snr_db / 20.0)


def family_basis(family, tt):
    """Basis matrix (len(tt) x n) of one track family on the fitted times tt."""
    kind, _, value = family.partition(":")
    try:
        number = float(value)
    except ValueError:
        raise SystemExit(f"--families: '{family}': expected poly:DEGREE or spline:SPACING_S")
    if kind == "poly":
        u = (tt - tt[0]) / (tt[-1] - tt[0])
        return np.column_stack([u ** k for k in range(int(number) + 1)])
    if kind == "spline":
        if number <= 0.0:
            raise SystemExit(f"--families: '{family}': the knot spacing must be > 0 s")
        spans = max(1, int(round((tt[-1] - tt[0]) / number)))
        inner = np.linspace(tt[0], tt[-1], spans + 1)
        knots = np.r_[[tt[0]] * 3, inner, [tt[-1]] * 3]
        count = len(knots) - 4
        return np.column_stack([BSpline(knots, np.eye(count)[i], 3)(tt) for i in range(count)])
    raise SystemExit(f"--families: '{family}': expected poly:DEGREE or spline:SPACING_S")


def mode_jacobian(amplitude, e, I):
    """d Re(amplitude_c exp(Phi(t))) per channel c [time, channel, parameter] of one mode whose
    phase integral Phi has d Phi / d coefficient = I (alpha) or i I (omega): the alpha
    coefficients, the omega coefficients, then the amplitude (re, im per channel)."""
    channels = len(amplitude)
    blocks = [np.stack([(amplitude[c] * unit * e[:, None] * I).real for c in range(channels)],
                       axis=1) for unit in (1.0, 1j)]
    for c in range(channels):
        for unit in (1.0, 1j):
            block = np.zeros((I.shape[0], channels, 1))
            block[:, c, 0] = (unit * e).real
            blocks.append(block)
    return np.concatenate(blocks, axis=2)


def inverse_information(J):
    """F^-1 = (J^T J)^-1 for the (whitened) Jacobian rows J, through the QR of J (F is
    ill-conditioned for fine knots)."""
    R = np.linalg.qr(J, mode="r")
    R_inv = np.linalg.solve(R, np.eye(R.shape[0]))
    return R_inv @ R_inv.T


def bounds(family, shape, shape_int, sd):
    """Per mode: (RMS rel. SD of alpha %, RMS rel. SD of f %, RMS rel. representation error of
    alpha %) over the scored interval."""
    t = np.arange(int(round(FIT_FROM_S * RATE_HZ)), int(round(FIT_TO_S * RATE_HZ)) + 1) / RATE_HZ
    tau = t - FREE_S
    dt = 1.0 / RATE_HZ
    B = family_basis(family, t)
    n = B.shape[1]
    I = np.cumsum(B, axis=0) * dt  # d Phi / d coefficient
    I -= I[0]
    blocks = []
    for f, alpha0, a in MODES:
        phase0 = alpha0 * shape_int(tau[0]) + 2j * np.pi * f * tau[0]
        amplitude = a * np.exp(phase0)  # at the first fitted sample
        e = np.exp(alpha0 * (shape_int(tau) - shape_int(tau[0])) + 2j * np.pi * f * (tau - tau[0]))
        blocks.append(mode_jacobian(amplitude, e, I))
    J = np.concatenate(blocks, axis=2)
    cov = inverse_information(J.reshape(-1, J.shape[2]) / sd)
    scored = (t >= SCORE[0]) & (t <= SCORE[1])
    out = []
    offset = 0
    for f, alpha0, _ in MODES:
        alpha = alpha0 * shape(tau)
        var_alpha = np.einsum("ij,jk,ik->i", B, cov[offset:offset + n, offset:offset + n], B)
        var_omega = np.einsum("ij,jk,ik->i", B,
                              cov[offset + n:offset + 2 * n, offset + n:offset + 2 * n], B)
        coef, *_ = np.linalg.lstsq(B, alpha, rcond=None)
        out.append((100.0 * np.sqrt(np.mean(var_alpha[scored] / alpha[scored] ** 2)),
                    100.0 * np.sqrt(np.mean(var_omega[scored])) / (2.0 * np.pi * f),
                    100.0 * np.sqrt(np.mean(((B @ coef - alpha) / alpha)[scored] ** 2))))
        offset += 2 * n + 4
    return out


def stiffid_errors(binary, seeds, extra, shape, shape_int, snr_db):
    t = np.arange(int(5.0 * RATE_HZ)) / RATE_HZ
    x = response(t, shape_int)
    sd = noise_sd(x, t, snr_db)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        trial = os.path.join(folder, "trial.csv")
        result = os.path.join(folder, "tfa.json")
        for seed in seeds:
            y = x + np.random.default_rng(seed).normal(0.0, sd, x.shape)
            np.savetxt(trial, np.column_stack([t, y]), delimiter=",", header="t,th1,th2",
                       comments="", fmt="%.10g")
            run = subprocess.run([binary, "tfa", trial, "--angles", "th1,th2", "--onset",
                                  str(ONSET_S), "-o", result] + extra,
                                 capture_output=True, text=True)
            if run.returncode != 0:
                raise SystemExit(f"{binary} tfa failed on seed {seed}: {run.stderr.strip()}")
            with open(result) as f:
                j = json.load(f)
            ts = np.array(j["t_s"])
            scored = (ts >= SCORE[0]) & (ts <= SCORE[1])
            tau = ts[scored] - FREE_S
            row = []
            for m, (f, alpha0, _) in enumerate(MODES):
                f_fit = np.array(j["f_hz"][m])[scored]
                alpha_fit = np.array(j["alpha_per_s"][m])[scored]
                row += [100.0 * np.sqrt(np.mean((f_fit / f - 1.0) ** 2)),
                        100.0 * np.sqrt(np.mean((alpha_fit / (alpha0 * shape(tau)) - 1.0) ** 2))]
            rows.append(row)
            print(f"  seed {seed}: f {row[0]:.2f} / {row[2]:.2f} %, "
                  f"alpha {row[1]:.2f} / {row[3]:.2f} %", flush=True)
    rows = np.array(rows)
    rms = np.sqrt(np.mean(rows ** 2, axis=0))
    print(f"  RMS over {len(seeds)} seeds: f {rms[0]:.2f} / {rms[2]:.2f} %, "
          f"alpha {rms[1]:.2f} / {rms[3]:.2f} % (strong / weak mode)")


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--profile", default="sigmoid", help="sigmoid or linear decay change")
    p.add_argument("--snr", type=float, default=20.0, help="SNR, dB")
    p.add_argument("--families", default="poly:0,poly:1,poly:2,poly:3,spline:1,spline:0.5,"
                   "spline:0.3,spline:0.1")
    p.add_argument("--stiffid", help="stiffid binary: also score its tracks on noisy draws")
    p.add_argument("--seeds", type=int, default=12, help="with --stiffid: draws 1..N")
    args = p.parse_args(argv)
    shape, shape_int = profile_functions(args.profile)
    t = np.arange(int(5.0 * RATE_HZ)) / RATE_HZ
    x = response(t, shape_int)
    sd = noise_sd(x, t, args.snr)
    print(f"profile {args.profile}, {args.snr:g} dB (noise SD {sd:.4g} rad at {RATE_HZ:g} Hz); "
          f"RMS over {SCORE[0]}-{SCORE[1]} s, %, strong (2.4 Hz) / weak (3.4 Hz) mode")
    print(f"{'family':>12} | {'SD alpha':>15} | {'SD f':>13} | {'bias alpha':>13}")
    for family in args.families.split(","):
        (a1, f1, b1), (a2, f2, b2) = bounds(family, shape, shape_int, sd)
        print(f"{family:>12} | {a1:6.3g} / {a2:6.3g} | {f1:5.3g} / {f2:5.3g} | "
              f"{b1:5.3g} / {b2:5.3g}")
    if args.stiffid:
        print(f"{args.stiffid} tfa {' '.join(extra) or '(default options)'}:")
        stiffid_errors(args.stiffid, range(1, args.seeds + 1), extra, shape, shape_int, args.snr)


if __name__ == "__main__":
    main()
