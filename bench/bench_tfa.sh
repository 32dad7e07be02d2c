#!/bin/bash
# Times `stiffid tfa --method METHOD` on one 5 s, 4 kHz posture trial against its numpy/scipy peer
# (the same stages) in the same run: median wall time of RUNS runs each, interleaved, and their
# ratio. METHOD spectrogram (default) is compared with bench/peer_tfa.py, modal with
# bench/peer_modal.py (bench/bench_modal.sh); PEER names another script in bench/.
# Usage: bench/bench_tfa.sh [BUILD_DIR] [RUNS] [METHOD] [PEER]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-$here/../build}"
runs="${2:-7}"
method="${3:-spectrogram}"
peer="${4:-peer_tfa.py}"
stiffid="$build/stiffid"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$here/peer_tfa.py" --make-trial "$work/trial.csv"
time_one() {  # wall seconds of one run of "$@" (bash's own clock: no process forked to read it)
  local start end
  start=$EPOCHREALTIME
  "$@" > /dev/null
  end=$EPOCHREALTIME
  echo "$end - $start" | bc -l
}
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
: > "$work/cpp" && : > "$work/py"
"$stiffid" tfa "$work/trial.csv" --angles th1,th2 --onset 2.5 --method "$method" -o "$work/out.json"
for _ in $(seq "$runs"); do
  time_one "$stiffid" tfa "$work/trial.csv" --angles th1,th2 --onset 2.5 --method "$method" \
    -o "$work/out.json" >> "$work/cpp"
  time_one /usr/bin/python3 "$here/$peer" "$work/trial.csv" --onset 2.5 >> "$work/py"
done
cpp=$(median < "$work/cpp")
py=$(median < "$work/py")
echo "stiffid tfa --method $method: median ${cpp} s over $runs runs"
echo "$peer: median ${py} s over $runs runs"
echo "ratio peer / stiffid: $(echo "$py / $cpp" | bc -l)"
