#!/usr/bin/env bash
# SpyLoc scenario test (issue 16, docs/spyloc.md): fixed seeds of `locus simulate spyloc` through the
# shipped config (config/spyloc.yaml):
#   - detection: >= 98 % of the LoS beeps found with the right identity (the issue's bar; measured
#     100 % and 100 % on seeds 101 and 102 — beeps the recording does not hold whole are not scored;
#     98.2 / 99.1 % when they were) and >= 60 % of those with the first path within 1 sample
#     (regression bar; measured 73.1 % and 63.8 %, before the multipath onset fit 44 %; the issue's bar
#     is 90 %), and >= 95 % of the published LoS/NLoS verdicts right (regression bar per seed; measured
#     95.9 % and 98.2 %, 92.7 / 93.9 % with the decay's verdict alone; the issue's 96 % holds pooled over
#     seeds 101-120: 97.2 %), scored by tools/scripts/check_spyloc_arrivals.py
#     (needs python3 with numpy and yaml; without them this part is skipped, said so);
#   - localization: the walker located; median <= 0.3 m, p90 <= 0.8 m (the issue's bar; measured
#     0.09 / 0.37 m and 0.11 / 0.35 m). It holds on these two seeds, on 15 of 20 and pooled over 20
#     (docs/spyloc.md "Localization");
#   - LoS/NLoS: the shipped model's recipe (`locus train spyloc` on seeds 3-6) tested on seeds 101 and
#     102 (`--test`): pooled accuracy >= 90 % (measured 92.9 %; issue: 96 %), NLoS >= 55 % (73 %).
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
  if command -v "$cand" >/dev/null && "$cand" -c 'import numpy, yaml, scipy' 2>/dev/null; then py="$cand"; break; fi
done

score_detection() {  # label scene bars...: the detection bars, by check_spyloc_arrivals.py
  local label="$1" sc="$2" status=0
  shift 2
  if [ -z "$py" ]; then echo "$label detection not scored: python3 with numpy, yaml and scipy not found"; return; fi
  "$py" "$src/tools/scripts/check_spyloc_arrivals.py" "$sc" "$sc.jsonl" "$@" >"$sc.det.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "$label detection bar missed:"; cat "$sc.det.txt"; fail=1
  else
    echo "$label detection OK: $(grep -E '  (los|verdicts)' "$sc.det.txt" | tr -s ' ')"
  fi
}

# The bars of seeds 101-103 were set in the quiet world (the difficulty's white noise bursts, 2 a
# minute), which they keep: since 2026-12-07 the simulator's default has babble / music interferers,
# measured by the interferer cases below at a harder 6 a minute.
quiet=(-o bursts=white -o bursts_per_minute=-1)

run_case() {  # seed
  local seed="$1" sc="$tmp/s$1"
  timeout 120 "$locus" simulate spyloc "$sc" --seed "$seed" -q "${quiet[@]}"
  if ! timeout 120 "$locus" replay "$sc" --config "$src/config/spyloc.yaml" --speed max \
       --events estimate,audio_detection,decay_features -o "$sc.jsonl" 2>"$sc.replay.log"; then
    echo "[seed $seed] locus replay failed:"; cat "$sc.replay.log"; fail=1; return
  fi
  local status=0
  timeout 60 "$locus" eval "$sc" "$sc.jsonl" --metric spyloc --min-located-fraction 1.0 --max-unknown-targets 0 \
    --max-median-error-m 0.3 --max-p90-error-m 0.8 >"$sc.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[seed $seed] localization bars missed (locus eval exit $status):"; cat "$sc.eval.txt"; fail=1
  else
    echo "[seed $seed] localization OK: $(grep -E 'PASS' "$sc.eval.txt" | tr -s ' ' | tr '\n' ' ')"
  fi
  score_detection "[seed $seed]" "$sc" --min-los-found 0.98 --min-los-within1 0.6 --min-verdicts 0.95
}

run_case 101
run_case 102

# Seed 103: the track used to slide across the line of its two LoS beacons after one 3-sigma range
# turned every heading hypothesis (docs/spyloc.md, "Seed 103"): the issue's p90 <= 0.8 m (measured
# 0.70 m with the Huber range update, range_huber_sigma 2; 3.90 m without it; 5.68 m while too-long
# ranges also counted as agreeing in the lost-track window).
timeout 120 "$locus" simulate spyloc "$tmp/s103" --seed 103 -q "${quiet[@]}"
status=0
timeout 120 "$locus" replay "$tmp/s103" --config "$src/config/spyloc.yaml" --speed max -o "$tmp/s103.jsonl" 2>"$tmp/s103.log" &&
  timeout 60 "$locus" eval "$tmp/s103" "$tmp/s103.jsonl" --metric spyloc --min-located-fraction 1.0 \
    --max-p90-error-m 0.8 >"$tmp/s103.eval.txt" 2>&1 || status=$?
if [ "$status" -ne 0 ]; then
  echo "[seed 103] p90 bar missed (exit $status):"; cat "$tmp/s103.log" "$tmp/s103.eval.txt" 2>/dev/null; fail=1
else
  echo "[seed 103] OK: $(grep -E 'PASS' "$tmp/s103.eval.txt" | tr -s ' ' | tr '\n' ' ')"
fi

# Interferers (docs/spyloc.md "Beeps inside an interferer's burst"): babble and music bursts, 6 per
# minute, ~10 dB louder near the tones than spyloc-104's. Bars: LoS found >= 98 % (the issue's; measured
# 99.1 % and 99.1 % on seeds 101 and 105; 96.3 / 92.3 % before the burst handling of 2026-11-29;
# pooled over 101-120 98.3 %, held-out 121-140 98.3 %), p90 <= 0.8 m.
for seed in 101 105; do
  sc="$tmp/i$seed"
  timeout 120 "$locus" simulate spyloc "$sc" --seed "$seed" -q -o bursts=mixed -o bursts_per_minute=6
  status=0
  timeout 120 "$locus" replay "$sc" --config "$src/config/spyloc.yaml" --speed max \
    --events estimate,audio_detection,decay_features -o "$sc.jsonl" 2>"$sc.log" &&
    timeout 60 "$locus" eval "$sc" "$sc.jsonl" --metric spyloc --min-located-fraction 1.0 --max-p90-error-m 0.8 \
      >"$sc.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[interferers, seed $seed] p90 bar missed (exit $status):"; cat "$sc.log" "$sc.eval.txt" 2>/dev/null; fail=1
  else
    score_detection "[interferers, seed $seed]" "$sc" --min-los-found 0.98
  fi
done

# LoS/NLoS classifier: trained as the shipped model is (docs/spyloc.md), tested on the two seeds above.
for seed in 3 4 5 6; do timeout 120 "$locus" simulate spyloc "$tmp/t$seed" --seed "$seed" -q; done
status=0
timeout 300 "$locus" train spyloc "$tmp/t3" "$tmp/t4" "$tmp/t5" "$tmp/t6" -o "$tmp/model.yaml" \
  --test "$tmp/s101" --test "$tmp/s102" >"$tmp/train.txt" 2>"$tmp/train.log" || status=$?
pooled="$(grep '^test pooled:' "$tmp/train.txt" || true)"
if [ "$status" -ne 0 ] || [ -z "$pooled" ]; then
  echo "locus train spyloc failed (exit $status):"; cat "$tmp/train.log" "$tmp/train.txt"; fail=1
else
  # "test pooled: LoS a/b (x %) NLoS c/d (y %) accuracy z %"
  read -r nlos_pct acc_pct < <(sed -E 's/.*NLoS [0-9]+\/[0-9]+ \(([0-9.]+) %\) accuracy ([0-9.]+) %.*/\1 \2/' <<<"$pooled")
  if awk -v a="$acc_pct" -v n="$nlos_pct" 'BEGIN { exit !(a >= 90.0 && n >= 55.0) }'; then
    echo "LoS/NLoS OK: $pooled"
  else
    echo "LoS/NLoS bar missed (accuracy >= 90 %, NLoS >= 55 %): $pooled"; cat "$tmp/train.txt"; fail=1
  fi
fi
exit "$fail"
