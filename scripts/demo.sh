#!/usr/bin/env bash
# The main job: MIMO identification of the shipped 2x2 endpoint example, frequency domain (stiffid
# frf) and time domain (stiffid irf) with a short human summary; then Perreault et al. 1999's
# simulation results reproduced (stiffid study perreault1999: Tables 1-2, Fig 6B, Fig 9).
set -euo pipefail
stiffid=${1:-build/stiffid}
root=$(cd "$(dirname "$0")/.." && pwd)
trial="$root/data/examples/endpoint_c25_snr20.csv"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

echo "== stiffid frf: $trial"
"$stiffid" frf "$trial" --inputs fx,fy --outputs x,y --nfft 256 --overlap 0.5 -o "$out/frf.json"
echo "== stiffid irf: $trial"
"$stiffid" irf "$trial" --inputs fx,fy --outputs x,y --lags -0.1:1.0 -o "$out/irf.json"

/usr/bin/python3 - "$out/frf.json" "$out/irf.json" <<'PY'
import json, sys
frf = json.load(open(sys.argv[1]))
irf = json.load(open(sys.argv[2]))
f = frf["frequency_hz"]
print(f"\nFRF: {len(f)} bins of {f[1]-f[0]:.3f} Hz from {frf['segments']} Welch segments of {frf['nfft']} samples")
for out in frf["outputs"]:
    coh = frf["coherence"]["multiple"][out]
    good = [fi for fi, c in zip(f, coh) if c > 0.9]
    band = f"{min(good):.2f}-{max(good):.2f} Hz" if good else "none"
    print(f"  output {out}: multiple coherence > 0.9 over {band} ({len(good)} of {len(f)} bins)")
    for inp in frf["inputs"]:
        h = frf["frf"][out][inp]
        print(f"    static compliance {out}/{inp} at {f[1]:.2f} Hz: {h['re'][1]:+.3e} m/N")
print(f"IRF: lags {irf['lag_s'][0]:+.2f} to {irf['lag_s'][-1]:+.2f} s")
for out, v in irf["vaf_percent"].items():
    print(f"  VAF {out}: {v:.2f} %")
print(f"  R^2: {irf['r2_percent']:.2f} %")
PY

echo
echo "== stiffid study perreault1999 (150 simulated trials; report in $out/perreault1999)"
"$stiffid" study perreault1999 --store "$out/perreault1999.sqlite" --report "$out/perreault1999"
sed -n '/^## Table 1/,$p' "$out/perreault1999/report.md" | grep -v '^Ours: \|^Paper (no numbers'
