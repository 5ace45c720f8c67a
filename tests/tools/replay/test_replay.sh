#!/usr/bin/env bash
# `locus replay` as a user runs it, on a two-device scene written by make_scene.py (A emits chirps, B
# hears them 5 ms later; a third device records nothing):
#   1. onset on every device (config/replay-onset.yaml, template "*"): both devices' detections;
#   2. the linktest localizer (a .so fixture) publishes A's detections over the shared link and B pairs
#      them with its own: 3 estimates at ~1.715 m, and a summary that proves A's finish() message
#      reached B before B finished (the shutdown phases), that B's inputs_ended() message reached A
#      before A finished, and that B saw its geometry (2 mics);
#   3. --speed realtime takes about real time;
#   4. a bad config and a bad scene exit 2 with file:line:column; a malformed imu.csv row exits 1,
#      naming the file:line:column, after flushing the estimates.
# Usage: test_replay.sh LOCUS_BIN SOURCE_DIR PLUGIN_DIR
set -u
LOCUS=$1
SRC=$2
PLUGINS=$3
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fails=0
check() {  # check DESCRIPTION COMMAND...
  local what=$1; shift
  if "$@"; then echo "ok   $what"; else echo "FAIL $what"; fails=$((fails + 1)); fi
}

python3 "$SRC/tests/tools/replay/make_scene.py" "$TMP/scene" || { echo "cannot write the scene"; exit 1; }

# 1. onset everywhere through the template.
"$LOCUS" replay "$TMP/scene" --config "$SRC/config/replay-onset.yaml" --events audio_detection \
  --out "$TMP/onset.jsonl" 2> "$TMP/onset.err"
check "onset replay exits 0" test $? -eq 0
nA=$(grep -c '"device":"A"' "$TMP/onset.jsonl")
nB=$(grep -c '"device":"B"' "$TMP/onset.jsonl")
check "A: 3 detections (got $nA)" test "$nA" -eq 3
check "B: 6 detections, 2 mics (got $nB)" test "$nB" -eq 6
check "detector instance name" grep -q '"detector":"onset"' "$TMP/onset.jsonl"
check "only audio_detection lines" bash -c "! grep -v '\"type\":\"audio_detection\"' '$TMP/onset.jsonl'"

# 2. linktest over the shared link.
cat > "$TMP/link.yaml" <<YAML
plugin_dirs: ["$PLUGINS"]
log_level: info
devices:
  - id: "*"
    detectors:
      - plugin: onset
        params: {threshold_db: 15}
  - id: B
    audio: {source: synth, params: {channels: 1}}
    imu: {source: scene_imu, params: {scene: /nonexistent, device: B}}
    detectors:
      - plugin: onset
        params: {threshold_db: 15}
localizers:
  - plugin: linktest
YAML
"$LOCUS" replay "$TMP/scene" --config "$TMP/link.yaml" --out "$TMP/link.jsonl" --events estimate,radio_sync \
  2> "$TMP/link.err"
status=$?
check "linktest replay exits 0 (got $status)" test $status -eq 0
[ $status -eq 0 ] || cat "$TMP/link.err"
python3 - "$TMP/link.jsonl" <<'PY'
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
est = [l for l in lines if l["type"] == "estimate"]
pairs = [e for e in est if e["target"] == "A"]
summary = [e for e in est if e["target"] == "summary"]
syncs = [l for l in lines if l["type"] == "radio_sync"]
ok = True
def expect(cond, what):
    global ok
    print(("ok   " if cond else "FAIL ") + what)
    ok = ok and cond
expect(len(pairs) == 3, f"3 paired estimates on B (got {len(pairs)})")
for p in pairs:
    expect(abs(p["distance_m"] - 1.715) < 0.05, f"range {p['distance_m']:.4f} m ~ 1.715 m")
    expect(p["reference"] == "B", "estimate made on node B")
expect(len(summary) == 1, "one summary")
if summary:
    s = summary[0]["position_m"]
    expect(s == [3, 3, 1], f"summary remote/local/done = {s} (A's finish() reached B before B finished)")
    expect(summary[0]["std_m"] == 2, f"B's geometry has 2 mics (got {summary[0]['std_m']})")
ended = [e for e in est if e["target"] == "ended"]
expect(len(ended) == 1 and ended[0]["reference"] == "A" and ended[0]["distance_m"] == 1,
       f"A, finishing first, had B's inputs_ended() message (the phase before finish): {ended}")
geo = [e for e in est if e["target"] == "geometry"]
expect(len(geo) == 1 and geo[0]["reference"] == "A" and geo[0]["confidence"] == 1 and geo[0]["std_m"] == 1,
       f"A's geometry reached its localizer (speaker, emits, 1 mic): {geo}")
expect(len(syncs) == 3 and all(l["device"] == "B" for l in syncs), f"3 radio_sync lines from B (got {len(syncs)})")
sys.exit(0 if ok else 1)
PY
check "linktest output" test $? -eq 0
check "the scene's streams replace the config's sources (logged)" \
  grep -q "device B: the scene's audio replaces audio source 'synth'" "$TMP/link.err"

# 3. realtime pace (3.2 s of audio).
start=$(date +%s.%N)
"$LOCUS" replay "$TMP/scene" --config "$SRC/config/replay-onset.yaml" --speed realtime --out "$TMP/rt.jsonl" \
  2> "$TMP/rt.err"
status=$?
end=$(date +%s.%N)
wall=$(python3 -c "print(f'{$end - $start:.2f}')")
check "realtime exits 0" test $status -eq 0
check "realtime takes about 3.2 s (took $wall s)" python3 -c "import sys; sys.exit(0 if 3.1 <= $wall <= 6.0 else 1)"

# 4. errors.
printf 'devices:\n  - id: "*"\n    detectors: [{plugin: onset, params: {treshold_db: 3}}]\n' > "$TMP/bad.yaml"
"$LOCUS" replay "$TMP/scene" --config "$TMP/bad.yaml" > /dev/null 2> "$TMP/bad.err"
check "bad config exits 2" test $? -eq 2
check "bad config names file:line:column" grep -q "bad.yaml:3:42: devices\[0\].detectors\[0\].params.treshold_db" "$TMP/bad.err"
"$LOCUS" replay "$TMP/nothing" --config "$SRC/config/replay-onset.yaml" > /dev/null 2> "$TMP/noscene.err"
check "missing scene exits 2" test $? -eq 2
check "missing scene is named" grep -q "$TMP/nothing" "$TMP/noscene.err"
python3 "$SRC/tests/tools/replay/make_scene.py" "$TMP/badimu" --bad-imu-line 151
"$LOCUS" replay "$TMP/badimu" --config "$TMP/link.yaml" --out "$TMP/badimu.jsonl" --events estimate,imu_sample \
  2> "$TMP/badimu.err"
check "malformed imu.csv exits 1" test $? -eq 1
check "the error names imu.csv:151:10" grep -q "imu.csv:151:10" "$TMP/badimu.err"
nimu=$(grep -c '"type":"imu_sample"' "$TMP/badimu.jsonl")
check "the 149 rows before it were delivered (got $nimu)" test "$nimu" -eq 149
check "estimates were still flushed" grep -q '"target":"summary"' "$TMP/badimu.jsonl"

if [ $fails -ne 0 ]; then
  echo "$fails check(s) failed"; echo "--- stderr of the linktest run"; cat "$TMP/link.err"; exit 1
fi
echo "all replay checks passed"
