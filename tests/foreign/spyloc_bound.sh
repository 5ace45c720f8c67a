#!/usr/bin/env bash
# What the foreign spyloc-104's onsets hold (tools/scripts/spyloc_bound.py; docs/spyloc.md "the carrier
# cycle by the known phase"): an ideal receiver picks the first path's carrier cycle for >= 90 % of
# its LoS beeps (96 % measured on 2026-12-08), so issue 16's 90 % bar is within the information there,
# while our simulator's onsets hold ~64 %.
#   spyloc_bound.sh SOURCE_DIR SCENES_DIR
set -euo pipefail
src="$1"; scenes="$2"
source "$(dirname "$0")/foreign_common.sh"
require_scenes "$scenes"
if [ ! -f "$scenes/spyloc-104/scene.yaml" ]; then
  echo "no spyloc-104 in $scenes: skipped"; exit 77
fi
/usr/bin/python3 "$src/tools/scripts/spyloc_bound.py" "$scenes/spyloc-104" --min-bound 0.9
