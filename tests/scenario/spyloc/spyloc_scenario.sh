#!/usr/bin/env bash
# SpyLoc scenario test (issue 16, docs/spyloc.md): fixed seeds of `locus simulate spyloc` through the
# shipped config (config/spyloc.yaml):
#   - detection: >= 98 % of the LoS beeps found with the right identity (the issue's bar; measured
#     98.2 % and 99.1 % on seeds 101 and 102), scored by tools/scripts/check_spyloc_arrivals.py
#     (needs python3 with numpy and yaml; without them this part is skipped, said so);
#   - localization: the walker located; median <= 0.5 m, p90 <= 1.2 m (measured with dead reckoning
#     0.18 / 0.66 m and 0.21 / 0.45 m). A regression guard: the issue's p90 <= 0.8 m holds on these two
#     seeds but not on every one of 20 (docs/spyloc.md "Localization").
# The foreign scene spyloc-104 is scored by the foreign-scene test (tests/foreign/bars/spyloc.args).
#   spyloc_scenario.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
tmp="$(mktemp -d /tmp/locus-spyloc-scenario.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
fail=0
py=""
for cand in /usr/bin/python3 python3; do
  if command -v "$cand" >/dev/null && "$cand" -c 'import numpy, yaml' 2>/dev/null; then py="$cand"; break; fi
done

run_case() {  # seed
  local seed="$1" sc="$tmp/s$1"
  timeout 120 "$locus" simulate spyloc "$sc" --seed "$seed" -q
  if ! timeout 120 "$locus" replay "$sc" --config "$src/config/spyloc.yaml" --speed max \
       --events estimate,audio_detection,decay_features -o "$sc.jsonl" 2>"$sc.replay.log"; then
    echo "[seed $seed] locus replay failed:"; cat "$sc.replay.log"; fail=1; return
  fi
  local status=0
  timeout 60 "$locus" eval "$sc" "$sc.jsonl" --metric spyloc --min-located-fraction 1.0 --max-unknown-targets 0 \
    --max-median-error-m 0.5 --max-p90-error-m 1.2 >"$sc.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[seed $seed] localization bars missed (locus eval exit $status):"; cat "$sc.eval.txt"; fail=1
  else
    echo "[seed $seed] localization OK: $(grep -E 'PASS' "$sc.eval.txt" | tr -s ' ' | tr '\n' ' ')"
  fi
  if [ -n "$py" ]; then
    status=0
    "$py" "$src/tools/scripts/check_spyloc_arrivals.py" "$sc" "$sc.jsonl" --min-los-found 0.98 >"$sc.det.txt" 2>&1 || status=$?
    if [ "$status" -ne 0 ]; then
      echo "[seed $seed] detection bar missed:"; cat "$sc.det.txt"; fail=1
    else
      echo "[seed $seed] detection OK: $(grep '  los' "$sc.det.txt")"
    fi
  else
    echo "[seed $seed] detection not scored: python3 with numpy and yaml not found"
  fi
}

run_case 101
run_case 102
exit "$fail"
