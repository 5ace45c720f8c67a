#!/usr/bin/env bash
# tests/fuzz/seed_corpus.sh TARGET DIR BIN: writes the seed inputs of fuzz target TARGET into DIR, from
# the repository's own files (configs, the committed seeds here), the foreign scenes when ../shared is
# present, WAV files made with sox, and for `link` the plugins' own encoders (BIN/locus_fuzz_seeds).
set -euo pipefail
target="$1" out="$2" bin="$3"
root="$(cd "$(dirname "$0")/../.." && pwd)"
here="$root/tests/fuzz"
scenes="$root/../shared/scenes"
mkdir -p "$out"
case "$target" in
  config)
    cp "$root"/config/*.yaml "$out"/
    find "$root/examples" -name '*.yaml' -exec cp {} "$out"/ \; 2>/dev/null || true ;;
  scene_yaml)
    cp "$here/seeds/scene.yaml" "$out/seed.yaml"
    for s in "$scenes"/*/scene.yaml; do [ -f "$s" ] && cp "$s" "$out/$(basename "$(dirname "$s")").yaml"; done ;;
  imu_csv|ble_csv|sync_csv)
    name="${target%_csv}.csv"
    printf 't,ax,ay,az,gx,gy,gz\n0.0,0,0,9.81,0,0,0\n0.005,0.1,0,9.8,0.01,0,0\n' > "$out/imu-min.csv"
    printf 't,address,rssi,tx_power,channel\n0.1,AA:BB:CC:DD:EE:01,-61,-59,37\n0.2,AA:BB:CC:DD:EE:01,-63,,\n' > "$out/ble-min.csv"
    printf 't,source\n0.5,B1\n1.5,B2\n' > "$out/sync-min.csv"
    find "$scenes" -name "$name" 2>/dev/null | while read -r f; do
      head -40 "$f" > "$out/$(basename "$(dirname "$(dirname "$f")")")-$(basename "$(dirname "$f")").csv"
    done ;;
  truth_csv)
    printf 't,id,x,y,z,qw,qx,qy,qz\n0.0,A,1,2,0.8,1,0,0,0\n0.1,A,1.01,2,0.8,1,0,0,0\n' > "$out/truth-min.csv"
    for f in "$scenes"/*/truth.csv; do [ -f "$f" ] && head -40 "$f" > "$out/$(basename "$(dirname "$f")").csv"; done ;;
  wav)
    sox -n -r 44100 -c 1 -b 16 "$out/mono16.wav" synth 0.01 sine 1000
    sox -n -r 48000 -c 2 -b 24 "$out/stereo24.wav" synth 0.01 sine 1000
    sox -n -r 44100 -c 1 -e floating-point -b 32 "$out/float32.wav" synth 0.01 sine 1000
    sox -n -r 44100 -c 4 -b 32 "$out/quad32.wav" synth 0.005 sine 1000
    head -c 300 "$out/mono16.wav" > "$out/truncated.wav" ;;
  estimates)
    cp "$here/seeds/estimates.jsonl" "$out/" ;;
  link)
    "$bin/locus_fuzz_seeds" "$out" ;;
  model)
    cp "$root"/config/*-envaware.yaml "$root"/config/spyloc-los.yaml "$out"/ ;;
  map_http)
    # requests as a browser and a curious client send them to the live map (tools/map, docs/map.md)
    printf 'GET / HTTP/1.1\r\nHost: 127.0.0.1:8080\r\nAccept: text/html\r\n\r\n' > "$out/index"
    printf 'GET /api/state HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n' > "$out/state"
    printf 'GET /events HTTP/1.1\r\nHost: [::1]:8080\r\nAccept: text/event-stream\r\nLast-Event-ID: 42\r\n\r\n' > "$out/events"
    printf 'GET /map.js HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\nGET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n' > "$out/pipelined"
    printf 'POST /api/state HTTP/1.1\r\nHost: evil.example\r\nContent-Length: 5\r\n\r\nhello' > "$out/post-foreign-host"
    printf 'GET /nope?x=%%zz HTTP/1.0\r\n\r\n' > "$out/notfound" ;;
  *)
    echo "seed_corpus.sh: unknown target '$target'" >&2; exit 2 ;;
esac
