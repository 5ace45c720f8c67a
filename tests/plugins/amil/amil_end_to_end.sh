#!/usr/bin/env bash
# AMIL end to end through the real binaries on one seed: `locus simulate amil` (the field test) ->
# `locus replay --config config/amil.yaml` (13 nodes over the in-process link: chirp detectors, the
# amil localizer's listener and player roles) -> `locus eval --metric amil` with bars: every listener
# located, mean direction error within the paper's headline with margin. The multi-seed accuracy
# bars are the scenario test (tests/scenario/amil).
#   amil_end_to_end.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
tmp="$(mktemp -d /tmp/locus-amil-e2e.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT

timeout 120 "$locus" simulate amil "$tmp/scene" --seed 3 >/dev/null
timeout 120 "$locus" replay "$tmp/scene" --config "$src/config/amil.yaml" --speed max -o "$tmp/est.jsonl" \
  --log-level info 2>"$tmp/replay.log" || { cat "$tmp/replay.log"; exit 1; }
n=$(grep -c '"type":"estimate"' "$tmp/est.jsonl" || true)
if [ "$n" -ne 12 ]; then
  echo "expected 12 estimates (one per listener), got $n"; cat "$tmp/replay.log"; cat "$tmp/est.jsonl"; exit 1
fi
grep -q '"frame":"player_start@' "$tmp/est.jsonl" || { echo "estimates are not in the player_start@T frame"; exit 1; }
status=0
timeout 60 "$locus" eval "$tmp/scene" "$tmp/est.jsonl" --metric amil \
  --min-located-fraction 1.0 --max-unflagged-direction-error-deg 3 --max-unknown-targets 0 || status=$?
if [ "$status" -ne 0 ]; then
  echo "locus eval: bars missed (exit $status)"; cat "$tmp/replay.log"; exit 1
fi
echo "amil end to end: OK"
