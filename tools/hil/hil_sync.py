"""`./run hil spyloc` and `./run hil montage` (tools/hil/hil.py, docs/room.md "SpyLoc and Montage"): the
sync-scheduled systems live, every sound emitted a known delay after a radio sync that travels over MQTT.

The layout is a scene of the family (`locus simulate spyloc|montage --seed N`, or --scene DIR). Started and
stopped here (hil_common.Run: own process groups, SIGTERM then SIGKILL on every exit path):
  - jackd (dummy driver, its own server name, synchronous, --period frames), mosquitto (own port),
  - `locus room LAYOUT` (--skew none): every speaker port into every microphone; the scene's beacons
    (emitters with a sound) are speaker ports at their anchors; a fake IIO IMU per device,
  - one `locusd --layout LAYOUT` per device, each a board: JACK capture and playback on the room's ports
    (one JACK client, so capture and playback frame F are one instant), the `link` sync source (the radio
    over MQTT: each arrival stamped), the MQTT link, and
      spyloc   beacons: capture from nothing (its frame clock only), playback to the room, the `link`
               source transmitting the beacon's own sync every period (the layout's sync.csv period; the
               beacons staggered as in the scene), `sync_emitter` (its beep at its own sync's arrival +
               sync_delay_s); the walker: config/spyloc.yaml's detectors and localizer, IIO IMU, the map;
      montage  every walker: config/montage.yaml's detectors and localizer, IIO IMU, `sync_emitter` (its
               Gold code at the start signal's arrival + delay_s + k·period_s); the first walker also
               transmits the start signal once (as W1 in the simulator); the reporter serves the map.
After the layout and a settle, every node is stopped (its final estimates and its log: audio origin, sync
counts and latency, emissions), then the room (the truth as a scene). Scored with `locus eval RUN OUT
--metric spyloc|montage` (the table and summary the replay prints), and the same layout replayed
(`locus replay LAYOUT -c config/FAMILY.yaml`) and scored for the comparison.
"""
import csv
import json
import os
import re
import shutil
import statistics
import subprocess
import threading
import time

import yaml

from hil_common import Failure, family_layout, read_jsonl, start_jackd, start_map_node, start_mosquitto, wait_for, watch

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
FAMILIES = ("spyloc", "montage")


def layout_for(args, locus, out):
    """(layout dir, scene dict): --scene DIR as given, else `locus simulate FAMILY --seed N [--duration S]`."""
    return family_layout(locus, args.name, out, args.seed, args.scene,
                         ["--duration", str(args.duration)] if args.duration else [])


def read_syncs(layout, scene):
    """[(local t, source)] of every device's sync.csv, by device."""
    out = {}
    for d in scene.get("devices") or []:
        if d.get("sync"):
            with open(os.path.join(layout, d["sync"])) as f:
                out[d["id"]] = [(float(r["t"]), r["source"]) for r in csv.DictReader(f)]
    return out


def plan_spyloc(scene, layout):
    """Walkers (devices with mics) and beacons (anchored emitters with a multitone and a sync_delay_s),
    each beacon's sync period (median interval of its syncs in the layout's sync.csv) and first sync."""
    beacons = []
    for e in scene.get("emitters") or []:
        sig = next((x for x in e.get("emits") or [] if x.get("type") == "multitone"), None)
        if sig is not None and e.get("anchor") and sig.get("sync_delay_s") is not None:
            beacons.append(e["id"])
    walkers = [d["id"] for d in scene.get("devices") or [] if d.get("mics")]
    if len(beacons) < 3 or not walkers:
        raise Failure(f"{layout}/scene.yaml: not a SpyLoc scene (expected >= 3 anchored multitone emitters with "
                      f"sync_delay_s under emitters:, and a device with mics; found {len(beacons)} and {len(walkers)})")
    syncs = read_syncs(layout, scene)
    periods = {}
    for b in beacons:
        t = sorted(x for rows in syncs.values() for x, s in rows if s == b)
        gaps = [y - x for x, y in zip(t, t[1:]) if y > x]
        periods[b] = statistics.median(gaps) if gaps else 1.0
    return walkers, beacons, periods


# Montage's rounds: the first emission this long after the start signal's arrival. The simulator's
# protocol commands the first round 20 ms after the start signal and each phone's speaker adds 20-150 ms
# of latency (the foreign world 5-50 ms): 0.1 s lies inside those 0.025-0.17 s and leaves the node's
# pipeline (one period, the detector thread, the dispatcher: ~7 ms at 256 frames) time to schedule it.
MONTAGE_DELAY_S = 0.1


def plan_montage(scene, layout):
    """Users (devices with a gold code, mics and a speaker), the start signal's sender (sync.csv's source,
    a user; else the first user), the round period (truth-extra.yaml period_s, else the command period of
    truth_emissions.csv, else 1 s) and the layout time of the start signal."""
    users = [d["id"] for d in scene.get("devices") or []
             if d.get("mics") and d.get("speaker") and any(x.get("type") == "gold" for x in d.get("emits") or [])]
    if len(users) < 2:
        raise Failure(f"{layout}/scene.yaml: not a Montage scene (expected >= 2 devices with mics, a speaker and a "
                      f"gold code; found {len(users)})")
    syncs = read_syncs(layout, scene)
    sources = [s for rows in syncs.values() for _, s in rows]
    start = sources[0] if sources and sources[0] in users else users[0]
    period = None
    extra = os.path.join(layout, "truth-extra.yaml")
    if os.path.exists(extra):
        with open(extra) as f:
            period = (yaml.safe_load(f) or {}).get("period_s")
    env = scene.get("environment") or {}
    if period is None and env.get("truth_emissions"):
        with open(os.path.join(layout, env["truth_emissions"])) as f:
            rows = list(csv.DictReader(f))
        t = sorted({float(r["t_command"]) for r in rows if r["id"] == users[0]})
        gaps = [b - a for a, b in zip(t, t[1:])]
        period = statistics.median(gaps) if gaps else None
    period = float(period or 1.0)
    # the start signal's true time: its arrival at the start user (local -> true with that clock)
    clock = ((scene.get("truth") or {}).get("clocks") or {}).get(start) or {}
    local = next((t for t, s in syncs.get(start, []) if s == start), None)
    t_sync = None
    if local is not None:
        t_sync = (local - float(clock.get("offset_s", 0.0))) / (1.0 + float(clock.get("skew_ppm", 0.0)) * 1e-6)
    return users, start, period, t_sync


def self_gain_for(scene, level_at_1m=0.1):
    """The room's --self-gain that puts a user's own code at half full scale in its microphone, as the
    simulator sets a phone's input level (the loudest user decides; 1 when no device has both)."""
    g = 1.0
    for d in scene.get("devices") or []:
        if not d.get("mics") or not d.get("speaker"):
            continue
        amp = max([float(x.get("amplitude", 1.0)) for x in d.get("emits") or [] if x.get("type") == "gold"] or [1.0])
        r = max(1e-3, min(sum((a - b) ** 2 for a, b in zip(m, d["speaker"])) ** 0.5 for m in d["mics"]))
        g = min(g, 0.5 * r / (level_at_1m * amp))
    return g


def jack_audio(server, ident, channels, connect):
    return {"source": "jack", "params": {"server": server, "client_name": ident, "channels": channels, "connect": connect}}


def jack_playback(server, ident):
    return {"sink": "jack", "params": {"server": server, "client_name": ident, "channels": 1, "connect": f"^room:{ident}_spk$"}}


def replay_config(name):
    with open(os.path.join(ROOT, "config", name + ".yaml")) as f:
        return yaml.safe_load(f)


def absolute_models(localizers):
    for loc in localizers:
        p = loc.get("params") or {}
        for k in ("los_model",):
            if p.get(k) and p[k] != "builtin" and not os.path.isabs(p[k]):
                p[k] = os.path.join(ROOT, p[k])
    return localizers


def node_config(args, ident, role, server, mqtt_port, room_out, out_jsonl, dev, extra):
    """One board's config. role: beacon | walker | montage."""
    base = {
        "log_level": "info",
        "sample_rate_hz": 44100,
        "output": {"path": out_jsonl, "events": ["estimate", "radio_sync"] + (["audio_detection", "step"] if role != "beacon" else [])},
        "link": {"type": "mqtt", "params": {"host": "127.0.0.1", "port": mqtt_port, "connect_timeout_s": 10}},
    }
    device = {"id": ident}
    if role == "beacon":
        # capture from nothing: the node's frame clock (capture frame F = playback frame F, one JACK client)
        device["audio"] = jack_audio(server, ident, 1, "")
        device["playback"] = jack_playback(server, ident)
        device["sync"] = {"source": "link", "params": {"sources": ident, "send_period_s": extra["period_s"],
                                                       "send_first_s": extra["first_s"],
                                                       "send_epoch_monotonic_s": extra["epoch"]}}
        base["devices"] = [device]
        base["localizers"] = [{"plugin": "sync_emitter"}]
        return base
    replay = replay_config(args.name)
    template = next(d for d in replay["devices"] if d["id"] == "*")
    device["audio"] = jack_audio(server, ident, len(dev["mics"]), f"^room:{ident}_mic_[0-9]+$")
    device["playback"] = jack_playback(server, ident)
    device["imu"] = {"source": "iio", "params": {"root": os.path.join(room_out, "iio", ident), "device": "lsm6dsl",
                                                  "mode": "buffered"}}
    device["sync"] = {"source": "link", "params": extra.get("sync_params", {})}
    device["detectors"] = template["detectors"]
    base["devices"] = [device]
    base["localizers"] = absolute_models(replay["localizers"]) + extra.get("localizers", [])
    return base


def log_text(out, name):
    try:
        with open(os.path.join(out, "logs", name + ".log"), errors="replace") as f:
            return f.read()
    except FileNotFoundError:
        return ""


def parse_node_log(text, ident):
    """What a node logged at exit: audio origin, frames/xruns, link sync counts and latency, emissions."""
    r = {}
    m = re.search(rf"device {re.escape(ident)}: audio frame 0 at CLOCK_MONOTONIC ([0-9.]+) s", text)
    if m:
        r["origin_s"] = float(m.group(1))
    m = re.search(rf"device {re.escape(ident)}: (\d+) frames processed, (\d+) lost .*playback: (\d+) xruns", text)
    if m:
        r["frames_lost"], r["playback_xruns"] = int(m.group(2)), int(m.group(3))
    m = re.search(r"link sync \S+: (\d+) sent as \S+, (\d+) received \(from ([^)]*)\), (\d+) from other sources, (\d+) malformed, "
                  r"(\d+) dropped; (?:one-way latency .* median ([0-9.]+) ms, p90 ([0-9.]+) ms, max ([0-9.]+) ms)?", text)
    if m:
        r["sync"] = {"sent": int(m.group(1)), "received": int(m.group(2)), "malformed": int(m.group(5)),
                     "dropped": int(m.group(6))}
        if m.group(7):
            r["sync"].update({"latency_median_ms": float(m.group(7)), "latency_p90_ms": float(m.group(8)),
                              "latency_max_ms": float(m.group(9))})
    m = re.search(r"sync_emitter \S+: (\d+) syncs, (\d+) emissions scheduled, (\d+) late \(not scheduled\), (\d+) refused, "
                  r"(\d+) cut by the emitter; (?:lead min ([-0-9.]+) ms, median ([-0-9.]+) ms)?", text)
    if m:
        r["emit"] = {"syncs": int(m.group(1)), "scheduled": int(m.group(2)), "late": int(m.group(3)),
                     "refused": int(m.group(4)), "cut": int(m.group(5))}
        if m.group(6):
            r["emit"].update({"lead_min_ms": float(m.group(6)), "lead_median_ms": float(m.group(7))})
    return r


def evaluate(locus, metric, scene_dir, est, json_out):
    """`locus eval --metric M`: (printed table, summary dict)."""
    r = subprocess.run([locus, "eval", scene_dir, est, "--metric", metric], capture_output=True, text=True)
    if r.returncode not in (0, 4):
        raise Failure(f"locus eval {scene_dir} {est} --metric {metric} failed ({r.returncode}): {r.stderr}")
    subprocess.run([locus, "eval", scene_dir, est, "--metric", metric, "--json", "--json-output", json_out],
                   capture_output=True, text=True)
    with open(json_out) as f:
        plugin = next((p for p in json.load(f)["plugins"] if p.get("metric") == metric), None)
    if plugin is None:  # nothing to score: no estimate at all
        return r.stdout + r.stderr, {"estimates": 0, "targets_located": 0}
    return r.stdout, plugin["summary"]


def sync_pairs(nodes_out, ids):
    """Each sync message's arrival (CLOCK_MONOTONIC) at every node, matched by sender and order: the
    radio_sync events of each node's output (audio timeline) + its audio origin."""
    arrivals = {}  # (node, source) -> [monotonic s]
    for ident, (path, origin) in nodes_out.items():
        if origin is None:
            continue
        for e in read_jsonl(path):
            if e.get("type") == "radio_sync":
                arrivals.setdefault((ident, e["source"]), []).append(origin + e["t_s"])
    return arrivals


def hil_sync(args, bin_dir, out, run):
    from map_measure import cpu_s  # tools/scripts (hil_common puts it on the path)
    locus, locusd = os.path.join(bin_dir, "locus"), os.path.join(bin_dir, "locusd")
    for d in ("logs", "nodes"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    fam = args.name
    what = f"--scene {args.scene}" if args.scene else f"locus simulate {fam} --seed {args.seed}" + \
        (f" --duration {args.duration:g}" if args.duration else "")
    print(f"== 1/5 layout: {what}", flush=True)
    layout, scene = layout_for(args, locus, out)
    devs = {d["id"]: d for d in scene.get("devices") or []}
    plan = {}  # ident -> (role, extra)
    if fam == "spyloc":
        walkers, beacons, periods = plan_spyloc(scene, layout)
        for i, b in enumerate(beacons):  # staggered as the simulator's beacons
            plan[b] = ("beacon", {"period_s": round(periods[b], 6), "first_s": round(args.sync_first + i * periods[b] / len(beacons), 6)})
        for w in walkers:
            plan[w] = ("walker", {"sync_params": {"sources": ",".join(beacons)}})
        reporter = walkers[0]
        print(f"   walker {', '.join(walkers)}; beacons {', '.join(f'{b} (sync every {periods[b]:g} s)' for b in beacons)}",
              flush=True)
    else:
        users, start, period, t_sync = plan_montage(scene, layout)
        t_begin = float(open(os.path.join(layout, "truth.csv")).read().splitlines()[1].split(",")[0])
        duration_all = float(open(os.path.join(layout, "truth.csv")).read().strip().splitlines()[-1].split(",")[0])
        # the start signal at its layout time: the room starts the layout 2 s after the last node (the
        # start user, started last) connects
        first_s = 2.0 + max(0.0, (t_sync if t_sync is not None else t_begin + 1.0) - t_begin)
        rounds = max(1, min(48, int((duration_all - t_begin - (first_s - 2.0) - MONTAGE_DELAY_S) / period)))
        emit = {"plugin": "sync_emitter", "params": {"sources": start, "delay_s": MONTAGE_DELAY_S,
                                                     "repeat_period_s": period, "repeat_count": rounds}}
        for u in users:
            sp = {"sources": start}
            if u == start:
                sp.update({"send_period_s": 1.0, "send_count": 1, "send_first_s": round(first_s, 3)})
            plan[u] = ("montage", {"sync_params": sp, "localizers": [emit]})
        plan = {u: plan[u] for u in [x for x in users if x != start] + [start]}  # the start user last
        reporter = users[-1]  # config/montage.yaml's reporter: the last user
        walkers = users
        print(f"   users {', '.join(users)}; start signal from {start} {first_s:.2f} s after its node starts; "
              f"{rounds} rounds every {period:g} s from {MONTAGE_DELAY_S} s after it", flush=True)
    duration_s = float(open(os.path.join(layout, "truth.csv")).read().strip().splitlines()[-1].split(",")[0])

    server = f"locus_hil_{os.getpid()}"
    print(f"== 2/5 jackd -n {server} -d dummy -p {args.period}; mosquitto; locus room (--skew none)", flush=True)
    jackd, env = start_jackd(run, out, server, args.period, args.realtime)
    mqtt_port, broker = start_mosquitto(run, out)
    room_out = os.path.join(out, "run")
    origins_csv = os.path.join(out, "node_origins.csv")
    room_log = os.path.join(out, "logs", "room.out")
    env_scene = scene.get("environment") or {}
    reflections = args.reflections if env_scene.get("room") else 0  # outdoors (no room): free field
    room = run.start("room", [locus, "room", layout, room_out, "--server", server, "--skew", "none", "--seed",
                              str(args.seed), "--lead-in", "2", "--reflections", str(reflections),
                              "--self-gain", f"{self_gain_for(scene) if fam == 'montage' else 1.0:.6g}",
                              "--node-origins", origins_csv], env=env, stdout=open(room_log, "w"))

    def room_said(pattern):
        with open(room_log) as f:
            return re.search(pattern, f.read())
    wait_for(lambda: room_said(r"room: \d+ devices of"), 30, "the room's ports and IIO trees", [("room", room)])

    order = [i for i in plan if plan[i][0] != "beacon"] + [i for i in plan if plan[i][0] == "beacon"]
    walker_layout = layout
    if fam == "spyloc" and args.calibrate_room_delay:
        walker_layout = calibrated_layout(layout, scene, os.path.join(out, "walker_layout"), ROOM_DELAY_SAMPLES / 44100.0)
        print(f"   the walker's layout: every sync_delay_s + {ROOM_DELAY_SAMPLES} samples (the room's converter delay, "
              "calibrated as a deployment calibrates its beacons')", flush=True)
    print(f"== 3/5 {len(order)} locusd nodes ({', '.join(f'{i}: {plan[i][0]}' for i in order)}), MQTT sync, "
          f"the layout ({duration_s:.1f} s)", flush=True)
    nodes, map_url = {}, None
    events, stop_sse = [], threading.Event()
    node_out = {}
    epoch = None
    senders = {i for i in order if plan[i][1].get("sync_params", plan[i][1]).get("send_period_s") or plan[i][0] == "beacon"}
    for ident in order:  # listeners first: the beacons' first syncs find them running
        role, extra = plan[ident]
        if ident in senders and epoch is None:  # the first sync must find every listener's sync source started
            wait_for(lambda: all("running " in log_text(out, "node-" + k) for k in nodes), 90,
                     "the listening nodes to start", [("locusd " + k, v) for k, v in nodes.items()])
            # one epoch for every sender's schedule: the beacons stay staggered however their nodes start
            epoch = time.monotonic() + 2.0 + 1.5 * len(senders)
        if role == "beacon":
            extra = dict(extra, epoch=round(epoch, 6))
        path_out = os.path.join(out, "nodes", ident + ".jsonl")
        cfg = node_config(args, ident, role, server, mqtt_port, room_out, path_out, devs.get(ident), extra)
        path = os.path.join(out, "nodes", ident + ".yaml")
        with open(path, "w") as f:
            yaml.safe_dump(cfg, f, sort_keys=False)
        cmd = [locusd, "--config", path, "--layout", walker_layout if role == "walker" else layout]
        if ident == reporter and args.map != "off":
            p, map_url = start_map_node(run, "node-" + ident, cmd, env, args.map, f"HIL: {fam} live ({what})",
                                        events, stop_sse, f"{out}/logs/node-{ident}.log")
        else:
            p = run.start("node-" + ident, cmd, env=env)
        nodes[ident] = p
        node_out[ident] = path_out
    alive = [("room", room), ("jackd", jackd), ("mosquitto", broker)] + [("locusd " + k, v) for k, v in nodes.items()]
    wait_for(lambda: room_said(r"layout starts at room time"), 90, "every node to connect to the room", alive)
    pids = {"jackd": jackd.pid, "mosquitto": broker.pid, "room": room.pid}
    pids.update({"locusd " + k: v.pid for k, v in nodes.items()})
    t0 = time.monotonic()
    cpu0 = {k: cpu_s(p) for k, p in pids.items()}
    peak_rss = {k: 0.0 for k in pids}
    end = t0 + 2.0 + duration_s + args.settle  # the lead-in, the layout, a settle for the last estimates
    while time.monotonic() < end:
        watch(pids, peak_rss, alive, "the layout", out)
        time.sleep(0.1)
    wall = time.monotonic() - t0
    cpu = {k: 100.0 * (cpu_s(p) - cpu0[k]) / wall for k, p in pids.items()}

    print("== 4/5 stop the nodes (final estimates, their logs), the room (the truth), mosquitto, jackd", flush=True)
    stop_sent_ns = time.monotonic_ns()
    info = {}
    for ident in [i for i in order if i != reporter] + [reporter]:
        rc = run.stop("node-" + ident)
        if rc != 0:
            raise Failure(f"locusd {ident} exited with {rc}; see {out}/logs/node-{ident}.log")
        info[ident] = parse_node_log(log_text(out, "node-" + ident), ident)
    stop_sse.set()
    with open(origins_csv, "w") as f:
        f.write("device,audio_origin_monotonic_s\n")
        for k, v in info.items():
            if "origin_s" in v:
                f.write(f"{k},{v['origin_s']:.9f}\n")
    if run.stop("room") != 0:
        raise Failure(f"locus room exited with an error; see {out}/logs/room.log")
    run.stop("mosquitto")
    run.stop("jackd")
    with open(room_log) as f:
        room_summary = f.read().strip().splitlines()[-1]

    print(f"== 5/5 locus eval --metric {fam}: live, then the same layout replayed", flush=True)
    shift_truth_steps(layout, scene, room_out)
    est = os.path.join(out, "estimates.jsonl")
    with open(est, "w") as f:
        for ident in order:
            for e in read_jsonl(node_out[ident]):
                if e.get("type") in ("estimate", "step"):
                    f.write(json.dumps(e) + "\n")
    table, live = evaluate(locus, fam, room_out, est, os.path.join(out, "eval_live.json"))
    print(table, end="")
    replay_est = os.path.join(out, "replay.jsonl")
    r = subprocess.run([locus, "replay", layout, "-c", os.path.join(ROOT, "config", fam + ".yaml"), "--speed", "max",
                        "-o", replay_est], capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise Failure(f"locus replay {layout} failed ({r.returncode}): {r.stderr}")
    _, rep = evaluate(locus, fam, layout, replay_est, os.path.join(out, "eval_replay.json"))

    # Sync: what was sent and received, the one-way latency, and per message how much later the walker
    # received it than the emitter did (what biases a range: c x that difference).
    arrivals = sync_pairs({k: (node_out[k], info[k].get("origin_s")) for k in order}, order)
    skew_ms = []
    if fam == "spyloc":
        for b in beacons:
            own = arrivals.get((b, b), [])
            for w in walkers:
                other = arrivals.get((w, b), [])
                for t in other:  # the beacon's own arrival of the same message: the nearest within half a period
                    near = min(own, key=lambda x: abs(x - t), default=None)
                    if near is not None and abs(near - t) < periods[b] / 2:
                        skew_ms.append((t - near) * 1e3)
    c = float(scene.get("speed_of_sound") or 343.2)
    range_err = range_errors(out, room_out, node_out, info, walkers, scene, c) if fam == "spyloc" else []
    detection = code_detections(room_out, node_out, info, walkers, scene) if fam == "montage" else None
    on_map = [(now, m["event"]) for now, m in events if m["event"].get("type") == "estimate"]
    origin = info.get(reporter, {}).get("origin_s")
    to_map_ms = sorted((now - (origin + e["t_s"]) * 1e9) / 1e6 for now, e in on_map if origin is not None and now < stop_sent_ns)
    emit = {k: v["emit"] for k, v in info.items() if "emit" in v}
    sync = {k: v["sync"] for k, v in info.items() if "sync" in v}
    result = {
        "localizer": fam, "layout": layout, "seed": None if args.scene else args.seed, "period_frames": args.period,
        "live": live, "replay": rep, "sync": sync, "emissions": emit,
        "walker_minus_emitter_arrival_ms": skew_ms, "range_error_m": range_err, "detection": detection,
        "estimate_to_map_ms": to_map_ms, "cpu_pct_of_one_core": cpu, "peak_rss_mb": peak_rss, "wall_s": wall,
        "nodes": info, "room": room_summary, "map_url": map_url, "out": out,
    }
    key = "mean_error_m"
    print(f"live vs replay ({fam}, same layout): located {live.get('targets_located')}/{live.get('targets_expected')} "
          f"vs {rep.get('targets_located')}/{rep.get('targets_expected')}; mean error {fmt(live.get(key))} vs "
          f"{fmt(rep.get(key))} m; median {fmt(live.get('median_error_m'))} vs {fmt(rep.get('median_error_m'))} m; "
          f"p90 {fmt(live.get('p90_error_m'))} vs {fmt(rep.get('p90_error_m'))} m; estimates "
          f"{live.get('estimates')} vs {rep.get('estimates')}")
    sent = sum(v["sent"] for v in sync.values())
    print(f"sync over MQTT: {sent} sent; received " + ", ".join(f"{k} {v['received']}" for k, v in sync.items()) +
          "; one-way latency median (max) " + ", ".join(f"{k} {v.get('latency_median_ms', float('nan')):.2f} "
                                                        f"({v.get('latency_max_ms', float('nan')):.2f}) ms" for k, v in sync.items()))
    if skew_ms:
        med = statistics.median(skew_ms)
        print(f"walker's arrival - emitter's own arrival of the same sync: median {med:.3f} ms, "
              f"range {min(skew_ms):.3f}..{max(skew_ms):.3f} ms over {len(skew_ms)} syncs = a range bias of "
              f"c x that: median {c * med / 1e3:+.3f} m ({c * min(skew_ms) / 1e3:+.3f}..{c * max(skew_ms) / 1e3:+.3f} m), "
              "uncompensated")
    if range_err:
        print(f"live ranges (beep - sync arrival - sync_delay_s, x c) - the room's true distance: median "
              f"{statistics.median(range_err):+.3f} m, p10..p90 {pct(range_err, 10):+.3f}..{pct(range_err, 90):+.3f} m over "
              f"{len(range_err)} beeps (the room's converter delay of {ROOM_DELAY_SAMPLES} samples is "
              f"{c * ROOM_DELAY_SAMPLES / 44100:+.3f} m of it; a deployment calibrates it into sync_delay_s)")
    if detection:
        print(f"other users' codes: {detection['within_3']} of {detection['pair_rounds']} pair-rounds detected within 3 "
              f"samples of the room's direct arrival ({detection['detections']} detections, {detection['wrong']} further off; "
              f"own code's offset {detection['own_offset_samples']:+.1f} samples: the room's converter delay and the "
              "detector's, the same for every code)")
    print("emissions: " + ", ".join(f"{k} {v['scheduled']} scheduled / {v['late']} late / {v['cut']} cut "
                                    f"(lead min {v.get('lead_min_ms', float('nan')):.1f} ms)" for k, v in emit.items()))
    if to_map_ms:
        print(f"latency, estimate's data time -> the map: {len(to_map_ms)} estimates, median "
              f"{statistics.median(to_map_ms):.0f} ms, max {max(to_map_ms):.0f} ms")
    else:
        print("latency: no estimate reached the map")
    print(f"CPU (% of one core over {wall:.1f} s) and peak RSS: " +
          ", ".join(f"{k} {cpu[k]:.1f} % {peak_rss[k]:.0f} MB" for k in pids))
    xr = sum(v.get("playback_xruns", 0) for v in info.values())
    print(f"xruns: nodes' playback {xr} in all; {room_summary}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result


# The room's interpolator keeps every tap in the past: a microphone hears the air kTaps/2 + 2 samples
# before its frame (tools/room/renderer.cpp, RoomRenderer's offset_s with --skew none), a fixed "ADC
# latency" that every range to a beep carries.
ROOM_DELAY_SAMPLES = 34


def calibrated_layout(layout, scene, dest, extra_s):
    """A copy of the layout (its files linked) whose beacons' sync_delay_s include `extra_s`: what the
    walker is told, as a deployment calibrates a beacon's delay (speaker and ADC latency included)."""
    shutil.rmtree(dest, ignore_errors=True)
    os.makedirs(dest)
    for name in os.listdir(layout):
        if name != "scene.yaml":
            os.symlink(os.path.join(layout, name), os.path.join(dest, name))
    sc = json.loads(json.dumps(scene))
    for e in sc.get("emitters") or []:
        for x in e.get("emits") or []:
            if x.get("sync_delay_s") is not None:
                x["sync_delay_s"] = float(x["sync_delay_s"]) + extra_s
    with open(os.path.join(dest, "scene.yaml"), "w") as f:
        yaml.safe_dump(sc, f, sort_keys=False)
    return dest


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(len(v) * q / 100))]


def range_errors(out, room_out, node_out, info, walkers, scene, c):
    """Per beep a walker detected: its range as SpyLoc forms it from the live sync (c x (beep - latest sync
    of that beacon - sync_delay_s)) minus the room's true distance at the beep's direct arrival."""
    with open(os.path.join(room_out, "scene.yaml")) as f:
        origin_room = float(yaml.safe_load(f)["environment"]["room_origin_monotonic_s"])
    delays = {e["id"]: float(x["sync_delay_s"]) for e in scene.get("emitters") or [] for x in e.get("emits") or []
              if x.get("sync_delay_s") is not None}
    with open(os.path.join(room_out, "room_arrivals.csv")) as f:
        arrivals = list(csv.DictReader(f))
    errs = []
    for w in walkers:
        p0 = info.get(w, {}).get("origin_s")
        if p0 is None:
            continue
        ev = read_jsonl(node_out[w])
        syncs = [e for e in ev if e.get("type") == "radio_sync"]
        mine = [(float(a["t_arrival"]), a["source"], float(a["distance_m"])) for a in arrivals if a["receiver"] == w]
        for d in (e for e in ev if e.get("type") == "audio_detection"):
            t_room = d["t_s"] + p0 - origin_room  # local (audio timeline) -> room time
            near = min(mine, key=lambda a: abs(a[0] - t_room), default=None)
            if near is None or abs(near[0] - t_room) > 0.005 or near[1] not in delays:
                continue
            prev = [s["t_s"] for s in syncs if s["source"] == near[1] and s["t_s"] < d["t_s"]]
            if prev:
                errs.append(c * (d["t_s"] - prev[-1] - delays[near[1]]) - near[2])
    return errs


def code_detections(room_out, node_out, info, users, scene):
    """Montage: each walker's detections of the other users' codes against the room's direct arrivals.
    A detection's offset from its nearest arrival of that code, less the median offset of the walker's
    own code (the room's converter delay plus the detector's fixed bias, common to every code and
    cancelled by ETOA), within 3 samples counts. Out of every (emission, other walker) pair."""
    with open(os.path.join(room_out, "scene.yaml")) as f:
        origin_room = float(yaml.safe_load(f)["environment"]["room_origin_monotonic_s"])
    codes = {}  # template index (the goldcode detector's order: the scene's gold emitters) -> user
    for d in scene.get("devices") or []:
        if any(x.get("type") == "gold" for x in d.get("emits") or []):
            codes[len(codes)] = d["id"]
    with open(os.path.join(room_out, "room_arrivals.csv")) as f:
        arrivals = list(csv.DictReader(f))
    with open(os.path.join(room_out, "room_emissions.csv")) as f:
        emissions = [r["id"] for r in csv.DictReader(f)]
    fs = 44100.0
    within = wrong = total = 0
    own_offsets = []
    for w in users:
        p0 = info.get(w, {}).get("origin_s")
        if p0 is None:
            continue
        by_src = {}
        for a in arrivals:
            if a["receiver"] == w:
                by_src.setdefault(a["source"], []).append(float(a["t_arrival"]))
        offs = {}
        for e in read_jsonl(node_out[w]):
            if e.get("type") != "audio_detection" or e.get("template") not in codes:
                continue
            src = codes[e["template"]]
            t_room = e["frame"] / fs + p0 - origin_room
            near = min(by_src.get(src, []), key=lambda x: abs(x - t_room), default=None)
            if near is not None:
                offs.setdefault(src, []).append((t_room - near) * fs)
        own = statistics.median(offs[w]) if offs.get(w) else 0.0
        own_offsets.append(own)
        for src, v in offs.items():
            if src == w:
                continue
            total += len(v)
            ok = sum(1 for x in v if abs(x - own) <= 3.0)
            within += ok
            wrong += len(v) - ok
    pair_rounds = sum(1 for e in emissions if e in users) * (len(users) - 1)
    return {"within_3": within, "wrong": wrong, "detections": total, "pair_rounds": pair_rounds,
            "own_offset_samples": statistics.median(own_offsets) if own_offsets else float("nan")}


def shift_truth_steps(layout, scene, room_out):
    """The layout's truth_steps.csv (heel strikes on layout time) on the run's time (the room plays
    layout time t at room time room_layout_start_s + t), so `locus eval` scores the live strides too.
    The room eases a walk in over its first second: steps in it are the layout's, not quite the room's."""
    name = (scene.get("environment") or {}).get("truth_steps")
    if not name or not os.path.exists(os.path.join(layout, name)):
        return
    with open(os.path.join(room_out, "scene.yaml")) as f:
        start = float(yaml.safe_load(f)["environment"]["room_layout_start_s"])
    if start < 0:
        return
    with open(os.path.join(layout, name)) as f:
        rows = list(csv.DictReader(f))
    with open(os.path.join(room_out, name), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()) if rows else ["t_true", "id", "stride_m", "frequency_hz"])
        w.writeheader()
        for r in rows:
            r["t_true"] = repr(float(r["t_true"]) + start)
            w.writerow(r)


def fmt(v):
    return "-" if v is None else f"{v:.3f}"
