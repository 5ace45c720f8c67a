#!/usr/bin/env bash
# Detection on every foreign Montage scene (environment.family: montage): replays it with
# config/montage-detect.yaml and scores the other users' arrivals with
# tools/scripts/check_montage_arrivals.py against bars/montage-detection.args (its --min/--max options).
# These bars keep what the detector reaches today; the issue-15 bar (95 % within 2 samples, none > 10
# samples off, for arrivals within 12 m) is NOT met yet: see docs/montage.md.
#   montage_detection.sh LOCUS_BIN SOURCE_DIR SCENES_DIR
set -euo pipefail
locus="$1"; src="$2"; scenes="$3"
source "$(dirname "$0")/foreign_common.sh"
require_scenes "$scenes"
tmp="$(mktemp -d /tmp/locus-montage-det.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
read_bars "$src/tests/foreign/bars/montage-detection.args"
fail=0; ran=0
for sc in "$scenes"/*/; do
  sc="${sc%/}"; name="$(basename "$sc")"
  [ -f "$sc/scene.yaml" ] || continue
  family="$(scene_family "$sc")"
  [ "$family" = "montage" ] || continue
  ran=$((ran + 1))
  if ! timeout 300 "$locus" replay "$sc" --config "$src/config/montage-detect.yaml" --speed max -o "$tmp/$name.jsonl" 2>"$tmp/$name.log"; then
    echo "[$name] locus replay failed:"; tail -20 "$tmp/$name.log"; fail=1; continue
  fi
  if /usr/bin/python3 "$src/tools/scripts/check_montage_arrivals.py" "$sc" "$tmp/$name.jsonl" "${args[@]}" >"$tmp/$name.txt" 2>&1; then
    echo "[$name] OK: $(grep 'the bar' "$tmp/$name.txt")"
  else
    echo "[$name] detection bars missed:"; cat "$tmp/$name.txt"; fail=1
  fi
done
[ "$ran" -gt 0 ] || { echo "no foreign Montage scene"; exit 77; }
exit "$fail"
