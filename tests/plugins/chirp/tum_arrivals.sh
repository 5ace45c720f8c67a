#!/usr/bin/env bash
# TUM detection bar (issue 14): the `chirp` detector with the scene's templates (config/replay-chirp-tum.yaml,
# own-emission cancellation on) must put >= 99 % of ALL arrivals (own, cross between the overlapping
# working pair, monitoring devices) within 1 sample of truth and none more than 5 samples off, on
#   1. the foreign scene ../shared/scenes/tum-102 (skipped when absent, unless CI=true), and
#   2. a `locus simulate tum` scene with overlapping exchanges (0-40 ms offsets) at 50 dB near-far, fixed seed.
# Scored by tools/scripts/check_tum_arrivals.py (exit 4 when a bar is missed).
# usage: tum_arrivals.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
py=/usr/bin/python3
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
status=0

score() {  # scene detections
  "$py" "$src/tools/scripts/check_tum_arrivals.py" "$1" "$2" --min-within1 0.99 --max-off5 0 || status=1
}

scene="$src/../shared/scenes/tum-102"
if [ -d "$scene" ]; then
  "$locus" replay "$scene" --config "$src/config/replay-chirp-tum.yaml" --speed max \
    --events audio_detection -o "$work/tum102.jsonl"
  score "$scene" "$work/tum102.jsonl"
elif [ "${CI:-}" = "true" ]; then
  echo "FAIL: $scene is missing (CI=true)" >&2
  status=1
else
  echo "skipped: $scene not present"
fi

"$locus" simulate tum "$work/sim" --seed 3 --duration 8 -o overlap=1 -o near_far_db=50 >/dev/null
"$locus" replay "$work/sim" --config "$src/config/replay-chirp-tum.yaml" --speed max \
  --events audio_detection -o "$work/sim.jsonl"
score "$work/sim" "$work/sim.jsonl"
exit $status
