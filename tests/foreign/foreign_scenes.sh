#!/usr/bin/env bash
# Replays every foreign scene whose family has a localizer config (config/<family>.yaml) and bars
# (tests/foreign/bars/<family>.args), scores it with `locus eval --metric <family>` and fails when a bar
# is missed (eval exits 4). The family is the scene's `environment.family`, never guessed from names.
#   foreign_scenes.sh LOCUS_BIN SOURCE_DIR SCENES_DIR
set -euo pipefail
locus="$1"; src="$2"; scenes="$3"
source "$(dirname "$0")/foreign_common.sh"
require_scenes "$scenes"
tmp="$(mktemp -d /tmp/locus-foreign.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
fail=0; ran=0
for sc in "$scenes"/*/; do
  sc="${sc%/}"; name="$(basename "$sc")"
  [ -f "$sc/scene.yaml" ] || continue
  family="$(scene_family "$sc")"
  if [ -z "$family" ]; then echo "[$name] no environment.family in scene.yaml: not scored"; continue; fi
  cfg="$src/config/$family.yaml"; bars="$src/tests/foreign/bars/$family.args"
  if [ ! -f "$cfg" ] || [ ! -f "$bars" ]; then echo "[$name] family '$family' has no localizer yet: not scored"; continue; fi
  ran=$((ran + 1))
  if ! timeout 300 "$locus" replay "$sc" --config "$cfg" --speed max -o "$tmp/$name.jsonl" 2>"$tmp/$name.log"; then
    echo "[$name] locus replay failed:"; tail -20 "$tmp/$name.log"; fail=1; continue
  fi
  read_bars "$bars"
  status=0
  timeout 120 "$locus" eval "$sc" "$tmp/$name.jsonl" --metric "$family" "${args[@]}" >"$tmp/$name.eval.txt" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    echo "[$name] bars missed (locus eval exit $status):"; cat "$tmp/$name.eval.txt"; fail=1
  else
    echo "[$name] OK ($family): $(grep -E 'PASS' "$tmp/$name.eval.txt" | tr -s ' ' | tr '\n' ';')"
  fi
done
[ "$ran" -gt 0 ] || echo "no foreign scene has a localizer yet"
exit "$fail"
