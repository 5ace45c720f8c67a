#!/usr/bin/env bash
# LocBLE clustering must not fuse distinct tags (docs/locble.md, "Clustering"). `locus simulate locble
# -o clustered=0` on seeds 1-3 puts 3 tags 6-19 m apart; replayed with the shipped config
# (clustering on), no two tags may come out at the same final position (fused: Algo. 2 gives every
# member of a cluster the same weighted mean). The same scenes replayed with the paper's DTW voting
# alone (cluster_min_bayes_factor 0, cluster_min_speed_mps 0: the code before the fix) must fuse at
# least one pair — otherwise this test no longer tests anything and says so.
#   locble_clustering.sh LOCUS_BIN SOURCE_DIR
set -euo pipefail
locus="$1"
src="$2"
tmp="$(mktemp -d /tmp/locus-locble-clustering.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
sed 's/^\( *\)std_scale:\(.*\)$/\1std_scale:\2\n\1cluster_min_bayes_factor: 0\n\1cluster_min_speed_mps: 0/' \
  "$src/config/locble.yaml" >"$tmp/dtw_alone.yaml"
grep -q 'cluster_min_bayes_factor: 0' "$tmp/dtw_alone.yaml" || { echo "could not derive the DTW-alone config"; exit 1; }

fused_pairs() {  # scene estimates.jsonl -> prints "tagA tagB truth_distance" for every fused pair > 2 m apart
  python3 - "$1" "$2" <<'PY'
import csv, json, math, sys
import yaml
scene, est = sys.argv[1], sys.argv[2]
sc = yaml.safe_load(open(scene + '/scene.yaml'))
addr = {m['address'].upper(): e['id'] for e in sc['emitters'] for m in e['emits'] if m['type'] == 'ble'}
pos = {}
for r in csv.DictReader(open(scene + '/truth.csv')):
    if r['id'] in addr.values():
        pos[r['id']] = (float(r['x']), float(r['y']))
last = {}
for line in open(est):
    d = json.loads(line)
    if d.get('type') == 'estimate' and d['target'].upper() in addr:
        last[addr[d['target'].upper()]] = d['position_m']
if len(last) != len(addr):
    sys.exit(f"{est}: {len(last)} of {len(addr)} tags located")
ids = sorted(last)
for i, a in enumerate(ids):
    for b in ids[i + 1:]:
        dt = math.dist(pos[a], pos[b])
        de = math.dist(last[a][:2], last[b][:2])
        if dt > 2.0 and de < 0.01:
            print(f"{a} {b} {dt:.1f}")
PY
}

fail=0 old_fused=0
for seed in 1 2 3; do
  sc="$tmp/seed$seed"
  timeout 60 "$locus" simulate locble "$sc" --seed "$seed" -q -o clustered=0
  for cfg in shipped dtw_alone; do
    conf="$src/config/locble.yaml"
    [ "$cfg" = dtw_alone ] && conf="$tmp/dtw_alone.yaml"
    timeout 60 "$locus" replay "$sc" --config "$conf" --speed max -o "$sc.$cfg.jsonl" 2>"$sc.$cfg.log" ||
      { echo "[seed $seed, $cfg] replay failed:"; cat "$sc.$cfg.log"; fail=1; continue; }
    pairs="$(fused_pairs "$sc" "$sc.$cfg.jsonl")" || { echo "[seed $seed, $cfg] $pairs"; fail=1; continue; }
    if [ "$cfg" = shipped ]; then
      if [ -n "$pairs" ]; then echo "[seed $seed] FAIL: distinct tags fused (tag tag true-distance-m): $pairs"; fail=1;
      else echo "[seed $seed] OK: no distinct tags fused"; fi
    else
      [ -n "$pairs" ] && old_fused=$((old_fused + 1))
      echo "[seed $seed] DTW voting alone fuses: ${pairs:-nothing}" | tr '\n' ' '; echo
    fi
  done
done
if [ "$old_fused" -eq 0 ]; then
  echo "FAIL: the paper's DTW voting alone fused no distinct tags on these seeds: this test no longer tells the gate works"
  fail=1
fi
exit "$fail"
