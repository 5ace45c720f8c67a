#!/usr/bin/python3
"""Hardware-in-the-loop run of a localizer (`./run hil NAME`, docs/room.md): live nodes in a virtual room.

`locble` is hil_locble.py (BlueZ through dbusmock and a fake IIO IMU, played by `locus feed`), `tum`
hil_tum.py (TUM's live roles: link sync, election, emissions); `spyloc` and `montage` are hil_sync.py
(emitters scheduled from a radio sync over MQTT); the process runner and the other pieces the runs share
are hil_common.py. This file: the command line and `amil`.

For `amil`: simulates the layout (`locus simulate amil`: the player's triangle gesture and 12 listeners;
the live protocol: the player pauses 0.8-1.0 s at each corner, long enough for its beep), then starts
  - jackd (dummy driver, its own server name, synchronous, one period of --period frames, real-time
    process threads unless --realtime 0: other work on the machine must not make the room miss a cycle),
  - mosquitto (its own loopback port),
  - `locus room` (the layout's acoustics between the nodes' speakers and microphones, a fake IIO IMU
    per device fed from the trajectories, the truth),
  - one `locusd` per device, each a board: JACK capture and playback on the room's ports, the `iio` IMU
    on its fake tree, the MQTT link, the `chirp` detector and the `amil` localizer (the player: the
    layout's emitting device; it serves the live map, whose URL is printed while it runs),
runs one gesture live, stops every node (their logs give each one's audio origin, which the room needs
for the truth clocks), stops the room (it writes the run's truth as a scene), and prints the same
listener table and summary line as `./run demo` (`locus eval --metric amil` + tools/demo/amil_report.py).

It measures, in the same run: the latency from the last beep reaching the last listener (the room's
truth: its emission onset + the path, on CLOCK_MONOTONIC) to each estimate arriving at an SSE client of
the live map (median, max); each process's CPU (% of one core over the gesture) and peak RSS; xruns.
`--json FILE` writes them. Every process is started in its own process group and stopped (SIGTERM,
then SIGKILL) on every exit path: success, failure, Ctrl-C, SIGTERM.

    tools/hil/hil.py amil --bin build/bin [--listeners 12] [--seed 1] [--period 1024] [--out DIR] [--json FILE]
"""
import argparse
import csv
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "tools", "scripts"))
sys.path.insert(0, HERE)
from hil_common import (Failure, Run, check_alive, read_jsonl, rss_mb, sample_peaks, start_map_node,  # noqa: E402
                        start_room, stop_nodes, stop_room, wait_for)
from map_measure import cpu_s  # noqa: E402
import hil_locble  # noqa: E402
import hil_sync  # noqa: E402
import hil_tum  # noqa: E402

import yaml  # noqa: E402

# localizers with a live HIL run (locble: hil_locble.py, tum: hil_tum.py; spyloc, montage: hil_sync.py)
LIVE = {"amil", "locble", "tum", "spyloc", "montage"}


def layout_for(args, bin_dir, out):
    """The layout scene: locus simulate amil (live pauses), pruned to --listeners listeners."""
    layout = os.path.join(out, "layout")
    cmd = [os.path.join(bin_dir, "locus"), "simulate", "amil", layout, "--seed", str(args.seed), "--difficulty",
           args.difficulty, "-o", f"gestures={args.gestures}", "-o", "pause_min_s=0.8", "-o", "pause_max_s=1.0", "-q"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise Failure(f"{' '.join(cmd)} failed: {r.stderr}")
    with open(os.path.join(layout, "scene.yaml")) as f:
        scene = yaml.safe_load(f)
    devices = scene["devices"]
    player = next(d["id"] for d in devices if d.get("emits"))
    listeners = [d["id"] for d in devices if d["id"] != player]
    if args.listeners < len(listeners):
        # an even spread over the grid (near and far, left and right)
        n = args.listeners
        keep = {listeners[round(i * (len(listeners) - 1) / max(1, n - 1))] for i in range(n)}
        scene["devices"] = [d for d in devices if d["id"] == player or d["id"] in keep]
        for key in ("clocks",):
            scene["truth"][key] = {k: v for k, v in scene["truth"][key].items() if k == player or k in keep}
        with open(os.path.join(layout, "scene.yaml"), "w") as f:
            yaml.safe_dump(scene, f, sort_keys=False)
        with open(os.path.join(layout, "truth.csv")) as f:
            rows = list(csv.reader(f))
        with open(os.path.join(layout, "truth.csv"), "w", newline="") as f:
            csv.writer(f).writerows([rows[0]] + [r for r in rows[1:] if r[1] == player or r[1] in keep])
        listeners = [i for i in listeners if i in keep]
    return layout, scene, player, listeners


def node_config(args, dev, player, server, mqtt_port, room_out, out_jsonl, track_csv):
    geometry = {"mics_m": [c for m in dev["mics"] for c in m]}
    if dev.get("speaker"):
        geometry["speaker_m"] = list(dev["speaker"])
    # one triangle = 4 strokes: base middle -> left corner -> top -> right corner -> base middle
    amil = {"player": player, "method": "robust", "session_movements": 4 * args.gestures}
    if dev["id"] == player:
        amil["track_csv"] = track_csv
    ident = dev["id"]
    return {
        "log_level": "info",
        "sample_rate_hz": 44100,
        "output": {"path": out_jsonl, "events": ["estimate", "audio_detection"] + (["imu_sample"] if args.imu_events else [])},
        "link": {"type": "mqtt", "params": {"host": "127.0.0.1", "port": mqtt_port, "connect_timeout_s": 10}},
        "devices": [{
            "id": ident,
            "audio": {"source": "jack", "params": {"server": server, "client_name": ident, "channels": len(dev["mics"]),
                                                    "connect": f"^room:{ident}_mic_[0-9]+$"}},
            "playback": {"sink": "jack", "params": {"server": server, "client_name": ident, "channels": 1,
                                                     "connect": f"^room:{ident}_spk$"}},
            "imu": {"source": "iio", "params": {"root": os.path.join(room_out, "iio", ident), "device": "lsm6dsl",
                                                "mode": "buffered"}},
            "geometry": geometry,
            # Live latency (docs/detectors.md): windows overlapped to a 10 ms hop (the default fft_size,
            # 16384: its noise median spans 0.32 s, as in replay), and an event reported 3 ms after its
            # strongest lag instead of a template length (AMIL's beeps never overlap): a detection follows
            # the end of its beep by ~10 ms plus the JACK period, instead of up to a 0.32 s hop plus 50 ms.
            "detectors": [{"plugin": "chirp", "params": {"f0_hz": 18000, "f1_hz": 22000, "duration_s": 0.05,
                                                          "fade_s": 0.005, "hop_s": 0.01, "settle_s": 0.003}}],
        }],
        "localizers": [{"plugin": "amil", "params": amil}],
    }


def hil_amil(args, bin_dir, out, run):
    locus, locusd = os.path.join(bin_dir, "locus"), os.path.join(bin_dir, "locusd")
    for d in ("logs", "nodes"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    print(f"== 1/5 layout: locus simulate amil (seed {args.seed}, {args.difficulty}, live pauses 0.8-1.0 s), "
          f"player + {args.listeners} listeners -> {out}/layout", flush=True)
    layout, scene, player, listeners = layout_for(args, bin_dir, out)

    print(f"== 2/5 jackd -d dummy -p {args.period}; mosquitto; locus room", flush=True)
    rm = start_room(run, out, os.path.join(bin_dir, "locus"), layout, args)
    server, env, jackd, mqtt_port, broker, room = rm.server, rm.env, rm.jackd, rm.mqtt_port, rm.broker, rm.proc
    room_out, origins_csv, room_log, room_said = rm.out, rm.origins_csv, rm.log, rm.said

    print(f"== 3/5 {1 + len(listeners)} locusd nodes (JACK capture/playback, IIO IMU, MQTT link, amil), one gesture",
          flush=True)
    devs = {d["id"]: d for d in scene["devices"]}
    nodes = {}
    map_url = None
    events = []  # (arrival monotonic ns, message) from the map's SSE stream
    stop_sse = threading.Event()
    def connected(ident):
        path = os.path.join(out, "logs", f"node-{ident}.log")
        with open(path) as f:
            return f"connected room:{ident}_mic_1 -> {ident}:in_1" in f.read()

    for ident in listeners + [player]:  # the player last: its listeners hear its first beep
        if ident == player:  # ... once every listener captures (the player beeps as soon as it rests)
            wait_for(lambda: all(connected(i) for i in listeners), 90, "every listener to capture from the room",
                     [("room", room)] + [("locusd " + k, v) for k, v in nodes.items()])
        cfg = node_config(args, devs[ident], player, server, mqtt_port, room_out,
                          os.path.join(out, "nodes", ident + ".jsonl"), os.path.join(out, "track.csv"))
        path = os.path.join(out, "nodes", ident + ".yaml")
        with open(path, "w") as f:
            yaml.safe_dump(cfg, f, sort_keys=False)
        cmd = [locusd, "--config", path]
        if ident == player and args.map != "off":
            p, map_url = start_map_node(run, "node-" + ident, cmd, env, args.map, f"HIL: {args.name} live (seed {args.seed})",
                                        events, stop_sse, f"{out}/logs/node-{ident}.log")
        else:
            p = run.start("node-" + ident, cmd, env=env)
        nodes[ident] = p

    alive = [("room", room), ("jackd", jackd)] + [("locusd " + k, v) for k, v in nodes.items()]
    wait_for(lambda: room_said(r"layout starts at room time"), 90, "every node to connect to the room", alive)
    m = room_said(r"layout starts at room time ([0-9.eE+-]+) s \(in [0-9.]+ s\) and ends ([0-9.eE+-]+) s later")
    layout_s = float(m.group(2))
    # CPU/RSS: from the layout's start to its end (the gesture runs in it)
    pids = {"jackd": jackd.pid, "mosquitto": broker.pid, "room": room.pid}
    pids.update({"locusd " + k: v.pid for k, v in nodes.items()})
    t0 = time.monotonic()
    cpu0 = {k: cpu_s(p) for k, p in pids.items()}
    peak_rss = {k: 0.0 for k in pids}
    peak_shm = {k: 0.0 for k in pids}
    est_path = os.path.join(out, "nodes", player + ".jsonl")

    def estimates():
        return [e for e in read_jsonl(est_path) if e.get("type") == "estimate"]
    deadline = time.monotonic() + layout_s + 2.0 + args.wait
    while time.monotonic() < deadline:
        sample_peaks(pids, peak_rss, peak_shm)
        check_alive(alive, "the gesture", out)
        if len({e["target"] for e in estimates()}) >= len(listeners) and time.monotonic() > t0 + layout_s:
            break
        time.sleep(0.1)
    wall = time.monotonic() - t0
    cpu = {k: 100.0 * (cpu_s(p) - cpu0[k]) / wall for k, p in pids.items()}

    # The estimates are in the player's output file; give the map's SSE client (the latency clock) a
    # moment to receive them too before the nodes stop.
    if map_url is not None:
        grace = time.monotonic() + 2.0
        while time.monotonic() < grace and \
                sum(1 for _, m in list(events) if m["event"].get("type") == "estimate") < len(estimates()):
            time.sleep(0.02)
    print("== 4/5 stop the nodes (their audio origins), then the room (the truth)", flush=True)
    stop_sse.set()
    origins, lost, xruns, _ = stop_nodes(run, out, [player] + listeners, origins_csv)
    room_summary = stop_room(run, out, room_log)

    print("== 5/5 locus eval --metric amil", flush=True)
    est = os.path.join(out, "estimates.jsonl")
    shutil.copy(est_path, est)
    ev = subprocess.run([locus, "eval", room_out, est, "--metric", "amil", "--json", "--json-output",
                         os.path.join(out, "eval.json")], capture_output=True, text=True)
    if ev.returncode not in (0, 4):
        raise Failure(f"locus eval failed ({ev.returncode}): {ev.stderr}")
    rep = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tools", "demo", "amil_report.py"), room_out, est,
                          os.path.join(out, "eval.json"), os.path.join(out, "track.csv"), os.path.join(out, "amil_map.png")],
                         capture_output=True, text=True)
    sys.stdout.write(rep.stdout)
    if rep.returncode != 0:
        raise Failure(f"amil_report.py failed: {rep.stderr}")

    # Latency: the last beep reaching the last listener (room truth, on CLOCK_MONOTONIC) -> the map.
    with open(os.path.join(room_out, "scene.yaml")) as f:
        env_room = yaml.safe_load(f)["environment"]
    origin = float(env_room["room_origin_monotonic_s"])
    arrivals = []
    with open(os.path.join(room_out, "room_arrivals.csv")) as f:
        arrivals = [r for r in csv.DictReader(f) if r["source"] == player and r["receiver"] != player]
    with open(os.path.join(out, "map_events.jsonl"), "w") as f:  # what the map's SSE client saw, when
        for now, msg in events:
            f.write(json.dumps({"monotonic_ns": now, "message": msg}) + "\n")
    latencies = []
    if arrivals:
        last_beep = max(float(r["t_emission"]) for r in arrivals)
        last_arrival = max(float(r["t_arrival"]) for r in arrivals if float(r["t_emission"]) == last_beep)
        heard_ns = (origin + last_arrival) * 1e9
        latencies = sorted((now - heard_ns) / 1e6 for now, msg in events if msg["event"].get("type") == "estimate")
    with open(os.path.join(out, "eval.json")) as f:
        summary = next(p for p in json.load(f)["plugins"] if p.get("metric") == "amil")["summary"]
    result = {
        "localizer": args.name, "listeners": len(listeners), "seed": args.seed, "period_frames": args.period,
        "located": summary.get("targets_located"), "expected": summary.get("targets_expected"),
        "mean_direction_error_deg": summary.get("mean_direction_error_deg"),
        "median_distance_error_pct": summary.get("median_distance_error_pct"),
        "latency_ms": latencies, "cpu_pct_of_one_core": cpu, "peak_rss_mb": peak_rss, "peak_rss_shmem_mb": peak_shm,
        "gesture_wall_s": wall,
        "node_playback_xruns": xruns, "node_frames_lost": lost, "room": room_summary, "map_url": map_url,
        "emissions": len({r["t_emission"] for r in arrivals}), "out": out,
    }
    if latencies:
        print(f"latency, last beep at the last listener -> estimate on the map: {len(latencies)} estimates, "
              f"median {statistics.median(latencies):.0f} ms, max {max(latencies):.0f} ms")
    else:
        print("latency: no estimate reached the map")
    node_cpu = [v for k, v in cpu.items() if k.startswith("locusd")]
    node_rss = [v for k, v in peak_rss.items() if k.startswith("locusd")]
    print(f"CPU (% of one core over {wall:.1f} s): player {cpu['locusd ' + player]:.1f}, listeners median "
          f"{statistics.median([cpu['locusd ' + i] for i in listeners]):.1f} (max {max(node_cpu):.1f}), room "
          f"{cpu['room']:.1f}, jackd {cpu['jackd']:.1f}, mosquitto {cpu['mosquitto']:.1f}; peak RSS (of it JACK's "
          f"shared memory): player {peak_rss['locusd ' + player]:.0f} MB ({peak_shm['locusd ' + player]:.0f}), listeners "
          f"median {statistics.median(node_rss):.0f} MB ({statistics.median(v for k, v in peak_shm.items() if k.startswith('locusd')):.0f}), "
          f"room {peak_rss['room']:.0f} MB ({peak_shm['room']:.0f})")
    print(f"xruns: nodes' playback {sum(xruns.values())} in all; {room_summary}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name", help="localizer (amil, locble, tum, spyloc, montage)")
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--out", help="run directory (default: a fresh temporary one, printed)")
    ap.add_argument("--listeners", type=int, default=12, help="listeners of the layout (1..12)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--difficulty", default="normal", choices=["easy", "normal", "hard"])
    ap.add_argument("--gestures", type=int, default=1, choices=[1, 3])
    ap.add_argument("--realtime", type=int, default=1, choices=[0, 1],
                    help="1 (default, as on a board): jackd -R -P 70, so jackd's, the room's and every node's process "
                         "threads run SCHED_FIFO when the user may (else jackd says so and runs without); 0: jackd -r")
    ap.add_argument("--period", type=int, default=None,
                    help="JACK period (frames; amil 1024, spyloc 256: a beacon's beep is due 50-75 ms after its sync, "
                         "which must cross the link, one period and the node's pipeline first)")
    ap.add_argument("--reflections", type=int, default=None, choices=[0, 1],
                    help="the room's image-source order (amil 0; spyloc 1: its LoS/NLoS classifier reads the decay)")
    ap.add_argument("--self-gain", type=float, default=0.2,
                    help="the player's own speaker into its own microphone (the room's --self-gain)")
    ap.add_argument("--map", default="127.0.0.1:0", help="the player's live map ([HOST:]PORT, or off)")
    ap.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the estimates after the layout")
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--imu-events", action="store_true", help="the nodes also write their IMU samples (JSON lines)")
    ap.add_argument("--scene", help="locble, tum, spyloc, montage: the layout, any scene of the family "
                                     "(default: locus simulate NAME --seed N)")
    ap.add_argument("--track", default="static", choices=["static", "ellipse"],
                    help="tum: the simulated layout's moving device (locus simulate tum -o track=)")
    ap.add_argument("--speed", type=float, default=1.0,
                    help="locble: scene seconds per wall second; only 1: the IMU's time base cannot be compressed "
                         "honestly (docs/room.md)")
    ap.add_argument("--settle", type=float, default=None,
                    help="seconds the nodes run on after the scene's end before they are stopped (their final updates; "
                         "locble 1, spyloc 3)")
    ap.add_argument("--duration", type=float, default=None,
                    help="tum: seconds of exchanges (default: the layout's span: its truth, or 12 s for a static one); "
                         "spyloc: the simulated layout's length (s; default the family's)")
    ap.add_argument("--calibrate-room-delay", action="store_true",
                    help="spyloc: tell the walker every beacon's sync_delay_s plus the room's converter delay (34 "
                         "samples, +0.26 m on every range), as a deployment calibrates its beacons; default: uncalibrated")
    ap.add_argument("--sync-first", type=float, default=1.0,
                    help="spyloc: the first beacon's first sync this long after its node starts (the others staggered)")
    args = ap.parse_args()

    names = subprocess.run([os.path.join(args.bin, "locus"), "plugins", "--json"], capture_output=True, text=True)
    localizers = set()
    if names.returncode == 0:
        localizers = {p["name"] for p in json.loads(names.stdout)["plugins"] if p["kind"] == "localizer"}
    if args.name not in LIVE:
        if localizers and args.name not in localizers:
            print(f"hil: unknown localizer '{args.name}' (known: {', '.join(sorted(localizers))})", file=sys.stderr)
        else:
            print(f"hil: no live HIL for {args.name} yet (only: {', '.join(sorted(LIVE))}); its replay: ./run demo",
                  file=sys.stderr)
        return 2
    if not 1 <= args.listeners <= 12:
        print("hil: --listeners: expected 1..12", file=sys.stderr)
        return 2
    if args.period is None:
        args.period = 1024 if args.name in ("amil", "tum") else 256
    if args.reflections is None:
        args.reflections = 0 if args.name in ("amil", "tum") else 1
    if args.settle is None:
        args.settle = 1.0 if args.name == "locble" else 3.0
    if args.name in ("amil", "tum") + hil_sync.FAMILIES:
        for tool in ("jackd", "jack_lsp", "mosquitto"):
            if shutil.which(tool) is None:
                print(f"hil: {tool} not found (tools/install-deps.sh installs it)", file=sys.stderr)
                return 1
    else:
        missing = hil_locble.check_tools()
        if missing:
            print(f"hil: {missing}", file=sys.stderr)
            return 1
        if args.speed != 1.0:
            # The steps and attitude detectors integrate the IMU over its timestamps: played X times
            # faster, the stamps shrink with the scene and the walk becomes another walk (faster steps,
            # a turn X times smaller), which the scene's truth does not describe (docs/room.md).
            print(f"hil: --speed {args.speed:g}: LocBLE's results depend on the IMU's time base, so its scene "
                  "cannot be compressed honestly; only --speed 1 (real time)", file=sys.stderr)
            return 2
    out = args.out or tempfile.mkdtemp(prefix=f"locus-hil-{args.name}-")
    os.makedirs(out, exist_ok=True)
    run = Run(out)

    def on_signal(sig, _frame):
        raise KeyboardInterrupt(f"signal {sig}")
    signal.signal(signal.SIGTERM, on_signal)
    status = 0
    t0 = time.monotonic()
    try:
        if args.name == "amil":
            hil_amil(args, args.bin, out, run)
        elif args.name == "tum":
            hil_tum.hil_tum(args, args.bin, out, run)
        elif args.name in hil_sync.FAMILIES:
            hil_sync.hil_sync(args, args.bin, out, run)
        else:
            hil_locble.hil_locble(args, args.bin, out, run)
        print(f"hil finished in {time.monotonic() - t0:.1f} s; files in {out}")
    except Failure as e:
        print(f"hil: {e}", file=sys.stderr)
        status = 1
    except KeyboardInterrupt:
        print("hil: interrupted; stopping everything", file=sys.stderr)
        status = 130
    finally:
        run.close()
        for f in os.listdir("/dev/shm"):  # what a killed jackd leaves, for this server only
            if f"_locus_hil_{os.getpid()}_" in f:
                try:
                    os.remove(os.path.join("/dev/shm", f))
                except OSError:
                    pass
    return status


if __name__ == "__main__":
    sys.exit(main())
