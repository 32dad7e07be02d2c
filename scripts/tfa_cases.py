"""Pieces the tfa report scripts share (scripts/tfa_method_table.py, scripts/tfa_reach_report.py):
turning a spec's impulse and noise, the percentage RMS error, and the number format of the tables.
Needs numpy (Debian python3-numpy)."""
import numpy as np


def set_impulse(spec, direction_deg):
    """Points the spec's first perturbation (an impulse) at direction_deg (deg from +x)."""
    pulse = spec["perturbations"][0]
    pulse.pop("random_octant", None)
    pulse.pop("octant", None)
    pulse["direction_deg"] = direction_deg


def set_noise(spec, snr_db):
    """White measurement noise at snr_db (dB), or none when snr_db is None."""
    if snr_db is None:
        spec.pop("noise", None)
    else:
        spec["noise"] = {"snr_db": snr_db}


def rms_error(est, ref):
    """Percentage RMS error 100 RMS(est - ref) / RMS(ref)."""
    return 100.0 * np.sqrt(np.mean((est - ref)**2) / np.mean(ref**2))


def fmt(v):
    """A table cell: one decimal, or an exponent from 1000 on; n/a for None or non-finite."""
    if v is None or not np.isfinite(v):
        return "n/a"
    return "%.1f" % v if abs(v) < 1000 else "%.0e" % v
