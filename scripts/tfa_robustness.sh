#!/bin/sh
# The modal tfa method on a posture trial (PROFILE: constant, sigmoid (default) or sharp K,
# models/specs/piovesan_posture_PROFILE.json) with one setting changed at a time (sample rate,
# hand position, stiffness scale, pulse amplitude, onset): the mean errors over directions 45,
# 90, 135 degrees and noise seeds 1-3 at 20 dB, and the runs meeting issue 7's targets for the
# non-common trials (docs/tfa_modal.md, "Cancelling modes"). Each line is
# scripts/tfa_method_table.py --set ...
#   scripts/tfa_robustness.sh [STIFFID] [OUT.md] [PROFILE]      (~4 min on the 2-core VM)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
stiffid=${1:-$here/../build/stiffid}
out=${2:-/dev/stdout}
profile=${3:-sigmoid}
case $profile in constant | sigmoid | sharp) ;; *)
  echo "tfa_robustness.sh: PROFILE must be constant, sigmoid or sharp, got '$profile'" >&2
  exit 2 ;;
esac
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# name|--set arguments (JSON values; K and C scaled together keep C = 0.01 K)
variants='defaults (4 kHz, hand (0.4, 0) m, 5 N at 2.5 s)|
sample rate 500 Hz|--set sample_rate_hz=500
sample rate 10 kHz|--set sample_rate_hz=10000
hand (0.45, -0.1) m|--set task.hand_m=[0.45,-0.1]
hand (0.3, 0.2) m|--set task.hand_m=[0.3,0.2]
hand (0.2, 0.35) m|--set task.hand_m=[0.2,0.35]
K and C x 0.5|--set viscoelasticity.stiffness_nm_per_rad=[[17.5,2.5],[2.5,10]] --set viscoelasticity.damping_nms_per_rad=[[0.175,0.025],[0.025,0.1]]
K and C x 2|--set viscoelasticity.stiffness_nm_per_rad=[[70,10],[10,40]] --set viscoelasticity.damping_nms_per_rad=[[0.7,0.1],[0.1,0.4]]
pulse 2 N|--set perturbations.0.amplitude_n=2
pulse 20 N|--set perturbations.0.amplitude_n=20
onset 1.5 s (stiffness change with it)|--set perturbations.0.onset_s=1.5 --set viscoelasticity.stiffness_profile.start_s=1.5 --set viscoelasticity.damping_profile.start_s=1.5'
{
  echo "$profile K, 20 dB, directions 45, 90, 135 degrees, seeds 1-3: mean % RMS errors over"
  echo "2.6-3.175 s / 2.6-4.5 s after an onset at 2.5 s (the intervals move with the onset)."
  echo
  echo "| variant | runs | k11 | k12 | k22 | c11 | c12 | c22 | K_valid % | runs meeting targets |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  echo "$variants" | while IFS='|' read -r name args; do
    # shellcheck disable=SC2086  # args: --set KEY=JSON words, no spaces inside
    /usr/bin/python3 "$here/tfa_method_table.py" --stiffid "$stiffid" --methods modal \
      --profiles "$profile" --snr 20 --directions 45,90,135 --seeds 1,2,3 --summary $args \
      -o "$work/table.md" > /dev/null
    # The means over directions and seeds: the summary row with direction "all".
    grep "^| $profile | all |" "$work/table.md" | awk -F'|' -v name="$name" '{
      for (i = 1; i <= NF; i++) gsub(/^ +| +$/, "", $i)
      printf "| %s | %s |", name, $6
      for (i = 0; i < 6; i++) printf " %s / %s |", $(7 + i), $(13 + i)
      printf " %s | %s |\n", $19, $24 }'
  done
} > "$work/out.md"
if [ "$out" = /dev/stdout ]; then cat "$work/out.md"; else mv "$work/out.md" "$out.tmp" && mv "$out.tmp" "$out"; fi
