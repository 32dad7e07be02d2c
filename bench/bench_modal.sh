#!/bin/bash
# Issue 7: times `stiffid tfa` with its default method (modal) on one 5 s, 4 kHz posture trial
# against the numpy/scipy peer bench/peer_modal.py in the same run (interleaved runs, medians,
# ratio; bench_tfa.sh does the work). Usage: bench/bench_modal.sh [BUILD_DIR] [RUNS]
here="$(cd "$(dirname "$0")" && pwd)"
exec "$here/bench_tfa.sh" "${1:-$here/../build}" "${2:-7}" modal peer_modal.py
