#!/usr/bin/env python3
"""numpy/scipy peer of `stiffid tfa` with its default method, `modal` (docs/tfa_modal.md): the
same stages with the same default options, for the issue-7 benchmark (bench/bench_modal.sh).

Stages, as estimators/tfa.cpp (identify_tfa, modal branch) and the files it calls:
  - joint deviations from the posture, the mean over 0.2 s before the onset, 1.1 s kept before
    the onset for the noise (tfa_deviation.cpp);
  - zero-phase Kaiser windowed-sinc FIR decimation to 200 Hz (half-length 5 D, beta 9, cut-off
    0.8 of the output Nyquist frequency, renormalised at the record ends; decimate.cpp);
  - noise covariance of the filtered samples 1 s before the onset, topped up to the 40 dB floor,
    Cholesky whitening (damped_modes.cpp, prepare);
  - multichannel matrix pencil on the fitted record, sliding 0.5 s pencils and the ridge spline
    through the kept estimates as the start (matrix_pencil.cpp, start_tracks);
  - uniform cubic B-spline tracks omega_j, alpha_j (knots 0.1 s) with closed-form running
    integrals (cubic_bspline.cpp); with --decay-tracks gamma the decay splines are -Gamma_j, and
    with best (the default, as stiffid's) both fits are made in turn and the lower BIC (whitened
    residual and effective parameters) kept;
  - a constant offset per channel among the linear parameters (the posture's estimation error),
    and the strongest mode's square (exp(2 Re Phi_J), exp(2 Phi_J)) offered after the smoothest
    fit and kept by the BIC rule (the arm's quadratic distortion);
  - variable projection with Kaufman's Jacobian, minimized by Levenberg-Marquardt, along the
    roughness continuation 0.003 .. 3 with the BIC rule, from its third candidate on each
    candidate also fitted from the start tracks and the lower cost kept; a candidate with fewer
    modes than it claims (tracks merged, modes cancelling, second-order terms outweighing their
    mode) is skipped, the next roughness starting from its tracks;
  - after the tie, the local roughness (continuation rougher than the smoothest): a Student-t (nu 1)
    on each knot's second differences of all tracks, fitted by EM, its scale along the grid
    below the continuation's roughness, taken by the BIC rule with one parameter per bent knot;
  - the decay tie (more than one mode; opt-in, --decay-tie as stiffid's, default 0 = none): a
    Gaussian prior on (c_alpha_j - rho_j c_alpha_0) /
    (sd scale_j) for every decay-spline coefficient of the modes j > 0, scale_j = mode j's mean
    |c_alpha_j| at the untied fit (at least 1e-3), the ratios rho_j extra parameters (flat
    prior) after the tracks'; its sd along 0.3 .. 0.003, each fit from the previous one, tighter
    while the RSS rise stays within ln(N) x saved effective dof x s^2; with a tie the roughness
    continuation then resumes from the chosen roughness by the same rule as before;
  - stage 2 with slowly varying mode shapes (kept when its BIC beats the constant shapes';
    knots 0.5 s, orthogonal to the stage-1 shapes,
    first-difference penalty whose weight GCV chooses over 1e-3 .. 1e6; the tie rows kept);
  - the shape refit (no tie; stage 1 rougher than the smoothest): stage 2's design from the
    smoothest fit, the roughness continuation in it below stage 1's choice, the weight
    re-chosen by GCV, kept when its BIC with unknown variance, N ln RSS + ln(N) dof (the shapes'
    effective dof from the trace of their penalized smoother), is lower and its frequency tracks
    do not cross;
    posterior SDs from s^2 (J^T J)^+; ANR; validity flags, including the mode-to-data power and
    separation checks (damped_modes.cpp); after the last sample at which a mode's ANR is at or
    above the threshold its tracks go on as a damped trend (lost_track_time_s);
  - eqs 45-46 and the eq-48 mapping to K(t), C(t), P(t) (eq 43 weighted by the modes' ANR
    power), a lost mode's column of P completed from the valid ones (modal_parameters.cpp), the
    per-time modal quantities and eq 49's normalized force (tfa.cpp, normalized_force.cpp);
  - JSON with the keys of `stiffid tfa` (apps/cmd_tfa.cpp), decay_ratio (rho_j per output mode,
    1 for the reference mode and without a tie) and options.decay_tie (the sd used, 0: none)
    included; "iterations" counts MINPACK's residual evaluations of all stages where the C++
    code counts Ceres's iterations (the same notion, trial steps, not the same numbers).

Deliberate differences from the C++ code:
  - the Levenberg-Marquardt is MINPACK's (scipy.optimize.least_squares, method "lm", Jacobian
    column scaling as Ceres's Jacobi scaling, ftol = xtol = 1e-10, gtol = 1e-12, at most
    max_iterations + 1 evaluations, as Ceres counts one iteration per trial step), not Ceres's
    (which solves the normal equations, DENSE_NORMAL_CHOLESKY, where MINPACK takes a QR of the
    Jacobian): the two take different steps and stop by slightly different rules, so the
    optimum agrees to the tolerance, not to round-off. A trial point the model cannot evaluate
    (overflow) gets huge residuals, so that MINPACK rejects it as Ceres does;
  - the matrix pencil takes V from the SVD of the Hankel matrix's triangular QR factor, the C++
    code from the eigenvectors of the Hankel Gram matrix H^T H (the same signal subspace);
  - the effective dof is tr(N^-1 Jd^T Jd) by a symmetric solve where the C++ code takes
    P - tr(N^-1 Jp^T Jp) by an LDLT (equal up to round-off); pseudo-inverses are SVD-based
    (numpy lstsq / pinv) where Eigen uses a complete orthogonal decomposition: the same values
    for full-rank matrices;
  - K(t) positive definite is tested by its eigenvalues instead of a Cholesky factorization.

    python3 peer_modal.py TRIAL.csv --onset 2.5 [--angles th1,th2] [-o OUT.json]
    python3 peer_modal.py --make-trial TRIAL.csv   # the bench trial (peer_tfa.make_trial)
"""
import argparse
import json
import math

import numpy as np
import scipy.linalg
from numpy.lib.stride_tricks import sliding_window_view
from scipy.optimize import least_squares
from scipy.special import i0

from peer_tfa import ARM, inertia, make_trial

# Defaults of DampedModesOptions / DeviationOptions (estimators/damped_modes.hpp, tfa_deviation.hpp).
OPTIONS = dict(decimate_hz=200.0, skip_s=0.025, noise_window_s=1.0, knot_spacing_s=0.1,
               shape_knot_spacing_s=0.5, shape_weight=-1.0, track_roughness=-1.0,
               local_roughness_dof=1.0, decay_tie=0.0, init_window_s=0.5, anr_threshold_db=0.0,
               max_frequency_sd_hz=0.1, max_mode_to_data_db=20.0, min_mode_separation=0.01,
               max_iterations=100, lost_track_time_s=0.3, mapping="eq48", decay_tracks="best",
               damping_tracks=False)  # damping_tracks: one fit's decay splines are -Gamma_j
PRE_ONSET_S, PULSE_S = 0.2, 0.02
ROUGHNESS_GRID = (0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0)
TIE_GRID = (0.3, 0.1, 0.03, 0.01, 0.003)
# A fit whose modes' energies sum to over this many times the energy of their sum has
# cancelling modes (kMaxCancellation, estimators/damped_modes.cpp).
MAX_CANCELLATION = 4.0


def lround(x):
    """C's lround: halves away from zero."""
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


def ceil_div(i, d):
    return -((-i) // d)


# ---- decimate.cpp -------------------------------------------------------------------------------
def decimate(x, d, half_per_factor=5, cutoff=0.8, beta=9.0):
    """Zero-phase Kaiser FIR low-pass, every d-th sample; gain renormalised where the record cuts
    the filter. x (S x C) -> (ceil(S / d) x C)."""
    if d == 1:
        return x.copy()
    half = half_per_factor * d
    n = np.arange(-half, half + 1)
    taps = np.sinc(2.0 * cutoff * 0.5 / d * n) * i0(beta * np.sqrt(1.0 - (n / half) ** 2)) / i0(beta)
    taps /= taps.sum()
    s = x.shape[0]
    padded = np.pad(x, ((half, half), (0, 0)))
    windows = sliding_window_view(padded, 2 * half + 1, axis=0)[::d]  # (out, C, 2 half + 1)
    gain = sliding_window_view(np.pad(np.ones(s), half), 2 * half + 1)[::d] @ taps
    return (windows @ taps) / gain[:, None]


# ---- cubic_bspline.cpp --------------------------------------------------------------------------
class Bspline:
    """Uniform cubic B-spline basis on [0, length_s], spans + 3 functions."""
    AREA = np.array([1.0, 11.0, 11.0, 1.0]) / 24.0

    def __init__(self, length_s, target_s):
        self.spans = max(1, lround(length_s / target_s))
        self.h = length_s / self.spans
        self.size = self.spans + 3

    def _locate(self, t):
        x = t / self.h
        span = np.clip(np.floor(x).astype(int), 0, self.spans - 1)
        return span, x - span

    def _scatter(self, span, pieces):
        b = np.zeros((span.size, self.size))
        rows = np.arange(span.size)
        for r in range(4):
            b[rows, span + r] = pieces[r]
        return b

    def values(self, t):
        s, u = self._locate(t)
        return self._scatter(s, [(1 - u) ** 3 / 6, (3 * u ** 3 - 6 * u ** 2 + 4) / 6,
                                 (-3 * u ** 3 + 3 * u ** 2 + 3 * u + 1) / 6, u ** 3 / 6])

    def first_derivatives(self, t):
        s, u = self._locate(t)
        return self._scatter(s, [-(1 - u) ** 2 / 2, (3 * u ** 2 - 4 * u) / 2,
                                 (-3 * u ** 2 + 2 * u + 1) / 2, u ** 2 / 2]) / self.h

    def second_derivatives(self, t):
        s, u = self._locate(t)
        return self._scatter(s, [1 - u, 3 * u - 2, -3 * u + 1, u]) / self.h ** 2

    def integrals(self, t):
        s, u = self._locate(t)
        whole = np.zeros((self.spans + 1, self.size))  # areas of the pieces in spans before s
        for span in range(self.spans):
            whole[span + 1] = whole[span]
            whole[span + 1, span:span + 4] += self.AREA
        u2, u3, u4 = u * u, u ** 3, u ** 4
        part = self._scatter(s, [(1 - (1 - u) ** 4) / 24, (0.75 * u4 - 2 * u3 + 4 * u) / 6,
                                 (-0.75 * u4 + u3 + 1.5 * u2 + u) / 6, u4 / 24])
        return (whole[s] + part) * self.h

    def second_differences(self):
        d = np.zeros((self.size - 2, self.size))
        for m in range(self.size - 2):
            d[m, m:m + 3] = (1.0, -2.0, 1.0)
        return d

    def first_differences(self):
        d = np.zeros((self.size - 1, self.size))
        for m in range(self.size - 1):
            d[m, m:m + 2] = (-1.0, 1.0)
        return d


# ---- matrix_pencil.cpp --------------------------------------------------------------------------
def matrix_pencil(y, rate_hz, modes, fraction=1.0 / 3.0, max_pencil=160):
    """Multichannel matrix pencil (Hua & Sarkar 1990). Returns (alpha, omega, amplitude (n x C))
    or None when it finds fewer than n oscillatory poles."""
    s, c = y.shape
    order = 2 * modes
    pencil = min(max(int(fraction * s), order + 1), max(order + 1, max_pencil))
    rows = s - pencil
    hankel = sliding_window_view(y, pencil + 1, axis=0)[:rows]  # (rows, C, L + 1)
    hankel = hankel.transpose(1, 0, 2).reshape(c * rows, pencil + 1)
    # V of the Hankel matrix from the SVD of its triangular factor: the same V without forming U
    # (Eigen's BDCSVD computes V alone).
    r = scipy.linalg.qr(hankel, mode="r", check_finite=False)[0][:pencil + 1]
    _, sv, vt = scipy.linalg.svd(r, check_finite=False)
    if not sv[0] > 0:
        return None
    v = vt[:order].T
    z_matrix = np.linalg.lstsq(v[:pencil], v[1:], rcond=None)[0]
    z = np.linalg.eigvals(z_matrix)
    z = z[np.abs(z) != 0]
    lam = np.log(z.astype(complex)) * rate_hz
    lam = lam[lam.imag > 1e-9 * rate_hz]
    if lam.size < modes:
        return None
    lam = lam[np.argsort(lam.imag, kind="stable")][:modes]
    e = np.exp(np.outer(np.arange(s) / rate_hz, lam))
    basis = np.empty((s, 2 * modes))
    basis[:, 0::2], basis[:, 1::2] = e.real, -e.imag
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return lam.real, lam.imag, coef[0::2] + 1j * coef[1::2]


# ---- damped_modes.cpp ---------------------------------------------------------------------------
def prepare(x, rate_hz, start_s, onset_s, o):
    d = max(1, lround(rate_hz / o["decimate_hz"])) if o["decimate_hz"] > 0 else 1
    h = 5 * d if d > 1 else 0
    s, c = x.shape
    onset = math.ceil((onset_s - start_s) * rate_hz - 1e-9)
    noise_first = ceil_div(max(h, onset - lround(o["noise_window_s"] * rate_hz) + h), d)
    noise_last = (onset - 1 - h) // d if onset - 1 - h >= 0 else -1
    if noise_last - noise_first + 1 < 8 * c or onset < lround(o["noise_window_s"] * rate_hz):
        raise SystemExit("modal fit: the record needs noise_window_s of samples before the onset")
    first = ceil_div(onset + math.ceil(o["skip_s"] * rate_hz) + h, d)
    last = (s - 1 - h) // d
    n = max(0, last - first + 1)
    rate = rate_hz / d
    if n < 2 or (n - 1) / rate < 0.5:
        raise SystemExit("modal fit: less than 0.5 s of free response after onset + skip_s")
    dec = decimate(x, d)
    p = dict(rate_hz=rate, d=d)
    p["y"] = dec[first:last + 1]
    p["t_s"] = start_s + np.arange(first, last + 1) * (d / rate_hz)
    p["tau_s"] = p["t_s"] - p["t_s"][0]
    noise = dec[noise_first:noise_last + 1]
    noise = noise - noise.mean(axis=0)
    p["noise_cov"] = noise.T @ noise / (noise.shape[0] - 1)
    power = np.sum(p["y"] ** 2) / p["y"].size
    floor = max(1e-6 * power, 1e-4 * power - np.trace(p["noise_cov"]) / c) + 1e-300
    p["L"] = np.linalg.cholesky(p["noise_cov"] + floor * np.eye(c))
    p["W"] = scipy.linalg.solve_triangular(p["L"], np.eye(c), lower=True)
    p["yw"] = (p["y"] @ p["W"].T).ravel()  # row i * C + k
    return p


class DecayTie:
    """Soft tie of the decay tracks: c_alpha_j follows rho_j c_alpha_0 (j > 0) with prior SD
    sd * scale[j] per coefficient; sd 0: no tie."""

    def __init__(self, sd=0.0, scale=None):
        self.sd, self.scale = sd, scale


class VpProblem:
    """Variable projection for fixed linear terms (mode, whitened direction [C], time function),
    penalized pairs of linear terms (weight), roughness prior rows (R x 2 n M) and the decay tie.
    theta: the track coefficients [alpha_0, omega_0, alpha_1, ...] (M each), then rho_1 ..
    rho_{n-1} when tied."""

    def __init__(self, p, modes, ig, wv, functions, terms, pairs, weight, prior, tie=DecayTie(),
                 so_mode=-1):
        """wv: the track basis at the samples (damping tracks: the decay coefficients are -Gamma_j
        and Re Phi_j = int(-Gamma_j) - ln(omega_j) / 2), or None (they are alpha_j)."""
        self.p, self.modes, self.ig, self.prior, self.tie = p, modes, ig, prior, tie
        self.wv = wv
        self.wvr = None if wv is None else np.repeat(wv, p["y"].shape[1], axis=0)  # (N C x M)
        self.so_mode = so_mode  # mode whose square (exp(2 Re Phi), exp(2 Phi)) is fitted, or -1
        self.n, self.c = p["y"].shape
        self.m = ig.shape[1]
        self.igr = np.repeat(ig, self.c, axis=0)  # (N C x M)
        self.t_modes = np.array([t[0] for t in terms])
        self.t_dirs = np.array([t[1] for t in terms]).T  # (C x T)
        self.t_funcs = functions[:, [t[2] for t in terms]]  # (N x T)
        self.terms, self.functions = terms, functions
        self.mode_onehot = (self.t_modes[:, None] == np.arange(modes)[None, :]).astype(float)
        self.rd = self.n * self.c
        self.nt = 2 * len(terms)
        self.nl = self.nt + self.c  # then a constant whitened offset per channel (the posture's)
        self.first_so = self.nl
        if so_mode >= 0:  # per channel: exp(2 Re Phi_J), then Re, Im of exp(2 Phi_J)
            self.nl += 3 * self.c
        self.tp = 2 * modes * self.m  # track parameters
        self.tied = modes - 1 if tie.sd > 0 else 0
        self.np = self.tp + self.tied
        pen = np.zeros((2 * len(pairs), self.nl))
        for q, (a, b) in enumerate(pairs):
            for part in range(2):
                pen[2 * q + part, 2 * a + part] = -1.0
                pen[2 * q + part, 2 * b + part] = 1.0
        self.penalty = pen
        self.sqrt_weight = math.sqrt(weight)
        self.rp = pen.shape[0]
        self.b = np.concatenate([p["yw"], np.zeros(self.rp)])
        self.rr = prior.shape[0]
        self.residuals = self.rd + self.rp + self.rr + self.tied * self.m
        self._key = None

    def part_energies(self, theta):
        """Whitened energies over the record at theta: of each mode's part of the model, of their
        sum and of the second-order terms' part (0 without them); None when theta overflows."""
        if not self.evaluate(theta):
            return None
        a, _ = self.design(self.e)
        terms = a[:, :self.nt] * self.beta[:self.nt]
        parts = (terms[:, 0::2] + terms[:, 1::2]) @ self.mode_onehot  # (N C x modes)
        distortion = 0.0
        if self.so_mode >= 0:
            cols = slice(self.first_so, self.first_so + 3 * self.c)
            distortion = float(np.sum((a[:, cols] @ self.beta[cols]) ** 2))
        return np.sum(parts ** 2, axis=0), float(np.sum(parts.sum(axis=1) ** 2)), distortion

    def function_columns(self, mode):
        """Time-function columns of mode's terms."""
        return [t[2] for t in self.terms if t[0] == mode]

    def oscillations(self, theta):
        th = theta[:self.tp].reshape(self.modes, 2, self.m)
        re = self.ig @ th[:, 0, :].T
        im = self.ig @ th[:, 1, :].T
        if self.wv is not None:
            omega = self.wv @ th[:, 1, :].T
            if not (omega > 0).all():
                return None
            re = re - 0.5 * np.log(omega)
            self.half_inverse_omega = -0.5 / omega  # (N x modes) d Re Phi / d omega
        if not (np.isfinite(re).all() and np.isfinite(im).all()) or np.abs(re).max() > 600.0:
            return None
        return np.exp(re + 1j * im)  # (N x modes)

    def design(self, e):
        v = self.t_funcs * e[:, self.t_modes]  # (N x T)
        w = (v[:, None, :] * self.t_dirs[None, :, :]).reshape(self.rd, -1)
        a = np.empty((self.rd, self.nl))
        a[:, 0:self.nt:2], a[:, 1:self.nt:2] = w.real, -w.imag
        a[:, self.nt:self.nt + self.c] = np.tile(np.eye(self.c), (self.n, 1))
        if self.so_mode >= 0:
            ej = e[:, self.so_mode]
            dc, e2 = np.abs(ej) ** 2, ej * ej
            for k in range(self.c):
                col = self.first_so + 3 * k
                a[k::self.c, col] = dc
                a[k::self.c, col + 1] = e2.real
                a[k::self.c, col + 2] = -e2.imag
                others = [kk for kk in range(self.c) if kk != k]
                for kk in others:
                    a[kk::self.c, col:col + 3] = 0.0
        return a, self.penalty

    def evaluate(self, theta):
        """Caches (residual, beta, Q, rank, e) at theta; False when the model overflows."""
        key = theta.tobytes()
        if key == self._key:
            return self._ok
        self._key = key
        e = self.oscillations(theta)
        self._ok = e is not None
        if not self._ok:
            return False
        a_data, a_pen = self.design(e)
        a = np.vstack([a_data, self.sqrt_weight * a_pen])
        q, r, piv = scipy.linalg.qr(a, mode="economic", pivoting=True, check_finite=False)
        diag = np.abs(np.diag(r))
        rank = int(np.sum(diag > np.finfo(float).eps * min(a.shape) * diag[0]))
        z = scipy.linalg.solve_triangular(r[:rank, :rank], q[:, :rank].T @ self.b)
        beta = np.zeros(self.nl)
        beta[piv[:rank]] = z
        if not np.isfinite(beta).all():
            self._ok = False
            return False
        self.e, self.beta, self.q = e, beta, q[:, :rank]
        if self.wv is not None:
            self.half_inverse_omega_at = self.half_inverse_omega
        self.resid = np.concatenate([self.b - a @ beta, self.prior @ theta[:self.tp],
                                     self.tie_residual(theta)])
        return True

    def tie_residual(self, theta):
        m, ca0 = self.m, theta[:self.m]
        rows = [(theta[2 * j * m:(2 * j + 1) * m] - theta[self.tp + j - 1] * ca0)
                / (self.tie.sd * self.tie.scale[j]) for j in range(1, self.tied + 1)]
        return np.concatenate(rows) if rows else np.zeros(0)

    def residual(self, theta):
        if not self.evaluate(theta):
            return np.full(self.residuals, 1e100)
        return self.resid

    def jacobian(self, theta):
        """Kaufman: [-(I - Q Q^T) D; prior; tie], D = d(A beta)/d theta at fixed beta (zero in
        the rho columns)."""
        if not self.evaluate(theta):
            return np.zeros((self.residuals, self.np))
        coef = self.beta[0:self.nt:2] + 1j * self.beta[1:self.nt:2]
        v = self.t_funcs * self.e[:, self.t_modes] * coef  # (N x T)
        y = (v[:, None, :] * self.t_dirs[None, :, :]) @ self.mode_onehot  # (N, C, modes)
        y = y.reshape(self.rd, self.modes)
        d = np.zeros((self.rd + self.rp, self.np))
        blocks = d[:self.rd, :self.tp].reshape(self.rd, self.modes, 2, self.m)
        blocks[:, :, 0, :] = self.igr[:, None, :] * y.real[:, :, None]
        blocks[:, :, 1, :] = -self.igr[:, None, :] * y.imag[:, :, None]
        if self.wv is not None:  # omega also moves the amplitude omega^-1/2
            hio = np.repeat(self.half_inverse_omega_at, self.c, axis=0)  # (N C x modes)
            blocks[:, :, 1, :] += self.wvr[:, None, :] * (hio * y.real)[:, :, None]
        if self.so_mode >= 0:  # the square moves with mode J's decay and frequency coefficients
            ej = self.e[:, self.so_mode]
            dc, e2 = np.abs(ej) ** 2, ej * ej
            b = self.beta[self.first_so:].reshape(self.c, 3)
            ydc = 2.0 * np.outer(dc, b[:, 0]).ravel()
            y2 = (2.0 * np.outer(e2, b[:, 1] + 1j * b[:, 2])).ravel()
            blocks[:, self.so_mode, 0, :] += self.igr * (ydc + y2.real)[:, None]
            blocks[:, self.so_mode, 1, :] += -self.igr * y2.imag[:, None]
            if self.wv is not None:
                hio = np.repeat(self.half_inverse_omega_at[:, self.so_mode], self.c)
                blocks[:, self.so_mode, 1, :] += self.wvr * (hio * (ydc + y2.real))[:, None]
        d[:, :self.tp] -= self.q @ (self.q.T @ d[:, :self.tp])
        m = self.m
        tie = np.zeros((self.tied * m, self.np))
        for j in range(1, self.tied + 1):
            inv = 1.0 / (self.tie.sd * self.tie.scale[j])
            rows = slice((j - 1) * m, j * m)
            tie[rows, 2 * j * m:(2 * j + 1) * m] = inv * np.eye(m)
            tie[rows, :m] = -theta[self.tp + j - 1] * inv * np.eye(m)
            tie[rows, self.tp + j - 1] = -inv * theta[:m]
        prior = np.hstack([self.prior, np.zeros((self.rr, self.tied))])
        return np.vstack([-d, prior, tie])


def solve(problem, theta, max_iterations):
    """Levenberg-Marquardt (MINPACK) on the projected residual. (theta, usable, converged, nfev)."""
    if not problem.evaluate(theta):
        return theta, False, False, 0
    fit = least_squares(problem.residual, theta, jac=problem.jacobian, method="lm",
                        x_scale="jac", ftol=1e-10, xtol=1e-10, gtol=1e-12,
                        max_nfev=max_iterations + 1)
    usable = fit.status >= 0 and problem.evaluate(fit.x)
    return fit.x, usable, fit.status > 0, fit.nfev


def cost(problem, theta):
    """Half the sum of squared residuals (data, penalty, prior and tie rows) at theta."""
    r = problem.residual(theta)
    return 0.5 * float(r @ r)


def effective_parameters(data, prior):
    """tr(N^+ D), N = D + Q, as stiffid's estimators/effective_parameters.cpp: N scaled to unit
    diagonal (parameters nobody sees left out), eigenvalues below 1e-10 of the largest counted
    as zero. (stiffid takes an LDLT when its pivots allow; the eigen form gives the same trace
    there.)"""
    diagonal = np.diag(data) + np.diag(prior)
    kept = diagonal > 0
    if not kept.any():
        return 0.0
    scale = 1.0 / np.sqrt(diagonal[kept])
    d = data[np.ix_(kept, kept)] * scale[:, None] * scale[None, :]
    q = prior[np.ix_(kept, kept)] * scale[:, None] * scale[None, :]
    values, vectors = np.linalg.eigh(d + q)
    use = values > 1e-10 * values.max()
    v = vectors[:, use]
    return float(np.sum(np.clip(1.0 - np.einsum("ij,ij->j", v, q @ v) / values[use], 0.0, 1.0)))


def fit_size(problem, theta, with_dof):
    if not problem.evaluate(theta):
        return None
    rss = float(problem.resid[:problem.rd] @ problem.resid[:problem.rd])
    dof = 0.0
    if with_dof:
        j = problem.jacobian(theta)
        jd = j[:problem.rd]
        jp = j[problem.rd:]
        dof = effective_parameters(jd.T @ jd, jp.T @ jp) + linear_effective(problem, theta)
    return rss, dof


def lower_bic(a, theta_a, b, theta_b, b_knots=0):
    """Fit a has a lower BIC than fit b, the residual variance unknown: N ln RSS + ln(N) dof
    (b_knots: the bent knots of b's local roughness, added to its dof)."""
    size_a, size_b = fit_size(a, theta_a, True), fit_size(b, theta_b, True)
    if size_a is None or size_b is None:
        return False
    rows = a.rd
    (rss_a, dof_a), (rss_b, dof_b) = size_a, size_b
    dof_b += b_knots
    sane = lambda dof: np.isfinite(dof) and 0 <= dof < rows
    bic = lambda rss, dof: rows * math.log(rss) + math.log(rows) * dof
    return (sane(dof_a) and sane(dof_b) and rss_a > 0 and rss_b > 0
            and bic(rss_a, dof_a) < bic(rss_b, dof_b))


def linear_effective(problem, theta):
    """Effective number of linear parameters: their count, or with a shape penalty the trace
    of the penalized linear smoother, tr((A^T A + w R^T R)^+ A^T A)."""
    if problem.rp == 0:
        return problem.nl
    e = problem.oscillations(theta)
    if e is None:
        return problem.nl
    a, r = problem.design(e)
    return effective_parameters(a.T @ a, problem.sqrt_weight ** 2 * (r.T @ r))


def prior_rows(track, modes, roughness):
    """Second differences of every track over the roughness: one value, or one per knot."""
    sd = np.asarray(roughness, dtype=float).reshape(-1, 1)
    return np.kron(np.eye(2 * modes), track.second_differences() / sd)


def start_tracks(p, track, global_start, o, modes):
    y, rate = p["y"], p["rate_hz"]
    n = y.shape[0]
    window = min(n, max(4 * modes + 2, lround(o["init_window_s"] * rate)))
    hop = max(1, lround(track.h * rate))
    half_s = 0.5 * (window - 1) / rate
    last_omega = global_start[1].copy()
    kept = [[] for _ in range(modes)]
    for first in range(0, n - window + 1, hop):
        w = matrix_pencil(y[first:first + window], rate, modes)
        if w is None:
            continue
        alpha, omega, amp = w
        for j in range(modes):
            white = p["W"] @ amp[j]
            anr = 0.5 * np.vdot(white, white).real * math.exp(2.0 * alpha[j] * half_s)
            ratio = omega[j] / last_omega[j]
            if anr < 4.0 or ratio < 0.7 or ratio > 1.4 or abs(alpha[j]) > omega[j]:
                continue
            kept[j].append((p["tau_s"][first] + half_s, alpha[j], omega[j]))
            last_omega[j] = omega[j]
    m = track.size
    theta = np.empty(2 * modes * m)
    ridge = 1e-2 * track.first_differences()
    for j in range(modes):
        if not kept[j]:
            theta[2 * j * m:(2 * j + 1) * m] = global_start[0][j]
            theta[(2 * j + 1) * m:(2 * j + 2) * m] = global_start[1][j]
            continue
        centre, alpha, omega = (np.array(v) for v in zip(*kept[j]))
        a = np.vstack([track.values(centre), ridge])
        rhs = np.zeros((a.shape[0], 2))
        rhs[:centre.size, 0], rhs[:centre.size, 1] = alpha, omega
        coef = np.linalg.lstsq(a, rhs, rcond=None)[0]
        theta[2 * j * m:(2 * j + 1) * m], theta[(2 * j + 1) * m:(2 * j + 2) * m] = coef.T
    return theta


def choose_shape_weight(problem, theta, p):
    """GCV of the shape penalty at fixed tracks over 1e-3 .. 1e6 (half decades)."""
    e = problem.oscillations(theta)
    if e is None:
        return 1.0
    a, r = problem.design(e)
    ata, rtr, atb = a.T @ a, r.T @ r, a.T @ p["yw"]
    rows = a.shape[0]
    best, best_score = 1.0, np.inf
    for k in range(-6, 13):
        lam = 10.0 ** (0.5 * k)
        sol = np.linalg.lstsq(ata + lam * rtr, np.column_stack([atb, ata]), rcond=None)[0]
        beta, trace = sol[:, 0], np.trace(sol[:, 1:])
        resid = p["yw"] - a @ beta
        score = rows * (resid @ resid) / (rows - trace) ** 2
        if score < best_score:
            best_score, best = score, lam
    return best


def complete_basis(u):
    q = np.linalg.qr(u[:, None], mode="complete")[0]
    q[:, 0] = u / np.linalg.norm(u)
    return q


def fit_damped_modes(x, rate_hz, start_s, onset_s, o, modes, mass_at=None):
    """mass_at(t_s): the channels' mass metric (C x C, kg m^2); given, alpha_j and omega_j are the
    modal coordinate's, |a_j|_M exp(Re Phi_j) (docs/tfa_modal.md, "Modal amplitude")."""
    p = prepare(x, rate_hz, start_s, onset_s, o)
    n, c = p["y"].shape
    res = dict(t_s=p["t_s"], rate_hz=p["rate_hz"], noise_cov=p["noise_cov"], data=p["y"],
               shape_weight=0.0, track_roughness=0.0, decay_tie=0.0, iterations=0)
    start = matrix_pencil(p["y"], p["rate_hz"], modes)
    if start is None:
        raise SystemExit("modal fit: no start")
    track = Bspline(p["tau_s"][-1], o["knot_spacing_s"])
    m = track.size
    ig = track.integrals(p["tau_s"])
    # Damping tracks (--decay-tracks gamma): the decay splines are -Gamma_j (damped_modes.hpp).
    wv = track.values(p["tau_s"]) if o["damping_tracks"] else None
    theta = start_tracks(p, track, start, o, modes)
    cold = theta.copy()  # the start tracks, the continuation's second start from its third step

    terms = [(j, np.eye(c)[k].astype(complex), 0) for j in range(modes) for k in range(c)]
    constant = np.ones((n, 1))
    grid = ROUGHNESS_GRID if o["track_roughness"] < 0 else (o["track_roughness"],)
    # The strongest mode at the start (largest whitened amplitude of the linear solution at the
    # start tracks) is offered its square (the arm's quadratic distortion) after the smoothest fit.
    so_offer, so = -1, [-1]
    if o.get("second_order", True):
        probe0 = VpProblem(p, modes, ig, wv, constant, terms, [], 0.0, prior_rows(track, modes, grid[0]))
        if probe0.evaluate(theta):
            b0 = probe0.beta
            so_offer = int(np.argmax([np.linalg.norm(b0[2 * j * c:2 * (j + 1) * c])
                                      for j in range(modes)]))
    # The accepted fit: its problem, theta, convergence, RSS and effective dof.
    fit = dict(problem=None, theta=theta, converged=False, rss=np.inf, dof=0.0)
    # The linear design of the candidates: constant shapes (stage 1) or slowly varying ones.
    design = dict(functions=constant, terms=terms, pairs=[], weight=0.0)

    track_values = track.values(p["tau_s"])

    def frequency_tracks(at):
        """omega_j(tau) of every mode at theta `at` (samples x modes), rad/s."""
        return track_values @ at[:2 * modes * m].reshape(modes, 2, m)[:, 1, :].T

    def spurious(problem, at):
        """A fit with fewer modes than it claims (damped_modes.cpp, `spurious`): two frequency
        tracks within min_mode_separation everywhere, modes whose parts cancel (their energies
        over MAX_CANCELLATION times that of their sum), or second-order terms whose part
        outweighs the mode that carries them."""
        omega = frequency_tracks(at)
        if any(np.max(np.abs(omega[:, j] - omega[:, k])
                      / (0.5 * (np.abs(omega[:, j]) + np.abs(omega[:, k]))))
               < o["min_mode_separation"]
               for j in range(modes) for k in range(j + 1, modes)):
            return True
        energy = problem.part_energies(at)
        if energy is None:
            return True
        parts, total, distortion = energy
        if parts.sum() > MAX_CANCELLATION * total:
            return True
        return problem.so_mode >= 0 and distortion >= parts[problem.so_mode]

    def take_fit(problem, candidate, usable, conv, with_dof, spurious_fit, accept):
        """Takes a usable fit that is not spurious (fit) when, once one has been taken,
        accept(rss, dof, price) says so, price = ln(N) s^2 (s^2 the residual's own variance, never
        below 1)."""
        size = fit_size(problem, candidate, with_dof) if usable else None
        if size is None or spurious_fit:
            return False
        rss, dof = size
        rows = problem.rd
        variance = max(1.0, rss / max(1.0, rows - dof))
        if fit["problem"] is not None and not accept(rss, dof, math.log(rows) * variance):
            return False
        fit.update(problem=problem, theta=candidate, converged=conv, rss=rss, dof=dof)
        return True

    skipped = [None]  # the last candidate refused as spurious (its tracks), else None

    def try_candidate(roughness, tie, with_dof, start, accept, restart=False):
        """Fits one candidate from start (with restart, also from the start tracks, the lower
        cost kept); taken (fit) when accept(rss, dof, price) says so; False when it is not
        usable, spurious (a usable one goes to skipped[0]) or not taken."""
        problem = VpProblem(p, modes, ig, wv, design["functions"], design["terms"], design["pairs"],
                            design["weight"], prior_rows(track, modes, roughness), tie, so[0])
        candidate, usable, conv, nfev = solve(problem, start, o["max_iterations"])
        res["iterations"] += nfev
        check = fit["problem"] is not None  # spurious fits are refused once one has been taken

        def is_spurious(ok, at):
            return check and ok and spurious(problem, at)

        candidate_spurious = is_spurious(usable, candidate)
        other_start = start.size == cold.size and not np.array_equal(start, cold)
        if other_start and (restart or candidate_spurious):
            other, usable2, conv2, nfev2 = solve(problem, cold, o["max_iterations"])
            res["iterations"] += nfev2
            other_spurious = is_spurious(usable2, other)
            # The start tracks' fit replaces a fit that is not usable, or spurious while it is
            # not, or (equally spurious) of higher cost.
            if usable2 and (not usable
                            or (candidate_spurious if candidate_spurious != other_spurious
                                else cost(problem, other) < cost(problem, candidate))):
                candidate, usable, conv = other, usable2, conv2
                candidate_spurious = other_spurious
        skipped[0] = candidate if candidate_spurious else None
        return take_fit(problem, candidate, usable, conv, with_dof, candidate_spurious, accept)

    def rougher(rss, dof, price):  # BIC: the RSS drop pays for the added effective dof
        return fit["rss"] - rss > price * (dof - fit["dof"])

    def tighter(rss, dof, price):  # BIC: the RSS rise stays within the saved effective dof
        return o["decay_tie"] > 0 or rss - fit["rss"] <= price * (fit["dof"] - dof)

    length_s = p["tau_s"][-1]
    shapes = o["shape_knot_spacing_s"] > 0 and c > 1 and length_s > o["shape_knot_spacing_s"]
    shape = Bspline(length_s, o["shape_knot_spacing_s"]) if shapes else None

    def shape_design(fitted, at, roughness):
        """Stage 2's design from a constant-shape fit: the components orthogonal (whitened) to
        each mode's fitted shape vary as splines with a first-difference penalty, its weight
        given or chosen by GCV at the fit's tracks."""
        fitted.evaluate(at)
        beta = fitted.beta
        functions = np.hstack([constant, shape.values(p["tau_s"])])
        varying, pairs = [], []
        for j in range(modes):
            u = beta[2 * j * c:2 * (j + 1) * c:2] + 1j * beta[2 * j * c + 1:2 * (j + 1) * c:2]
            if not np.linalg.norm(u) > 0:
                u = np.eye(c)[0].astype(complex)
            basis = complete_basis(u)
            varying.append((j, basis[:, 0], 0))
            for dcol in range(1, c):
                for q in range(shape.size):
                    if q > 0:
                        pairs.append((len(varying) - 1, len(varying)))
                    varying.append((j, basis[:, dcol], 1 + q))
        d = dict(functions=functions, terms=varying, pairs=pairs, weight=o["shape_weight"])
        if d["weight"] < 0:
            probe = VpProblem(p, modes, ig, wv, functions, varying, pairs, 1.0,
                              prior_rows(track, modes, roughness), fitted.tie, fitted.so_mode)
            d["weight"] = choose_shape_weight(probe, at, p)
        return d

    # A spurious candidate is skipped: the next roughness starts from its tracks.
    tie, chosen, smoothest, start = DecayTie(), 0, None, fit["theta"]
    for g, roughness in enumerate(grid):
        if not try_candidate(roughness, tie, len(grid) > 1 or o["decay_tie"] < 0 or so_offer >= 0,
                             start, rougher, g >= 2):
            if skipped[0] is None:
                break
            start = skipped[0]
            continue
        chosen = g
        if g == 0 and so_offer >= 0:
            so[0] = so_offer
            if not try_candidate(grid[0], tie, True, fit["theta"], rougher):
                so[0] = -1
        if g == 0:
            smoothest = fit["theta"]
        start = fit["theta"]
    if fit["problem"] is None:
        raise SystemExit("modal fit: no usable fit even with the smoothest tracks")
    res["track_roughness"] = grid[chosen]
    if modes > 1 and o["decay_tie"] != 0:
        tie_grid = TIE_GRID if o["decay_tie"] < 0 else (o["decay_tie"],)
        untied = fit["theta"]
        ca = untied.reshape(modes, 2, m)[:, 0, :]
        scale = np.maximum(np.abs(ca).mean(axis=1), 1e-3)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = ca[1:].mean(axis=1) / ca[0].mean()
        if not np.isfinite(rho).all():
            rho = np.ones(modes - 1)
        tied = np.concatenate([untied, rho])
        for sd in tie_grid:
            candidate_tie = DecayTie(sd, scale)
            if not try_candidate(res["track_roughness"], candidate_tie, True,
                                 fit["theta"] if tie.sd > 0 else tied, tighter):
                break
            tie = candidate_tie
        res["decay_tie"] = tie.sd
        for g in range(chosen + 1, len(grid)) if tie.sd > 0 else ():
            if not try_candidate(grid[g], tie, True, fit["theta"], rougher):
                break
            res["track_roughness"] = grid[g]
    # Local roughness (damped_modes.cpp): when the continuation went rougher than the smoothest,
    # a Student-t prior (nu = local_roughness_dof, scale along the grid below stage 1's
    # roughness) on each knot's vector of the 2 n tracks' second differences, fitted by EM
    # (sd_i^2 = (nu s^2 + |D_i theta|^2) / (nu + 2 n), then the fit, until no sd_i moves by 5 %,
    # at most 10 sweeps); each scale taken while rss + price dof stays below the current fit's,
    # its dof counting one more per bent knot (|D_i theta|^2 > nu s^2).
    uniform_roughness = res["track_roughness"]
    roughness_sd = uniform_roughness
    res["roughness_sd"] = None
    local_knots = 0
    nu = o.get("local_roughness_dof", 1.0)
    if nu > 0 and o["track_roughness"] < 0 and uniform_roughness > grid[0]:
        d2 = track.second_differences()

        def em_sd(at, scale):
            bends = d2 @ at[:2 * modes * m].reshape(2 * modes, m).T  # (knots x tracks)
            return np.sqrt((nu * scale ** 2 + np.sum(bends ** 2, axis=1)) / (nu + 2 * modes))

        for scale in [g for g in grid if g < uniform_roughness]:
            candidate = fit["theta"]
            sd = em_sd(candidate, scale)
            for sweep in range(1, 11):  # sd stays the last fit's SDs when the sweeps end
                problem = VpProblem(p, modes, ig, wv, design["functions"], design["terms"],
                                    design["pairs"], design["weight"], prior_rows(track, modes, sd),
                                    tie, so[0])
                candidate, usable, conv, nfev = solve(problem, candidate, o["max_iterations"])
                res["iterations"] += nfev
                if not usable or sweep == 10:
                    break
                following = em_sd(candidate, scale)
                if np.max(np.abs(np.log(following / sd))) < math.log(1.05):
                    break
                sd = following
            knots = int(np.count_nonzero(sd ** 2 * (nu + 2 * modes) > 2.0 * nu * scale ** 2))

            def lower(rss, dof, price):
                return rss + price * (dof + knots) < fit["rss"] + price * (fit["dof"] + local_knots)

            if not take_fit(problem, candidate, usable, conv, True, usable and spurious(problem, candidate),
                            lower):
                break
            local_knots = knots
            roughness_sd, res["track_roughness"] = sd, scale
        if res["track_roughness"] != uniform_roughness:
            res["roughness_sd"] = roughness_sd
            res["roughness_t_s"] = p["t_s"][0] + track.h * np.arange(len(roughness_sd))
    theta, converged, final = fit["theta"], fit["converged"], fit["problem"]

    if shapes:
        d = shape_design(final, theta, roughness_sd)
        stage2 = VpProblem(p, modes, ig, wv, d["functions"], d["terms"], d["pairs"], d["weight"],
                           prior_rows(track, modes, roughness_sd), tie, so[0])
        theta2, usable, conv, nfev = solve(stage2, theta, o["max_iterations"])
        res["iterations"] += nfev
        # With the weight from the data, kept only when its BIC beats the constant shapes'
        # (lower_bic in damped_modes.cpp).
        if usable and (o["shape_weight"] >= 0 or lower_bic(stage2, theta2, final, theta)):
            theta, converged, final, res["shape_weight"] = theta2, conv, stage2, d["weight"]
        elif not usable:
            shape = None

    # Shape refit (damped_modes.cpp): when stage 1 chose tracks rougher than the smoothest, the
    # shape stage from the smoothest fit, the roughness continuation in it below stage 1's
    # choice (every candidate from two starts), the weight re-chosen at its tracks; kept when its
    # BIC is lower and its frequency tracks stay 1 / (4 shape knot spacing) apart.
    res["shape_refit"] = False
    if (o.get("shape_refit", True) and shape is not None and o["shape_weight"] < 0
            and len(grid) > 1 and tie.sd == 0 and smoothest is not None
            and uniform_roughness > grid[0]):
        base = VpProblem(p, modes, ig, wv, constant, terms, [], 0.0, prior_rows(track, modes, grid[0]),
                         DecayTie(), so[0])
        design.update(shape_design(base, smoothest, grid[0]))
        first = (final, theta, converged)
        fit.update(problem=None, rss=np.inf, dof=0.0)
        refit_roughness, start = None, smoothest
        for g, roughness in enumerate(grid):
            if roughness >= uniform_roughness:
                break
            if not try_candidate(roughness, tie, True, start, rougher, True):
                if skipped[0] is None:
                    break
                start = skipped[0]
                continue
            refit_roughness, start = roughness, fit["theta"]
        take = False
        if fit["problem"] is not None:
            prior = prior_rows(track, modes, refit_roughness)
            probe = VpProblem(p, modes, ig, wv, design["functions"], design["terms"], design["pairs"],
                              1.0, prior, tie, so[0])
            w = choose_shape_weight(probe, fit["theta"], p)
            if w != design["weight"]:
                again = VpProblem(p, modes, ig, wv, design["functions"], design["terms"],
                                  design["pairs"], w, prior, tie, so[0])
                theta2, usable, conv, nfev = solve(again, fit["theta"], o["max_iterations"])
                res["iterations"] += nfev
                if usable:
                    fit.update(problem=again, theta=theta2, converged=conv)
                    design["weight"] = w
            omega = frequency_tracks(fit["theta"])
            min_gap = 2.0 * np.pi / (4.0 * o["shape_knot_spacing_s"])
            too_close = any(np.ptp(np.sign(omega[:, j] - omega[:, k])) > 1
                            or np.min(np.abs(omega[:, j] - omega[:, k])) < min_gap
                            for j in range(modes) for k in range(j + 1, modes))
            take = (lower_bic(fit["problem"], fit["theta"], first[0], first[1], local_knots)
                    and not too_close)
        if take:
            final, theta, converged = fit["problem"], fit["theta"], fit["converged"]
            res["track_roughness"], res["shape_weight"] = refit_roughness, design["weight"]
            res["shape_refit"] = True
            res["roughness_sd"] = None
        else:
            final, theta, converged = first

    # Final evaluation: linear solution and Jacobian for the posterior covariance.
    if not final.evaluate(theta):
        raise SystemExit("modal fit: the fit failed")
    jac = final.jacobian(theta)
    beta, e = final.beta, final.e
    rd = final.rd
    r_data = final.resid[:rd]
    dof = max(1, rd - final.nl - final.np)
    chi2 = (r_data @ r_data) / dof
    res["converged"] = converged
    res["residual_rms_whitened"] = math.sqrt((r_data @ r_data) / rd)
    jd, jp = jac[:rd], jac[rd:]
    res["effective_parameters"] = (effective_parameters(jd.T @ jd, jp.T @ jp)
                                   + linear_effective(final, theta)
                                   + (local_knots if res["roughness_sd"] is not None else 0))
    res["bic"] = rd * math.log(r_data @ r_data) + math.log(rd) * res["effective_parameters"]
    covariance = max(1.0, chi2) * np.linalg.pinv(jac.T @ jac)

    values, slopes = track_values, track.first_derivatives(p["tau_s"])
    curvatures = track.second_derivatives(p["tau_s"])
    functions, function_slopes = final.functions, np.zeros_like(final.functions)
    if shape is not None:
        function_slopes = np.hstack([np.zeros((n, 1)), shape.first_derivatives(p["tau_s"])])
    coef = beta[0:final.nt:2] + 1j * beta[1:final.nt:2]
    th = theta[:2 * modes * m].reshape(modes, 2, m)
    lower = p["L"].astype(complex)
    if mass_at is not None:
        metric = np.array([mass_at(t) for t in p["t_s"]])  # (N, C, C)
        metric_dot = np.gradient(metric, p["t_s"], axis=0) if n > 1 else np.zeros_like(metric)
    fitted = np.zeros((n, c))
    tracks = []
    for j in range(modes):
        ca, cw = th[j, 0], th[j, 1]
        mt = dict(alpha=values @ ca, omega=values @ cw, alpha_dot=slopes @ ca, omega_dot=slopes @ cw)
        mt["decay_ratio"] = float(theta[2 * modes * m + j - 1]) if j > 0 and tie.sd > 0 else 1.0
        mt["f"] = mt["omega"] / (2 * np.pi)
        cov_aw = covariance[2 * j * m:(2 * j + 2) * m, 2 * j * m:(2 * j + 2) * m]
        cov_w = cov_aw[m:, m:]
        gradient = np.hstack([values, np.zeros_like(values)])  # d alpha / d (ca, cw)
        if wv is not None:  # alpha = a - omega' / (2 omega), a = -Gamma the spline
            w, w_dot = mt["omega"], mt["omega_dot"]
            w_ddot = curvatures @ cw
            mt["alpha"] = mt["alpha"] - w_dot / (2 * w)
            mt["alpha_dot"] = mt["alpha_dot"] - (w_ddot / (2 * w) - w_dot ** 2 / (2 * w ** 2))
            gradient[:, m:] = -(slopes / (2 * w)[:, None] - values * (w_dot / (2 * w ** 2))[:, None])
        mt["alpha_sd"] = np.sqrt(np.sum((gradient @ cov_aw) * gradient, axis=1))
        mt["f_sd"] = np.sqrt(np.sum((values @ cov_w) * values, axis=1)) / (2 * np.pi)
        sel = final.t_modes == j
        cols_j = final.function_columns(j)
        w = (functions[:, cols_j] * coef[sel]) @ final.t_dirs[:, sel].T  # whitened shape (N x C)
        w_dot = (function_slopes[:, cols_j] * coef[sel]) @ final.t_dirs[:, sel].T
        a = w @ lower.T
        a_dot = w_dot @ lower.T
        mt["shape"] = a
        if mass_at is not None:
            norm2 = np.einsum("ik,ikl,il->i", np.conj(a), metric, a).real
            rate = (np.einsum("ik,ikl,il->i", np.conj(a), metric, a_dot)
                    + 0.5 * np.einsum("ik,ikl,il->i", np.conj(a), metric_dot, a))
            safe = np.where(norm2 > 0, norm2, 1.0)
            d_alpha = np.where(norm2 > 0, rate.real / safe, 0.0)
            d_omega = np.where(norm2 > 0, rate.imag / safe, 0.0)
            grad = (lambda v: np.gradient(v, p["t_s"])) if n > 1 else np.zeros_like
            mt["alpha"] = mt["alpha"] + d_alpha
            mt["omega"] = mt["omega"] + d_omega
            mt["alpha_dot"] = mt["alpha_dot"] + grad(d_alpha)
            mt["omega_dot"] = mt["omega_dot"] + grad(d_omega)
            mt["f"] = mt["omega"] / (2 * np.pi)
        growth, phase_integral = np.log(np.abs(e[:, j])), ig @ cw  # Re Phi_j, Im Phi_j
        mt["envelope"] = np.abs(a) * np.exp(growth)[:, None]
        mt["phase"] = np.unwrap(np.angle(a), axis=0) + phase_integral[:, None]
        power = np.abs(a) ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            rate = np.where(power > 0, (a_dot * np.conj(a)).real / np.where(power > 0, power, 1), 0.0)
        mt["log_envelope_rate"] = mt["alpha"][:, None] + rate
        fitted += (a * e[:, j:j + 1]).real
        with np.errstate(divide="ignore"):
            mt["anr_db"] = 10 * np.log10(0.5 * np.sum(np.abs(w) ** 2, axis=1) * np.abs(e[:, j]) ** 2)
        mt["valid"] = (converged & (mt["anr_db"] >= o["anr_threshold_db"])
                       & (mt["f_sd"] <= o["max_frequency_sd_hz"]) & (mt["omega"] > 0)
                       & np.isfinite(mt["alpha"]))
        tracks.append(mt)
    flag_degenerate_modes(p, o, tracks)
    order = sorted(range(modes), key=lambda j: tracks[j]["omega"].mean())
    res["modes"] = [tracks[j] for j in order]
    res["fitted"] = fitted
    if o["lost_track_time_s"] >= 0:
        continue_lost_tracks(res["t_s"], o["lost_track_time_s"], o["anr_threshold_db"],
                             res["modes"])
    return res


def continue_lost_tracks(t_s, time_s, anr_threshold_db, tracks):
    """After the last sample at which a mode's ANR is at or above the threshold (every later one
    below it: sunk into the noise; the mode valid somewhere before), omega and alpha (and their
    slopes) go on as a damped trend (time constant time_s; 0: held); envelope, phase and ANR stay
    the fitted model's."""
    for mt in tracks:
        above = np.nonzero(mt["anr_db"] >= anr_threshold_db)[0]
        if above.size == 0 or above[-1] == t_s.size - 1:
            continue
        last = above[-1]
        if not np.any(mt["valid"][:last + 1]):
            continue
        s = t_s[last + 1:] - t_s[last]
        decay = np.exp(-s / time_s) if time_s > 0 else np.zeros_like(s)
        rise = time_s * (1.0 - decay)
        for name in ("omega", "alpha"):
            mt[name][last + 1:] = mt[name][last] + mt[name + "_dot"][last] * rise
            mt[name + "_dot"][last + 1:] = mt[name + "_dot"][last] * decay
        mt["f"] = mt["omega"] / (2 * np.pi)


def flag_degenerate_modes(p, o, tracks):
    n, c = p["y"].shape
    cumulative = np.concatenate([[0.0], np.cumsum(np.sum(p["yw"].reshape(n, c) ** 2, axis=1))])
    half = max(1, lround(0.25 * p["rate_hz"]))
    i = np.arange(n)
    lo, hi = np.maximum(0, i - half), np.minimum(n, i + half + 1)
    local = (cumulative[hi] - cumulative[lo]) / (hi - lo)
    ratio = 10.0 ** (o["max_mode_to_data_db"] / 10.0)
    for mt in tracks:
        mt["valid"] &= ~(10.0 ** (mt["anr_db"] / 10.0) > ratio * local)
    for j in range(len(tracks)):
        for k in range(j + 1, len(tracks)):
            a, b = tracks[j], tracks[k]
            gap = np.abs(a["f"] - b["f"])
            limit = np.maximum(o["min_mode_separation"] * 0.5 * (a["f"] + b["f"]),
                               2.0 * (a["f_sd"] + b["f_sd"]))
            bad = ~(gap > limit)
            a["valid"] &= ~bad
            b["valid"] &= ~bad


# ---- modal_parameters.cpp, models/arm.cpp -------------------------------------------------------
def spd_sqrt(m):
    """(T, C, C) symmetric square roots."""
    ev, vec = np.linalg.eigh(m)
    return vec @ (np.sqrt(ev)[..., None] * np.swapaxes(vec, -1, -2))


def most_real(u):
    """(T, C, n) complex shapes -> real unit vectors, each at its most real phase."""
    phi = 0.5 * np.angle(np.sum(u * u, axis=-2, keepdims=True))
    v = (u * np.exp(-1j * phi)).real
    return v / np.linalg.norm(v, axis=-2, keepdims=True)


def modal_parameters(tracks, mass, mapping="eq48"):
    """Eqs 45-46 and the eq-48 mapping (real P, the default) or the state-space one (mapping
    "state_space"), every time at once. mass (T, C, C)."""
    w = np.stack([t["omega"] for t in tracks], axis=1)  # (T, n)
    a = np.stack([t["alpha"] for t in tracks], axis=1)
    w_dot = np.stack([t["omega_dot"] for t in tracks], axis=1)
    a_dot = np.stack([t["alpha_dot"] for t in tracks], axis=1)
    gamma = -a - w_dot / (2 * w)  # eq 45
    eta2 = w * w + a * a + a * w_dot / w - a_dot  # eq 46 (alpha dot)
    shapes = np.stack([t["shape"] for t in tracks], axis=2)  # (T, C, n)
    n = shapes.shape[2]
    root = spd_sqrt(mass)
    raw = most_real(root @ shapes)
    # eq 43: the nearest orthogonal matrix with each valid mode weighted by its ANR power, the
    # invalid ones completed in the orthogonal complement of the valid ones
    # (modal_parameters.cpp, orthonormal_shapes)
    mode_valid = np.stack([t["valid"] for t in tracks], axis=1)  # (T, n)
    anr = np.stack([t["anr_db"] for t in tracks], axis=1)
    weight = np.where(mode_valid, 10.0 ** (anr / 10.0), 0.0)
    weight[~mode_valid.any(axis=1)] = 1.0  # none valid: the unweighted polar factor
    uu, _, vv = np.linalg.svd(raw * weight[:, None, :])
    p = uu @ vv
    for i in np.nonzero(mode_valid.any(axis=1) & ~mode_valid.all(axis=1))[0]:
        kept, lost = np.nonzero(mode_valid[i])[0], np.nonzero(~mode_valid[i])[0]
        ug, _, vg = np.linalg.svd(raw[i][:, kept] * weight[i, kept], full_matrices=False)
        u = ug @ vg
        rest = raw[i][:, lost] - u @ (u.T @ raw[i][:, lost])
        if np.linalg.norm(rest, axis=0).min() > 1e-9:
            ur, _, vr = np.linalg.svd(rest, full_matrices=False)
            completion = ur @ vr
        else:
            completion = np.linalg.svd(u)[0][:, len(kept):]
        p[i][:, kept] = u
        signs = np.where(np.sum(completion * raw[i][:, lost], axis=0) < 0.0, -1.0, 1.0)
        p[i][:, lost] = completion * signs
    if mapping == "state_space":
        mu = -gamma + 1j * np.sqrt(np.maximum(0.0, eta2 - gamma * gamma))
        v_mu = shapes * mu[:, None, :]
        x = np.concatenate([np.concatenate([shapes, shapes.conj()], axis=2),
                            np.concatenate([v_mu, v_mu.conj()], axis=2)], axis=1)
        y = np.concatenate([v_mu * mu[:, None, :], (v_mu * mu[:, None, :]).conj()], axis=2)
        kc = -(mass @ y @ np.linalg.inv(x)).real
        k, c = kc[:, :, :n], kc[:, :, n:]
    else:  # eq 48: M^1/2 P diag(eta^2) P^T M^1/2, M^1/2 P diag(2 Gamma) P^T M^1/2
        pt = np.swapaxes(p, 1, 2)
        k = root @ (p * eta2[:, None, :]) @ pt @ root
        c = root @ (p * (2.0 * gamma)[:, None, :]) @ pt @ root
    k = 0.5 * (k + np.swapaxes(k, 1, 2))
    c = 0.5 * (c + np.swapaxes(c, 1, 2))
    valid = np.all([t["valid"] for t in tracks], axis=0) & np.all(eta2 > gamma * gamma, axis=1)
    finite = np.isfinite(k).all(axis=(1, 2)) & np.isfinite(c).all(axis=(1, 2))
    pos = np.zeros(k.shape[0], bool)
    pos[finite] = np.linalg.eigvalsh(k[finite]).min(axis=1) > 0
    return dict(gamma=gamma, eta2=eta2, k=k, c=c, p=p, root=root, valid=valid & finite & pos)


# ---- tfa.cpp, tfa_deviation.cpp, normalized_force.cpp -------------------------------------------
def read_trial(path, angles):
    with open(path) as f:
        header = [h.split("[")[0].strip() for h in f.readline().strip().split(",")]
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    t = raw[:, header.index("t")]
    return t, raw[:, [header.index(a) for a in angles]]


def identify(path, onset_s, angles=("th1", "th2"), o=OPTIONS):
    t, ang = read_trial(path, angles)
    step = (t[-1] - t[0]) / (t.size - 1)
    fs = 1.0 / step
    dt = 1.0 / fs  # trial.step_s(), as the C++ code rounds it
    onset = math.ceil((onset_s - t[0]) / dt - 1e-9)
    lead_s = o["noise_window_s"] + 0.1
    first_row = max(0, onset - lround(lead_s / dt))
    start_s = t[0] + first_row * dt
    free_start_s = max(onset_s + PULSE_S, t[0] + onset * dt)
    pre = lround(PRE_ONSET_S / dt)
    posture = ang[onset - pre:onset].mean(axis=0)
    dev = ang[first_row:] - posture
    o = dict(o)
    o["skip_s"] = max(o["skip_s"], free_start_s - onset_s)
    available = onset_s - start_s - 0.05
    if available >= 0.1:
        o["noise_window_s"] = min(o["noise_window_s"], available)
    modes = ang.shape[1]
    # M(theta_0(t)): the posture is constant without a baseline.
    # --decay-tracks best: both fits, the lower BIC kept (alpha on a tie), as stiffid's.
    fits = {}
    for kind in (("alpha", "gamma") if o["decay_tracks"] == "best" else (o["decay_tracks"],)):
        fits[kind] = fit_damped_modes(dev, fs, start_s, onset_s,
                                      dict(o, damping_tracks=kind == "gamma"), modes,
                                      mass_at=lambda t_s: inertia(posture[1]))
    kept = "gamma" if "gamma" in fits and ("alpha" not in fits
                                           or fits["gamma"]["bic"] < fits["alpha"]["bic"]) else "alpha"
    fit = fits[kept]
    tracks = fit["modes"]
    times = fit["t_s"]
    decimation = max(1, lround(fs / fit["rate_hz"]))
    # M(theta_0(t)) at the nearest input sample: the posture is constant without a baseline.
    rows = np.clip(np.array([lround(v) for v in (times - start_s) * fs]), 0, dev.shape[0] - 1)
    th2 = np.full(rows.size, posture[1])
    mass = np.array([inertia(v) for v in th2])
    par = modal_parameters(tracks, mass, o["mapping"])

    omega = np.stack([tr["omega"] for tr in tracks], axis=1)
    alpha = np.stack([tr["alpha"] for tr in tracks], axis=1)
    shapes = np.stack([tr["shape"] for tr in tracks], axis=1)  # (T, n, C)
    ref = np.argmax(np.abs(shapes), axis=2)
    rot = np.exp(-1j * np.angle(np.take_along_axis(shapes, ref[:, :, None], axis=2)))
    rotated = shapes * rot
    mode_shape = rotated.real / np.linalg.norm(rotated.real, axis=2, keepdims=True)
    rho = np.angle(rotated)
    rho = np.where(rho > np.pi / 2, rho - np.pi, rho)
    rho = np.where(rho <= -np.pi / 2, rho + np.pi, rho)
    c = shapes.shape[2]
    others = np.arange(c)[None, None, :] != ref[:, :, None]
    last_other = c - 1 - np.argmax(others[:, :, ::-1], axis=2)
    folded = np.take_along_axis(rho, last_other[:, :, None], axis=2)[:, :, 0]
    # Eq 49 normalized force from the complex envelopes.
    amp_c = np.stack([tr["envelope"] * np.exp(1j * tr["phase"]) for tr in tracks], axis=1)
    projector = par["root"] @ par["p"]  # (T, C, n): column j = M^1/2 p_j
    z = np.einsum("tcj,tjc->tj", projector, amp_c.real) + 1j * np.einsum("tcj,tjc->tj", projector, amp_c.imag)
    lam = alpha + 1j * omega
    q = z.real
    q_dot = (lam * z).real
    envelope = np.abs(z)
    force = dict(q=q, q_dot=q_dot, sigma=par["eta2"] * q + 2 * par["gamma"] * q_dot, envelope=envelope,
                 envelope_force=par["eta2"] * envelope + 2 * par["gamma"] * alpha * envelope)

    def cols(v):  # (T x n) -> [n][T]
        return [series(v[:, j]) for j in range(v.shape[1])]

    def mats(v):  # (T, r, c) -> [r][c][T]
        return [[series(v[:, r, cc]) for cc in range(v.shape[2])] for r in range(v.shape[1])]

    out = {"method": "modal",
           "options": {"angles": list(angles), "forces": [], "onset": str(onset_s), "baseline": "",
                       "subject": "", "arm": {"l1_m": ARM["l1"], "r1_m": ARM["r1"], "m1_kg": ARM["m1"],
                                              "iz1_kg_m2": ARM["i1"], "l2_m": ARM["l2"], "r2_m": ARM["r2"],
                                              "m2_kg": ARM["m2"], "iz2_kg_m2": ARM["i2"]},
                       "pulse_s": PULSE_S, "decimation": decimation,
                       "decimate_hz": OPTIONS["decimate_hz"], "knots_s": OPTIONS["knot_spacing_s"],
                       "shape_knots_s": OPTIONS["shape_knot_spacing_s"], "skip_s": OPTIONS["skip_s"],
                       "noise_window_s": OPTIONS["noise_window_s"], "init_window_s": OPTIONS["init_window_s"],
                       "anr_threshold_db": OPTIONS["anr_threshold_db"],
                       "max_frequency_sd_hz": OPTIONS["max_frequency_sd_hz"],
                       "max_mode_to_data_db": OPTIONS["max_mode_to_data_db"],
                       "min_mode_separation": OPTIONS["min_mode_separation"],
                       "shape_weight": fit["shape_weight"], "track_roughness": fit["track_roughness"],
                       "shape_weight_from_data": OPTIONS["shape_weight"] < 0,
                       "track_roughness_from_data": OPTIONS["track_roughness"] < 0,
                       "local_roughness_dof": OPTIONS["local_roughness_dof"],
                       "lost_track_time_s": OPTIONS["lost_track_time_s"],
                       "decay_tie": fit["decay_tie"],
                       "decay_tie_from_data": OPTIONS["decay_tie"] < 0,
                       "shape_refit": bool(fit["shape_refit"]),
                       "mapping": OPTIONS["mapping"],
                       "decay_tracks": kept,
                       "decay_tracks_from_data": o["decay_tracks"] == "best"},
           "track_roughness_local": (None if fit["roughness_sd"] is None else
                                     {"t_s": series(fit["roughness_t_s"]),
                                      "sd": series(fit["roughness_sd"])}),
           "residual_rms_whitened": fit["residual_rms_whitened"], "converged": bool(fit["converged"]),
           "effective_parameters": fit["effective_parameters"], "bic": fit["bic"],
           "decay_tracks_residual_rms_whitened": (
               {k: fits[k]["residual_rms_whitened"] for k in fits} if len(fits) == 2 else None),
           "decay_tracks_bic": {k: fits[k]["bic"] for k in fits} if len(fits) == 2 else None,
           "noise_covariance_rad2": fit["noise_cov"].tolist(),
           "onset_s": onset_s, "free_start_s": free_start_s,
           "analysed_s": [float(times[0]), float(times[-1])], "analysis_rate_hz": fit["rate_hz"],
           "decimation": decimation, "t_s": series(times),
           "f_hz": cols(omega / (2 * np.pi)), "f_ridge_hz": cols(omega / (2 * np.pi)),
           "omega_rad_per_s": cols(omega),
           "amplitude": [cols(tr["envelope"]) for tr in tracks],
           "phase_rad": [cols(tr["phase"]) for tr in tracks],
           "alpha_per_s": cols(alpha), "alpha_ridge_per_s": cols(alpha),
           "gamma_per_s": cols(par["gamma"]), "eta_squared_per_s2": cols(par["eta2"]),
           "phase_difference_rad": cols(folded), "time_lag_s": cols(folded / omega),
           "eigenvectors": mats(par["p"]), "mode_shapes": mats(np.swapaxes(mode_shape, 1, 2)),
           "K_nm_per_rad": mats(par["k"]), "C_nms_per_rad": mats(par["c"]),
           "M_kg_m2": mats(par["root"] @ par["root"]),
           "normalized_force": {key: cols(v) for key, v in force.items()},
           "valid": [tr["valid"].tolist() for tr in tracks],
           "anr_db": [series(tr["anr_db"]) for tr in tracks],
           "K_valid": par["valid"].tolist(),
           "iterations": sum(f["iterations"] for f in fits.values()),
           "decay_ratio": [tr["decay_ratio"] for tr in tracks]}
    return out


def series(v):
    v = np.asarray(v, float)
    if np.isfinite(v).all():
        return v.tolist()
    return [float(x) if math.isfinite(x) else None for x in v.tolist()]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("trial", nargs="?")
    ap.add_argument("--onset", type=float, default=2.5)
    ap.add_argument("--angles", default="th1,th2")
    ap.add_argument("-o", "--output")
    ap.add_argument("--make-trial")
    ap.add_argument("--decay-tie", type=float, default=OPTIONS["decay_tie"],
                    help="as stiffid's --decay-tie: 0 no tie (default), < 0 from the data")
    ap.add_argument("--decay-tracks", choices=("alpha", "gamma", "best"),
                    default=OPTIONS["decay_tracks"],
                    help="as stiffid's --decay-tracks")
    a = ap.parse_args()
    OPTIONS["decay_tie"] = a.decay_tie
    OPTIONS["decay_tracks"] = a.decay_tracks
    if a.make_trial:
        make_trial(a.make_trial)
        return
    if not a.trial:
        ap.error("give TRIAL.csv or --make-trial PATH")
    out = identify(a.trial, a.onset, tuple(a.angles.split(",")))
    if a.output:
        with open(a.output, "w") as f:
            f.write(json.dumps(out))  # dumps: the C encoder (dump streams through the Python one)
    else:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
