#!/usr/bin/env bash
# LocBLE scenario test (docs/locble.md, "Accuracy"): `locus simulate locble` (env=world, the default)
# on fixed seeds through the shipped config (config/locble.yaml), scored by `locus eval --metric
# locble`. Guards, not the issue's bar: the campaign mean over seeds 1-20 of the simulator as hard as
# the world is 6.4 m (bar 1.5 m, not met, docs/locble.md "Limits"); these seeds are the ones where the
# method does best today, so a change that breaks the dead reckoning, the frame or the posterior fails
# here.
#   - seeds 15, 4, 9 (measured 3.25 / 4.22 / 4.29 m): every tag located, mean final error <= 4.5 m;
#   - seed 1 (4.70 m): every tag located, mean final error <= 5.0 m.
# Seed-to-seed spread is large (3.3-9.3 m over seeds 1-20), so these are chosen, not representative.
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

run_case 15 4.5
run_case 4 4.5
run_case 9 4.5
run_case 1 5.0
exit "$fail"
