#!/usr/bin/env bash
# usage: test_locusd.sh BIN_DIR SOURCE_DIR
set -uo pipefail
bin="$1"; src="$2"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fails=0; passes=0
ok() { echo "ok   - $*"; passes=$((passes + 1)); }
fail() { echo "FAIL - $*"; fails=$((fails + 1)); }

# 0. Every shipped config is valid (board configs are only checked: they name hardware). In a build
#    without some optional backend (LOCUS_WITH_<X>=OFF or its library missing; `locus version` lists
#    them), a config naming one is refused (exit 2) with only "'<name>' is not available: <X> support
#    was not built in (...)" errors at file:line:column, each for a backend this build lacks.
missing=$("$bin/locus" version | awk '/ support was not built in /{print $1}' | paste -sd'|')
not_built_only() {  # FILE: every error line is a not-built-in one for a missing backend, and there is one
  local errors others
  errors=$(grep -cE '^[^:]+:[0-9]+:[0-9]+: ' "$1")
  others=$(grep -E '^[^:]+:[0-9]+:[0-9]+: ' "$1" |
           grep -cvE "^[^:]+:[0-9]+:[0-9]+: [^ ]+: [a-z ]+ '($missing)' is not available: [A-Za-z]+ support was not built in \\(LOCUS_WITH_[A-Z]+=")
  [ "$errors" -gt 0 ] && [ "$others" -eq 0 ]
}
for cfg in "$src"/config/*.yaml; do
  name=$(basename "$cfg")
  # trained model files live beside the configs (locus train ... -o config/<name>-<model>.yaml); they
  # declare a top-level `format:` and are checked by their plugins' own tests
  if grep -qE '^format: ' "$cfg"; then ok "$name is a model file (format: $(sed -n 's/^format: //p' "$cfg")), not a config"; continue; fi
  "$bin/locus" check-config "$cfg" > "$tmp/check.out" 2>&1; s=$?
  if [ $s -eq 0 ]; then
    ok "check-config accepts $name"
  elif [ -n "$missing" ] && [ $s -eq 2 ] && not_built_only "$tmp/check.out"; then
    ok "check-config refuses $name only for backends not built in ($missing)"
  else
    fail "check-config on $name (exit $s)"; cat "$tmp/check.out"
  fi
done

# 1. The demo config is valid and runs to the end at full speed with the expected detections:
#    A has 2 channels, B 1, each hears 5 chirps in 5 s.
sed 's/pace: realtime/pace: max/' "$src/config/demo.yaml" > "$tmp/fast.yaml"
"$bin/locus" check-config "$tmp/fast.yaml" > "$tmp/check.out" 2>&1 && ok "check-config accepts the demo" || { fail "check-config on demo"; cat "$tmp/check.out"; }
"$bin/locusd" --config "$tmp/fast.yaml" > "$tmp/fast.jsonl" 2> "$tmp/fast.err"
status=$?
[ $status -eq 0 ] && ok "locusd exits 0 at the end of a finite stream" || { fail "locusd exit $status"; cat "$tmp/fast.err"; }
n=$(grep -c '"type":"audio_detection"' "$tmp/fast.jsonl")
[ "$n" -eq 15 ] && ok "15 detections (5 chirps x 3 channels)" || fail "expected 15 detections, got $n"
python3 - "$tmp/fast.jsonl" <<'PY' && ok "every line is a JSON object with a type" || fail "malformed JSON lines"
import json, sys
for line in open(sys.argv[1]):
    obj = json.loads(line)
    assert isinstance(obj, dict) and "type" in obj, line
PY

# 2. A bad config: every error reported with file:line:column, exit status 2, nothing run.
cat > "$tmp/bad.yaml" <<'YAML'
sample_rate_hz: 44100
output: {path: "-", events: [estimate, nonsense]}
devices:
  - id: A
    audio:
      source: synth
      params: {channels: 0, treshold: 3}
    detectors:
      - plugin: no_such_plugin
YAML
"$bin/locusd" --config "$tmp/bad.yaml" > "$tmp/bad.out" 2> "$tmp/bad.err"
status=$?
[ $status -eq 2 ] && ok "bad config exits 2" || fail "bad config exit $status"
for pattern in "bad.yaml:2:[0-9]*:.*nonsense" "bad.yaml:7:[0-9]*:.*channels" "bad.yaml:7:[0-9]*:.*treshold" "bad.yaml:9:[0-9]*:.*no_such_plugin"; do
  grep -q "$pattern" "$tmp/bad.err" && ok "error reported: $pattern" || { fail "missing error: $pattern"; cat "$tmp/bad.err"; }
done
[ ! -s "$tmp/bad.out" ] && ok "nothing ran" || fail "output written despite bad config"
"$bin/locus" check-config "$tmp/bad.yaml" > /dev/null 2>&1; s=$?
[ $s -eq 2 ] && ok "locus check-config exits 2 on a bad config" || fail "check-config exit $s"
"$bin/locusd" --config "$tmp/missing.yaml" > /dev/null 2> "$tmp/missing.err"; s=$?
[ $s -eq 2 ] && grep -q "missing.yaml" "$tmp/missing.err" && ok "missing config: exit 2 naming the file" || fail "missing config: exit $s"
"$bin/locusd" --no-such-flag > /dev/null 2>&1; s=$?
[ $s -eq 2 ] && ok "bad usage exits 2" || fail "bad usage exit $s"

# 3. SIGTERM and SIGINT stop a real-time node cleanly: exit 0, every line written is complete.
sed 's/duration_s: 5.0/duration_s: 600.0/' "$src/config/demo.yaml" > "$tmp/long.yaml"
for sig in TERM INT; do
  "$bin/locusd" --config "$tmp/long.yaml" --output "$tmp/long-$sig.jsonl" 2> "$tmp/long-$sig.err" &
  pid=$!
  sleep 3
  kill -$sig $pid
  wait $pid; s=$?
  [ $s -eq 0 ] && ok "SIG$sig: exit 0" || { fail "SIG$sig: exit $s"; cat "$tmp/long-$sig.err"; }
  grep -q "stopping" "$tmp/long-$sig.err" && ok "SIG$sig: logged the stop" || fail "SIG$sig: no stop message"
  n=$(grep -c '"type":"audio_detection"' "$tmp/long-$sig.jsonl")
  [ "$n" -ge 6 ] && ok "SIG$sig: $n detections flushed from ~3 s of audio" || fail "SIG$sig: only $n detections"
  python3 -c "import json,sys; [json.loads(l) for l in open(sys.argv[1])]" "$tmp/long-$sig.jsonl" && ok "SIG$sig: output complete" || fail "SIG$sig: truncated output"
done

# 4. The live map's command line (docs/map.md): bad addresses and parameters exit 2 naming the problem,
#    before anything runs; a node with --http prints the map's URL on stdout and serves it while it runs.
if "$bin/locus" version | grep -q '^  http .*built in'; then
  check_usage() {  # check_usage "what" "expected stderr text" locusd-args...
    local what="$1" want="$2"; shift 2
    "$bin/locusd" "$@" > "$tmp/map.out" 2> "$tmp/map.err"; local s=$?
    if [ $s -eq 2 ] && grep -qF -- "$want" "$tmp/map.err" && [ ! -s "$tmp/map.out" ]; then ok "$what: exit 2, '$want'"
    else fail "$what: exit $s"; cat "$tmp/map.err"; fi
  }
  check_usage "port out of range" "the port must be a number in [0, 65535]" --config "$tmp/fast.yaml" --http 99999
  check_usage "host name instead of an address" "is not an IP address" --config "$tmp/fast.yaml" --http example.org:80
  check_usage "unknown map parameter" "--http-param bogus: unknown key" --config "$tmp/fast.yaml" --http 0 --http-param bogus=1
  check_usage "map parameter out of range" "--http-param max_clients" --config "$tmp/fast.yaml" --http 0 --http-param max_clients=0
  check_usage "unknown event type" "unknown event type 'nope'" --config "$tmp/fast.yaml" --http 0 --http-param events=nope
  check_usage "--hub without --http" "--hub serves a map" --hub
  check_usage "--hub with a config" "--hub runs no pipeline" --hub --http 0 --config "$tmp/fast.yaml"
  check_usage "--http-param without --http" "--http-param needs --http" --config "$tmp/fast.yaml" --http-param linger_s=1
  check_usage "no config" "--config is required" --http 0
  # A real-time node with the map: URL on stdout, the page and the state served while it runs, SIGTERM exits 0.
  "$bin/locusd" --config "$tmp/long.yaml" --output "$tmp/map.jsonl" --http 127.0.0.1:0 > "$tmp/map.out" 2> "$tmp/map.err" &
  pid=$!
  url=""
  for _ in $(seq 100); do url=$(sed -n 's/^map: //p' "$tmp/map.out"); [ -n "$url" ] && break; sleep 0.1; done
  [[ "$url" == http://127.0.0.1:*/ ]] && ok "--http prints the map's URL ($url)" || fail "no map URL on stdout"
  if [ -n "$url" ]; then
    code=$(curl -s -o /dev/null -w '%{http_code}' "$url") && [ "$code" = 200 ] && ok "the page is served" || fail "GET / -> $code"
    sleep 2
    curl -s "${url}api/state" > "$tmp/state.json"
    python3 - "$tmp/state.json" <<'PY' && ok "the state lists the node's devices with their link" || fail "state: $(head -c 300 "$tmp/state.json")"
import json, sys
s = json.load(open(sys.argv[1]))
ids = {d["id"]: d for d in s["devices"]}
assert ids and all(d["link"] == "in-process" for d in ids.values()), ids
assert s["finished"] is False and s["status"].startswith("running"), s["status"]
PY
  fi
  kill -TERM $pid; wait $pid; s=$?
  [ $s -eq 0 ] && ok "--http node: SIGTERM exits 0" || { fail "--http node: exit $s"; cat "$tmp/map.err"; }
else
  "$bin/locusd" --config "$tmp/fast.yaml" --http 0 > /dev/null 2> "$tmp/map.err"; s=$?
  [ $s -eq 2 ] && grep -q "HTTP map support was not built in (LOCUS_WITH_HTTP=" "$tmp/map.err" && ok "--http without the map: exit 2, not built in" || fail "--http without the map: exit $s"
fi

echo "$passes passed, $fails failed"
[ $fails -eq 0 ]
