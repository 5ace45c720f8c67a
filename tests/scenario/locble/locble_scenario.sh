#!/usr/bin/env bash
# LocBLE scenario test (docs/locble.md, "Accuracy"): `locus simulate locble` (env=world, the default)
# on fixed seeds through the shipped config (config/locble.yaml), scored by `locus eval --metric
# locble`. Guards, not the issue's bar: the campaign mean over 20 seeds is 3.5 m (bar 1.5 m, not met,
# docs/locble.md "Limits"); these seeds are ones where the method is at or near the bar today, so a
# change that breaks the dead reckoning, the frame or the posterior fails here.
#   - seeds 1, 14, 15 (measured 0.49 / 1.33 / 1.51 m): every tag located, mean final error <= 2.0 m;
#   - seeds 5, 9 (1.64 / 1.59 m): every tag located, mean final error <= 2.5 m.
# Seed-to-seed spread is large (0.5-7.8 m over seeds 1-20), so these are chosen, not representative.
#   locble_scenario.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
tmp="$(mktemp -d /tmp/locus-locble-scenario.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
fail=0

run_case() {  # seed max-mean-error-m
  local seed="$1" bar="$2" sc="$tmp/seed$1"
  timeout 60 "$locus" simulate locble "$sc" --seed "$seed" -q
  if ! timeout 60 "$locus" replay "$sc" --config "$src/config/locble.yaml" --speed max -o "$sc.est.jsonl" 2>"$sc.replay.log"; then
    echo "[seed $seed] locus replay failed:"; cat "$sc.replay.log"; fail=1; return
  fi
  local status=0
  timeout 60 "$locus" eval "$sc" "$sc.est.jsonl" --metric locble --max-unknown-targets 0 --min-located-fraction 1.0 \
    --max-mean-error-m "$bar" >"$sc.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[seed $seed] bars missed (locus eval exit $status):"; cat "$sc.eval.txt"; fail=1
  else
    echo "[seed $seed] OK: $(grep -E 'PASS' "$sc.eval.txt" | tr -s ' ' | tr '\n' ' ')"
  fi
}

run_case 1 2.0
run_case 14 2.0
run_case 15 2.0
run_case 5 2.5
run_case 9 2.5
exit "$fail"
