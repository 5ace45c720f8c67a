#!/usr/bin/env bash
# AMIL scenario test (docs/amil.md, "Accuracy"): bars on fixed seeds of the simulated field test
# (`locus simulate amil`), through the shipped config (config/amil.yaml). Two scene models:
#   - PAPER: the paper's distance-experiment gesture (Sec. V: (0,0) -> (-30.5,0) -> (0,30.5) ->
#     (30.5,0) cm) without the per-device transducer responses, babble/music bursts and hand wiggle
#     that `normal` now has (OLD below): seeds 3 and 11, every listener located, mean direction error
#     of the estimates not flagged inconsistent/weak <= DIR1 deg, every listener within 2.5 m with a
#     distance, their median distance error <= DIST1 %; three gestures (seed 5): located, unflagged
#     direction <= DIR3 deg.
#   - WORLD: `normal` as it is now (as hard as ../shared/scenes/README.md): seed 3, every listener
#     located, the unflagged ones' mean direction error <= DIR1 deg and every listener within 2.5 m
#     with a distance (the issue-13 bars hold over 20 seeds, not on every single seed: docs/amil.md).
# `locus eval` exits 4 when a bar is missed; this script then prints the eval table and fails.
#   amil_scenario.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
DIR1=3.0
DIST1=20
DIR3=3.0
tmp="$(mktemp -d /tmp/locus-amil-scenario.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
fail=0

OLD="-o shape=paper -o transducers=0 -o bursts=white -o wiggle_m=0 -o corner_jitter_m=0 -o pause_min_s=0.4 -o pause_max_s=0.7"

run_case() {  # name seed gestures "simulate-options" eval-options...
  local name="$1" seed="$2" gestures="$3" simopts="$4"
  shift 4
  local sc="$tmp/$name"
  # shellcheck disable=SC2086
  timeout 120 "$locus" simulate amil "$sc" --seed "$seed" -o "gestures=$gestures" $simopts >/dev/null
  if ! timeout 120 "$locus" replay "$sc" --config "$src/config/amil.yaml" --speed max -o "$sc.est.jsonl" \
         2>"$sc.replay.log"; then
    echo "[$name] locus replay failed:"; cat "$sc.replay.log"; fail=1; return
  fi
  local status=0
  timeout 60 "$locus" eval "$sc" "$sc.est.jsonl" --metric amil --max-unknown-targets 0 "$@" >"$sc.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[$name] bars missed (locus eval exit $status):"; cat "$sc.eval.txt"; fail=1
  else
    echo "[$name] OK: $(grep -E 'PASS' "$sc.eval.txt" | tr '\n' ' ')"
  fi
}

NEAR="--min-near-with-distance-fraction 1.0 --max-near-median-distance-error-pct $DIST1"
run_case paper-1g-s3 3 1 "$OLD" --min-located-fraction 1.0 --max-unflagged-direction-error-deg "$DIR1" $NEAR
run_case paper-1g-s11 11 1 "$OLD" --min-located-fraction 1.0 --max-unflagged-direction-error-deg "$DIR1" $NEAR
run_case paper-3g-s5 5 3 "$OLD" --min-located-fraction 1.0 --max-unflagged-direction-error-deg "$DIR3"
run_case world-1g-s3 3 1 "" --min-located-fraction 1.0 --max-unflagged-direction-error-deg "$DIR1" --min-near-with-distance-fraction 1.0
# hard: obstructed listeners' first paths are reflections; what is not flagged must be right
run_case world-hard-1g-s6 6 1 "--difficulty hard" --max-unflagged-direction-error-deg 5
exit "$fail"
