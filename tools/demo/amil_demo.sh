#!/usr/bin/env bash
# The AMIL demo (./run demo): simulate the paper's field test (a player drawing the triangle on a
# table, 12 listeners on the 1.22 m grid), replay it through the daemon in real time
# (`locusd --scene ... --speed realtime`, one node per device over one in-process link, as boards over
# MQTT), score it (`locus eval --metric amil`), print the listeners' table (true vs estimated direction
# and distance) and draw the map (PNG) from the files Locus wrote.
#
#   tools/demo/amil_demo.sh BIN_DIR [--out DIR] [--seed N] [--difficulty easy|normal|hard] [--gestures 1|3] [--speed realtime|max]
#                           [--map [HOST:]PORT] [--map-linger S]
#
# The live map: when locusd was built with it (LOCUS_WITH_HTTP), the replay also serves the map
# (locusd --http, docs/map.md) on 127.0.0.1 and a free port (--map sets one; --map off turns it off),
# and the demo prints its URL while the replay runs; --map-linger S keeps it open S seconds after the
# replay (Ctrl-C ends it early).
#
# Files in DIR (default: a fresh temporary directory, printed): scene/ (the simulated scene),
# amil.yaml (config/amil.yaml plus the player's track file), estimates.jsonl (what locusd published),
# track.csv (the player's tracked gesture and beep positions), eval.json (locus eval), amil_map.png.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${1:?usage: amil_demo.sh BIN_DIR [--out DIR] [--seed N] [--difficulty D] [--gestures 1|3] [--speed S]}"
shift
out="" seed=1 difficulty=normal gestures=1 speed=realtime map="127.0.0.1:0" map_linger=0
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --difficulty) difficulty="$2"; shift 2 ;;
    --gestures) gestures="$2"; shift 2 ;;
    --speed) speed="$2"; shift 2 ;;
    --map) map="$2"; shift 2 ;;
    --map-linger) map_linger="$2"; shift 2 ;;
    *) echo "amil_demo.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
done
for tool in locus locusd; do
  [ -x "$bin/$tool" ] || { echo "amil_demo.sh: $bin/$tool not found (build first: ./run build)" >&2; exit 2; }
done
if [ -z "$out" ]; then out="$(mktemp -d /tmp/locus-amil-demo.XXXXXX)"; fi
mkdir -p "$out"
rm -rf "$out/scene"

start_ns=$(date +%s%N)
echo "== 1/4 simulate: AMIL field test (seed $seed, $difficulty, $gestures gesture(s)) -> $out/scene"
"$bin/locus" simulate amil "$out/scene" --seed "$seed" --difficulty "$difficulty" -o "gestures=$gestures" >/dev/null

# The demo's config: config/amil.yaml, plus the player's track file for the map.
sed "s|^\(\s*\)method: robust.*|&\n\1track_csv: \"$out/track.csv\"|" "$root/config/amil.yaml" > "$out/amil.yaml"
grep -q track_csv "$out/amil.yaml" || { echo "amil_demo.sh: could not add track_csv to the config" >&2; exit 1; }

map_args=()
if [ "$map" != off ] && "$bin/locus" version | grep -q '^  http .*built in'; then
  map_args=(--http "$map" --http-param "linger_s=$map_linger" --http-param "title=AMIL demo (seed $seed)")
fi
echo "== 2/4 locusd --config config/amil.yaml --scene $out/scene --speed $speed ${map_args[*]:0:2}"
# locusd prints "map: URL" on stdout as soon as the map serves (the estimates go to the file).
"$bin/locusd" --config "$out/amil.yaml" --scene "$out/scene" --speed "$speed" -o "$out/estimates.jsonl" "${map_args[@]}" \
  | sed -u 's|^map: |   live map (open it now): |'

echo "== 3/4 locus eval --metric amil"
status=0
"$bin/locus" eval "$out/scene" "$out/estimates.jsonl" --metric amil --json --json-output "$out/eval.json" >/dev/null || status=$?
if [ "$status" -ne 0 ] && [ "$status" -ne 4 ]; then
  echo "amil_demo.sh: locus eval failed (exit $status)" >&2
  exit "$status"
fi

echo "== 4/4 table and map"
/usr/bin/python3 "$here/amil_report.py" "$out/scene" "$out/estimates.jsonl" "$out/eval.json" "$out/track.csv" "$out/amil_map.png"
end_ns=$(date +%s%N)
ms=$(( (end_ns - start_ns) / 1000000 ))
printf 'demo finished in %d.%01d s; files in %s\n' $((ms / 1000)) $(((ms % 1000) / 100)) "$out"
