"""`./run hil tum` (tools/hil/hil.py tum, docs/room.md "TUM"): TUM's live roles on boards in a virtual room.

The layout is a TUM scene: `locus simulate tum --seed N -o overlap=1 -o track=static|ellipse` (default), or
--scene DIR (e.g. the foreign ../shared/scenes/tum-102). Started and stopped here (hil_common.Run: own
process groups, SIGTERM then SIGKILL on every exit path):
  - jackd (dummy driver, its own server name), mosquitto (its own loopback port),
  - `locus room` with the layout: every device's speaker into every device's two microphones (moving ends:
    the delays follow the trajectories), each device's IMU with a magnetometer (`--magnetometer`: the
    layout's truth.magnetic_field_world; a layout without one gets the simulator's field, said so) on a
    fake IIO device, the microphones' clocks skewed as the layout's (`--skew scene`),
  - one `locusd` per device, each a board from config/tum-node.yaml (JACK capture of its two mics and
    playback into its speaker, the IIO IMU, the MQTT link, `chirp` with both tones + `attitude`, `tum`
    with `elect_devices` = the layout's devices and `elect_order` = the layout's emitters, so that a tie
    of RTTs -- every RTT on one machine is far below `elect_tie_s` -- elects the pair the replay uses).
    The nodes synchronise over the link, elect the working pair, which emits; device 1 solves and serves
    the live map (its URL printed).
After --duration seconds of exchanges the nodes are stopped (their audio origins: the truth clocks), then
the room (it writes the run's truth as a scene), and `locus eval RUN estimates --metric tum` scores the live
run as it scores a replay; the same layout replayed (`locus replay LAYOUT -c config/tum.yaml`) is scored too.

Figures: live vs replay (Eq. 23 median / p90, located); the election each node adopted; the link's RTTs and
host-clock offsets (truth: 0, every node runs on this machine's CLOCK_MONOTONIC) and the audio-clock offsets
the recordings paired vs the room's truth clocks; emissions scheduled / missed / late; latency from a tone's
emission (device 1's audio clock -> CLOCK_MONOTONIC) to its estimates on the map; each process's CPU and RSS.
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

from hil_common import (Failure, check_alive, family_layout, read_jsonl, sample_peaks, start_map_node, start_room,
                        stop_nodes, stop_room, wait_for)
from map_measure import cpu_s

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SIM_FIELD_UT = [12.1, 14.6, -44.0]  # the simulator's field (locus simulate tum writes it), for a layout without one


def layout_for(args, locus, out):
    """The layout: simulated, or --scene (its scene.yaml and truth.csv copied; a missing magnetic field
    added). (dir, scene dict, the recordings' dir, note about the field or None)."""
    if args.scene and not os.path.isfile(os.path.join(args.scene, "scene.yaml")):
        raise Failure(f"--scene {args.scene}: no scene.yaml there")
    src, scene = family_layout(locus, "tum", out, args.seed, args.scene,
                               extra=("-o", "overlap=1", "-o", f"track={args.track}"))
    if not args.scene:
        return src, scene, src, None
    if (scene.get("environment") or {}).get("family") != "tum":
        raise Failure(f"--scene {args.scene}: environment.family is {(scene.get('environment') or {}).get('family')!r}, "
                      "expected 'tum'")
    if (scene.get("truth") or {}).get("magnetic_field_world") is not None:
        return src, scene, src, None
    # The room's magnetometers need a field; the scene's recording had its own (unknown) one.
    layout = os.path.join(out, "layout")
    os.makedirs(layout, exist_ok=True)
    shutil.copy(os.path.join(src, scene["truth"]["trajectories"]), layout)
    scene["truth"]["magnetic_field_world"] = SIM_FIELD_UT
    for d in scene["devices"]:  # the recordings stay with the original (the replay reads them there)
        for stream in ("audio", "imu", "ble", "sync"):
            d.pop(stream, None)
    with open(os.path.join(layout, "scene.yaml"), "w") as f:
        yaml.safe_dump(scene, f, sort_keys=False)
    note = (f"{args.scene} has no truth.magnetic_field_world: the room's magnetometers read the simulator's "
            f"{SIM_FIELD_UT} uT (its recording's own field and hard iron are not reproduced)")
    return layout, scene, src, note


def node_config(template, dev, server, mqtt_port, room_out, out_jsonl, n_devices, emitters):
    """config/tum-node.yaml for device `dev` of the layout on the room's ports."""
    cfg = json.loads(json.dumps(template))
    ident = dev["id"]
    cfg["log_level"] = "info"
    cfg["output"] = {"path": out_jsonl, "events": ["estimate", "audio_detection", "attitude"]}  # what each node saw
    cfg["link"] = {"type": "mqtt", "params": {"host": "127.0.0.1", "port": mqtt_port, "connect_timeout_s": 10}}
    d = cfg["devices"][0]
    d["id"] = ident
    d["audio"] = {"source": "jack", "params": {"server": server, "client_name": ident, "channels": len(dev["mics"]),
                                               "connect": f"^room:{ident}_mic_[0-9]+$"}}
    d["playback"] = {"sink": "jack", "params": {"server": server, "client_name": ident, "channels": 1,
                                                "connect": f"^room:{ident}_spk$"}}
    d["imu"] = {"source": "iio", "params": {"root": os.path.join(room_out, "iio", ident), "device": "lsm6dsl",
                                            "mode": "buffered"}}
    d["geometry"] = {"mics_m": [c for m in dev["mics"] for c in m]}
    if dev.get("speaker"):
        d["geometry"]["speaker_m"] = list(dev["speaker"])
    tum = cfg["localizers"][0]["params"]
    tum["elect_devices"] = n_devices
    tum["elect_order"] = ",".join(emitters)
    # On one machine every link RTT is the MQTT client's and the dispatchers' scheduling (measured 35-50 ms
    # over the loopback broker), not a network path: a tie, which the layout's emitter order breaks.
    tum["elect_tie_s"] = 0.1
    return cfg


def evaluate(locus, scene_dir, est, json_out):
    ev = subprocess.run([locus, "eval", scene_dir, est, "--metric", "tum", "--json-output", json_out],
                        capture_output=True, text=True)
    if ev.returncode not in (0, 4):
        raise Failure(f"locus eval {scene_dir} {est} failed ({ev.returncode}): {ev.stderr}")
    with open(json_out) as f:
        summary = next(p for p in json.load(f)["plugins"] if p.get("metric") == "tum")["summary"]
    return ev.stdout, summary


def hil_tum(args, bin_dir, out, run):
    locus, locusd = os.path.join(bin_dir, "locus"), os.path.join(bin_dir, "locusd")
    for d in ("logs", "nodes"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    what = args.scene or f"locus simulate tum --seed {args.seed} -o overlap=1 -o track={args.track}"
    print(f"== 1/6 layout: {what} -> {out}/layout", flush=True)
    layout, scene, replay_scene, note = layout_for(args, locus, out)
    if note:
        print(f"   note: {note}", flush=True)
    devices = [d for d in scene["devices"] if len(d.get("mics") or []) >= 2]
    emitters = [d["id"] for d in scene["devices"] if d.get("emits")]
    if len(devices) < 3 or len(emitters) < 2:
        raise Failure(f"{layout}: TUM needs two emitting devices and a monitor with two mics each "
                      f"({len(devices)} two-mic devices, emitters {emitters})")
    with open(os.path.join(layout, scene["truth"]["trajectories"])) as f:
        t_rows = [float(r["t"]) for r in csv.DictReader(f)]
    duration = args.duration or (max(t_rows) - min(t_rows) if max(t_rows) > min(t_rows) else 12.0)

    print(f"== 2/6 jackd -d dummy -p {args.period}; mosquitto; locus room --magnetometer", flush=True)
    rm = start_room(run, out, locus, layout, args, ["--magnetometer"])
    server, env, jackd, mqtt_port, broker, room = rm.server, rm.env, rm.jackd, rm.mqtt_port, rm.broker, rm.proc
    room_out, origins_csv, room_log = rm.out, rm.origins_csv, rm.log

    device1 = emitters[0]
    print(f"== 3/6 {len(devices)} locusd nodes from config/tum-node.yaml (sync, election, emissions); {duration:.0f} s "
          f"of exchanges; the map on {device1} (expected device 1)", flush=True)
    with open(os.path.join(ROOT, "config", "tum-node.yaml")) as f:
        template = yaml.safe_load(f)
    nodes, events, stop_sse, map_url = {}, [], threading.Event(), None
    for dev in devices:
        ident = dev["id"]
        cfg = node_config(template, dev, server, mqtt_port, room_out, os.path.join(out, "nodes", ident + ".jsonl"),
                          len(devices), emitters)
        path = os.path.join(out, "nodes", ident + ".yaml")
        with open(path, "w") as f:
            yaml.safe_dump(cfg, f, sort_keys=False)
        cmd = [locusd, "--config", path]
        if ident == device1 and args.map != "off":
            p, map_url = start_map_node(run, "node-" + ident, cmd, env, args.map, f"HIL: tum live ({what})", events,
                                        stop_sse, f"{out}/logs/node-{ident}.log")
        else:
            p = run.start("node-" + ident, cmd, env=env)
        nodes[ident] = p
    alive = [("room", room), ("jackd", jackd), ("mosquitto", broker)] + [("locusd " + k, v) for k, v in nodes.items()]
    wait_for(lambda: rm.said(r"layout starts at room time"), 90, "every node to connect to the room", alive)

    def node_said(ident, pattern):
        with open(os.path.join(out, "logs", f"node-{ident}.log"), errors="replace") as f:
            return re.search(pattern, f.read())
    wait_for(lambda: all(node_said(i, r"tum: working devices") for i in nodes), 60, "every node to adopt the working devices",
             alive)
    pids = {"jackd": jackd.pid, "mosquitto": broker.pid, "room": room.pid}
    pids.update({"locusd " + k: v.pid for k, v in nodes.items()})
    t0 = time.monotonic()
    cpu0 = {k: cpu_s(p) for k, p in pids.items()}
    peak_rss = {k: 0.0 for k in pids}
    est_path = os.path.join(out, "nodes", device1 + ".jsonl")
    deadline = t0 + duration + 3.0  # start_delay_s (1 s) and the last exchange's detection and solve
    while time.monotonic() < deadline:
        sample_peaks(pids, peak_rss)
        check_alive(alive, "the exchanges", out)
        time.sleep(0.1)
    wall = time.monotonic() - t0
    cpu = {k: 100.0 * (cpu_s(p) - cpu0[k]) / wall for k, p in pids.items()}
    if map_url is not None:  # the map's SSE client: a moment to receive what the node wrote
        n_est = len([e for e in read_jsonl(est_path) if e.get("type") == "estimate"])
        grace = time.monotonic() + 2.0
        while time.monotonic() < grace and sum(1 for _, m in list(events) if m["event"].get("type") == "estimate") < n_est:
            time.sleep(0.02)
    stop_sse.set()

    print("== 4/6 stop the nodes (their audio origins), then the room (the truth)", flush=True)
    origins, lost, xruns, logs = stop_nodes(run, out, list(nodes), origins_csv)
    room_summary = stop_room(run, out, room_log)

    # What each node adopted, found and emitted (its log at exit).
    roles = {}
    for ident, text in logs.items():
        m = re.search(r"tum: working devices (\S+) and (\S+) \(RTT ([0-9.]+) ms\)", text)
        roles[ident] = (m.group(1), m.group(2)) if m else None
    sync = [dict(src=m.group(1), dst=m.group(2), offset_s=float(m.group(3)), rtt_ms=float(m.group(4)),
                 spread_ms=float(m.group(5)), n=int(m.group(6)))
            for text in logs.values()
            for m in re.finditer(r"tum: link sync (\S+) -> (\S+): offset ([-0-9.e]+) s, RTT ([0-9.e]+) ms, spread ([0-9.e]+) ms "
                                 r"over (\d+) round trips", text)]
    emitted = {}
    for ident, text in logs.items():
        m = re.search(r"tum: \S+ emitted tone (\d): (\d+) scheduled, (\d+) missed .*?, (\d+) refused.*, (\d+) late", text)
        if m:
            emitted[ident] = dict(tone=int(m.group(1)), scheduled=int(m.group(2)), missed=int(m.group(3)),
                                  refused=int(m.group(4)), late=int(m.group(5)))
    elected = roles.get(device1)
    paired = {m.group(1): float(m.group(2)) for m in re.finditer(r"tum: recordings pair (\S+)'s audio clock at ([-0-9.e]+) s",
                                                               logs.get(elected[0] if elected else device1, ""))}

    print("== 5/6 locus eval --metric tum: live", flush=True)
    est = os.path.join(out, "estimates.jsonl")
    shutil.copy(os.path.join(out, "nodes", (elected[0] if elected else device1) + ".jsonl"), est)
    live_text, live = evaluate(locus, room_out, est, os.path.join(out, "eval.json"))
    print(live_text, end="")
    print(f"== 6/6 the same layout replayed: locus replay {replay_scene} -c config/tum.yaml", flush=True)
    replay_est = os.path.join(out, "replay.jsonl")
    r = subprocess.run([locus, "replay", replay_scene, "-c", os.path.join(ROOT, "config", "tum.yaml"), "--speed", "max", "-o",
                        replay_est], capture_output=True, text=True)
    if r.returncode != 0:
        raise Failure(f"locus replay {replay_scene} failed ({r.returncode}): {r.stderr[-2000:]}")
    replay_text, replay = evaluate(locus, replay_scene, replay_est, os.path.join(out, "replay_eval.json"))
    print(replay_text, end="")

    # Truth of the audio clocks: the run's scene (the room wrote it from the node origins and the skews).
    with open(os.path.join(room_out, "scene.yaml")) as f:
        run_scene = yaml.safe_load(f)
    clocks = run_scene["truth"]["clocks"]
    origin_room = float(run_scene["environment"]["room_origin_monotonic_s"])

    def local(ident, t_room):
        c = clocks[ident]
        return t_room * (1.0 + float(c.get("skew_ppm", 0.0)) * 1e-6) + float(c.get("offset_s", 0.0))
    ests = [e for e in read_jsonl(est) if e.get("type") == "estimate"]
    t_mid_room = None
    if ests and elected:  # the middle of the run on room time
        c1 = clocks[elected[0]]
        t_mid_local = statistics.median(e["t_s"] for e in ests)
        t_mid_room = (t_mid_local - float(c1.get("offset_s", 0.0))) / (1.0 + float(c1.get("skew_ppm", 0.0)) * 1e-6)
    # The pairing's offset is a device's tone-1 arrival minus device 1's own (both on their clocks): the
    # clock offset plus the path from device 1's speaker to the device (origins here: +-0.2 ms).
    positions = {}
    if t_mid_room is not None:
        with open(os.path.join(room_out, run_scene["truth"]["trajectories"])) as f:
            for r in csv.DictReader(f):
                ident, t = r["id"], float(r["t"])
                if ident not in positions or abs(t - t_mid_room) < abs(positions[ident][0] - t_mid_room):
                    positions[ident] = (t, [float(r["x"]), float(r["y"]), float(r["z"])])
    c = float(run_scene.get("speed_of_sound") or 343.0)
    clock_rows = []
    for ident, off in paired.items():
        truth = local(ident, t_mid_room) - local(elected[0], t_mid_room) if t_mid_room is not None else float("nan")
        path = (sum((a - b) ** 2 for a, b in zip(positions[ident][1], positions[elected[0]][1])) ** 0.5 / c
                if ident in positions and elected[0] in positions else float("nan"))
        clock_rows.append(dict(device=ident, paired_s=off, truth_s=truth, path_s=path,
                               error_ms=(off - truth - path) * 1e3))

    # Latency: a tone's emission (device 1's audio clock, via its origin) -> its estimates on the map.
    latencies = []
    if elected and elected[0] in origins:
        c1 = clocks[elected[0]]
        for now, msg in events:
            ev = msg["event"]
            if ev.get("type") == "estimate":
                t_room = (ev["t_s"] - float(c1.get("offset_s", 0.0))) / (1.0 + float(c1.get("skew_ppm", 0.0)) * 1e-6)
                latencies.append((now - (origin_room + t_room) * 1e9) / 1e6)
    with open(os.path.join(out, "map_events.jsonl"), "w") as f:
        for now, msg in events:
            f.write(json.dumps({"monotonic_ns": now, "message": msg}) + "\n")

    def fmt(v, unit="", k=1.0, digits=1):
        return "n/a" if v is None else f"{v * k:.{digits}f}{unit}"
    print(f"live vs replay (Eq. 23): median {fmt(live.get('median_error_m'), ' cm', 100)} / "
          f"{fmt(replay.get('median_error_m'), ' cm', 100)}, p90 {fmt(live.get('p90_error_m'), ' cm', 100)} / "
          f"{fmt(replay.get('p90_error_m'), ' cm', 100)}, located {live.get('targets_located')}/{live.get('targets_expected')} / "
          f"{replay.get('targets_located')}/{replay.get('targets_expected')}, snapshots {live.get('snapshots')} / "
          f"{replay.get('snapshots')}")
    agree = len({v for v in roles.values()}) == 1
    print(f"election: {elected[0] + ' (device 1), ' + elected[1] if elected else 'none'}; every node the same: "
          f"{'yes' if agree else 'no: ' + str(roles)}; the replay's: {emitters[0]}, {emitters[1]}")
    if sync:
        rtts = [s["rtt_ms"] for s in sync]
        offs = [abs(s["offset_s"]) * 1e3 for s in sync]
        print(f"link sync ({len(sync)} directed pairs): RTT median {statistics.median(rtts):.2f} ms (max {max(rtts):.2f}); "
              f"host-clock offset found |median| {statistics.median(offs):.3f} ms (max {max(offs):.3f}) vs truth 0 "
              "(one machine, one CLOCK_MONOTONIC)")
    for row in clock_rows:
        print(f"audio clock of {row['device']} vs {elected[0]}: paired from the recordings {row['paired_s']:.6f} s = room "
              f"truth {row['truth_s']:.6f} s + path {row['path_s'] * 1e3:.2f} ms {row['error_ms']:+.3f} ms")
    for ident, e in emitted.items():
        print(f"emissions of {ident} (tone {e['tone']}): {e['scheduled']} scheduled, {e['missed']} missed, "
              f"{e['refused']} refused, {e['late']} late")
    if latencies:
        print(f"latency, tone emission -> estimate on the map: {len(latencies)} estimates, median "
              f"{statistics.median(latencies):.0f} ms, max {max(latencies):.0f} ms")
    else:
        print("latency: no estimate reached the map")
    node_cpu = {k[len('locusd '):]: v for k, v in cpu.items() if k.startswith("locusd ")}
    print("CPU (% of one core over {:.1f} s) / peak RSS: ".format(wall) +
          ", ".join(f"{k} {node_cpu[k]:.1f} % {peak_rss['locusd ' + k]:.0f} MB" for k in node_cpu) +
          f"; room {cpu['room']:.1f} % {peak_rss['room']:.0f} MB, jackd {cpu['jackd']:.1f} %, mosquitto {cpu['mosquitto']:.1f} %")
    print(f"xruns: nodes' playback {sum(xruns.values())}, frames lost {sum(lost.values())}; {room_summary}")
    result = {
        "localizer": "tum", "layout": what, "seed": args.seed, "track": None if args.scene else args.track,
        "duration_s": duration, "live": live, "replay": replay, "roles": roles, "elected": elected,
        "expected_election": emitters[:2], "sync": sync, "audio_clocks": clock_rows, "emissions": emitted,
        "latency_ms": latencies, "cpu_pct_of_one_core": cpu, "peak_rss_mb": peak_rss, "node_playback_xruns": xruns,
        "node_frames_lost": lost, "room": room_summary, "map_url": map_url, "field_note": note, "out": out,
    }
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result
