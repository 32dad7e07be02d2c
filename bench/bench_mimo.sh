#!/bin/sh
# End-to-end MIMO benchmark (issue 3): `stiffid frf --nfft 4096` + `stiffid irf --lags -0.1:0.5` on
# 10-minute, 1 kHz, 2x2 endpoint trials, against the Python peers (bench/peer_frf.py:
# scipy.signal.csd + numpy solve, coherences and the random-error bands; bench/peer_irf.py: numpy
# FFT correlations, Cholesky with LAPACK's condition estimate, VAF and R^2 both ways) doing the
# same work with the same settings and writing the same JSON, each side as two processes that
# read the CSV.
# Two trials (bench/make_bench_trial.py, the same model and noise, different force bandwidths):
#   broadband     forces low-passed at 100 Hz: Psi of eq 11 (1202 x 1202) is well conditioned
#                 (condition number ~6e6), and both sides solve it by Cholesky: the issue's
#                 equivalent scripts, doing the same work.
#   band-limited  forces low-passed at 9 Hz (Perreault et al. 1999's band) sampled at 1 kHz: Psi's
#                 reciprocal condition is ~5e-13, stiffid refuses the plain solve as singular, and
#                 both sides run the Westwick & Kearney MDL pseudo-inverse (--pinv mdl; the peer
#                 with numpy.linalg.eigh and the same rule).
#
#   bench/bench_mimo.sh [BUILD_DIR] [WORK_DIR] [RUNS]
#
# BUILD_DIR holds the stiffid program (default: build); WORK_DIR receives the trials (made once,
# ~40 MB each, not committed) and the JSON outputs (default: ${TMPDIR:-/tmp}/stiffid-bench). Runs
# alternate stiffid / peer RUNS times (default 5) after one warm-up each, timed with /usr/bin/time;
# prints each run, the medians and the ratio, then checks that both sides computed the same IRFs,
# VAFs and FRFs.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
work=${2:-${TMPDIR:-/tmp}/stiffid-bench}
runs=${3:-5}
python=/usr/bin/python3
stiffid=$(cd "$build" && pwd)/stiffid
mkdir -p "$work"
[ -x "$stiffid" ] || { echo "bench_mimo: no stiffid program in $build" >&2; exit 2; }

seconds() {  # wall-clock seconds of one run of a shell command
  /usr/bin/time -f %e -o "$work/time.txt" sh -c "$1" >/dev/null
  cat "$work/time.txt"
}
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

# compare NAME TRIAL IRF_FLAGS: times both sides on TRIAL, IRF_FLAGS given to both irf commands.
compare() {
  name=$1
  trial=$2
  irf_flags=$3
  io="--inputs fx,fy --outputs x,y"
  stiffid_cmd="\"$stiffid\" frf \"$trial\" $io --nfft 4096 -o \"$work/frf.json\" && \
\"$stiffid\" irf \"$trial\" $io --lags=-0.1:0.5 $irf_flags -o \"$work/irf.json\""
  peer_cmd="\"$python\" \"$here/peer_frf.py\" \"$trial\" $io --nfft 4096 -o \"$work/peer_frf.json\" && \
\"$python\" \"$here/peer_irf.py\" \"$trial\" $io --lags=-0.1:0.5 $irf_flags -o \"$work/peer_irf.json\""
  echo "== $name trial ($(basename "$trial")), irf ${irf_flags:-plain solve}"
  seconds "$stiffid_cmd" >/dev/null  # warm-up: page cache, dynamic loading
  seconds "$peer_cmd" >/dev/null
  : >"$work/stiffid_s.txt"
  : >"$work/peer_s.txt"
  i=1
  while [ "$i" -le "$runs" ]; do
    a=$(seconds "$stiffid_cmd")
    b=$(seconds "$peer_cmd")
    echo "$a" >>"$work/stiffid_s.txt"
    echo "$b" >>"$work/peer_s.txt"
    echo "run $i: stiffid $a s, peer $b s"
    i=$((i + 1))
  done
  ms=$(median <"$work/stiffid_s.txt")
  mp=$(median <"$work/peer_s.txt")
  echo "median wall time: stiffid $ms s, peer $mp s, peer/stiffid $(echo "$mp $ms" | awk '{printf "%.1f", $1 / $2}')x"
  "$python" - "$work" <<'PY'
import json, sys
import numpy as np
w = sys.argv[1]
def worst(a, b, keys):
    err = 0.0
    for path in keys:
        x, y = a, b
        for k in path:
            x, y = x[k], y[k]
        x = np.array([np.nan if v is None else v for v in x], dtype=float)
        y = np.array([np.nan if v is None else v for v in y], dtype=float)
        if not (np.isfinite(x) == np.isfinite(y)).all():
            return float("inf")  # null (non-finite) in one output only
        m = np.isfinite(x)
        err = max(err, float(np.max(np.abs(x[m] - y[m])) / np.max(np.abs(y[m]))))
    return err
irf, peer = json.load(open(w + "/irf.json")), json.load(open(w + "/peer_irf.json"))
keys = [("irf", o, i) for o in irf["outputs"] for i in irf["inputs"]]
print("IRF: max relative difference stiffid vs peer %.1e; VAF %s vs %s; R^2 %.4f vs %.4f" % (
    worst(irf, peer, keys), {k: round(v, 4) for k, v in irf["vaf_percent"].items()},
    {k: round(v, 4) for k, v in peer["vaf_percent"].items()}, irf["r2_percent"], peer["r2_percent"]))
print("IRF from correlations (eqs 12-13): VAF %s vs %s; R^2 %.4f vs %.4f; condition number %s vs %s" % (
    {k: round(v, 4) for k, v in irf["vaf_correlation_percent"].items()},
    {k: round(v, 4) for k, v in peer["vaf_correlation_percent"].items()},
    irf["r2_correlation_percent"], peer["r2_correlation_percent"],
    "%.6g" % irf["condition_number"] if irf.get("condition_number") else "-",
    "%.6g" % peer["condition_number"] if "condition_number" in peer else "-"))
frf, pfrf = json.load(open(w + "/frf.json")), json.load(open(w + "/peer_frf.json"))
keys = [("frf", o, i, part) for o in frf["outputs"] for i in frf["inputs"] for part in ("re", "im")]
print("FRF: max relative difference stiffid vs peer %.1e" % worst(frf, pfrf, keys))
keys = [("random_error", "frf_magnitude", o, i, part) for o in frf["outputs"] for i in frf["inputs"]
        for part in ("eps", "lower", "upper")]
keys += [("random_error", "coherence", kind, o, i, "eps") for kind in ("ordinary", "partial")
         for o in frf["outputs"] for i in frf["inputs"]]
keys += [("random_error", "coherence", "multiple", o, "eps") for o in frf["outputs"]]
print("random-error bands: max relative difference stiffid vs peer %.1e" % worst(frf, pfrf, keys))
PY
}

broadband=$work/mimo_bench_100hz.csv
limited=$work/mimo_bench.csv
[ -f "$broadband" ] || "$python" "$here/make_bench_trial.py" "$broadband" --force-hz 100
[ -f "$limited" ] || "$python" "$here/make_bench_trial.py" "$limited" --force-hz 9
compare broadband "$broadband" ""
compare band-limited "$limited" "--pinv mdl"
