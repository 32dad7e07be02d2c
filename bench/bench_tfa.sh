#!/bin/bash
# Times `stiffid tfa --method spectrogram` on one 5 s, 4 kHz posture trial against the numpy/scipy
# peer (bench/peer_tfa.py, the same stages) in the same run: median wall time of RUNS runs each,
# interleaved, and their ratio. Usage: bench/bench_tfa.sh [BUILD_DIR] [RUNS]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-$here/../build}"
runs="${2:-7}"
stiffid="$build/stiffid"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$here/peer_tfa.py" --make-trial "$work/trial.csv"
time_one() {  # wall seconds of one run of "$@"
  local start end
  start=$(date +%s.%N)
  "$@" > /dev/null
  end=$(date +%s.%N)
  echo "$end - $start" | bc -l
}
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
: > "$work/cpp" && : > "$work/py"
"$stiffid" tfa "$work/trial.csv" --angles th1,th2 --onset 2.5 --method spectrogram -o "$work/out.json"
for _ in $(seq "$runs"); do
  time_one "$stiffid" tfa "$work/trial.csv" --angles th1,th2 --onset 2.5 --method spectrogram \
    -o "$work/out.json" >> "$work/cpp"
  time_one /usr/bin/python3 "$here/peer_tfa.py" "$work/trial.csv" --onset 2.5 >> "$work/py"
done
cpp=$(median < "$work/cpp")
py=$(median < "$work/py")
echo "stiffid tfa: median ${cpp} s over $runs runs"
echo "peer_tfa.py: median ${py} s over $runs runs"
echo "ratio peer / stiffid: $(echo "$py / $cpp" | bc -l)"
