#!/usr/bin/env bash
# AMIL scenario test (docs/amil.md, "Accuracy"): the issue's bars, with margin, on fixed seeds of the
# simulated field test (`locus simulate amil`), through the shipped config (config/amil.yaml):
#   - normal, one gesture, seeds 3 and 11: every listener located, mean direction error <= DIR1 deg,
#     median distance error (all 12 listeners) <= DIST1 %, no unknown targets;
#   - normal, three gestures, seed 5: every listener located, mean direction error <= DIR3 deg,
#     mean position error <= POS3 m.
# `locus eval` exits 4 when a bar is missed; this script then prints the eval table and fails.
#   amil_scenario.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
DIR1=3.0
DIST1=20
DIR3=3.0
POS3=1.0
tmp="$(mktemp -d /tmp/locus-amil-scenario.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
fail=0

run_case() {  # name seed gestures eval-options...
  local name="$1" seed="$2" gestures="$3"
  shift 3
  local sc="$tmp/$name"
  timeout 120 "$locus" simulate amil "$sc" --seed "$seed" -o "gestures=$gestures" >/dev/null
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

run_case normal-1g-s3 3 1 --min-located-fraction 1.0 --max-direction-error-deg "$DIR1" --max-median-distance-error-pct "$DIST1"
run_case normal-1g-s11 11 1 --min-located-fraction 1.0 --max-direction-error-deg "$DIR1" --max-median-distance-error-pct "$DIST1"
run_case normal-3g-s5 5 3 --min-located-fraction 1.0 --max-direction-error-deg "$DIR3" --max-mean-error-m "$POS3"
exit "$fail"
