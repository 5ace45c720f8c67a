"""`./run hil locble` (tools/hil/hil.py locble, docs/room.md "LocBLE"): LocBLE live over real BlueZ
(dbusmock) and a fake IIO IMU.

The layout is a LocBLE scene (`locus simulate locble --seed N`, or --scene DIR of the family). Started
and stopped here (hil_common.Run: own process groups, SIGTERM then SIGKILL on every exit path):
  - a private D-Bus system bus (dbus-daemon, its config and socket in the run directory),
  - python3-dbusmock's `bluez5` template as bluetoothd on it,
  - mosquitto (the node's link),
  - `locus feed LAYOUT DEVICE` (tools/feed): the observer's imu.csv into a fake IIO device (sysfs tree +
    FIFO) and every tag's advertisements (ble.csv) as RSSI changes of its org.bluez.Device1 object, in
    real time on the scene's clock; it starts the clock once the node reads the IMU and discovers,
  - one `locusd` board: `bluez` BLE source, `iio` IMU, `steps` + `attitude` detectors and the `locble`
    localizer of config/locble.yaml, MQTT link, the live map (`--http`, its URL printed).
After the scene, the node is stopped (its final estimates), then everything else. The run's truth is the
layout with the observer's clock replaced by the one the feed played it on (CLOCK_MONOTONIC: the node's
device-local time live), so `locus eval --metric locble` scores the live estimates as it scores a replay;
the same scene replayed (`locus replay LAYOUT -c config/locble.yaml --speed max`) is scored too.

Figures: live vs replay mean final error; advertisements fed vs `ble_advertisement` events the node
produced vs what its bluez source counted; latency (the last advertisement fed -> the last estimate update
on the map, and each update's data time -> the map); the node's CPU and peak RSS.
"""
import json
import os
import re
import shutil
import statistics
import subprocess
import threading
import time

import yaml

from hil_common import Failure, family_layout, read_jsonl, rss_mb, start_map_node, start_mosquitto, wait_for, watch

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
TOOLS = ("dbus-daemon", "mosquitto")

BUS_CONF = """<!DOCTYPE busconfig PUBLIC "-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN"
 "http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd">
<busconfig>
  <type>system</type>
  <listen>unix:path={socket}</listen>
  <auth>EXTERNAL</auth>
  <policy context="default">
    <allow user="*"/>
    <allow own="*"/>
    <allow send_type="method_call"/>
    <allow send_type="signal"/>
    <allow send_type="method_return"/>
    <allow send_type="error"/>
    <allow receive_type="method_call"/>
    <allow receive_type="signal"/>
    <allow receive_type="method_return"/>
    <allow receive_type="error"/>
  </policy>
</busconfig>
"""


def check_tools():
    """'' or what is missing (tools/install-deps.sh installs each)."""
    for tool in TOOLS:
        if shutil.which(tool) is None:
            return f"{tool} not found (tools/install-deps.sh installs it)"
    r = subprocess.run(["/usr/bin/python3", "-c", "import dbusmock"], capture_output=True, text=True)
    if r.returncode != 0:
        return "python3-dbusmock not found (/usr/bin/python3 -c 'import dbusmock'; tools/install-deps.sh installs it)"
    return ""


def layout_for(args, locus, out):
    """The layout: --scene DIR as given, else `locus simulate locble --seed N`; its observer (the device
    with a ble stream) and the scene."""
    layout, scene = family_layout(locus, "locble", out, args.seed, args.scene)
    observers = [d for d in scene.get("devices") or [] if d.get("ble") and d.get("imu")]
    if not observers:
        raise Failure(f"{layout}/scene.yaml: no device with both a ble and an imu stream (devices[].ble, devices[].imu): "
                      "not a LocBLE scene")
    return layout, scene, observers[0]["id"]


def node_config(observer, iio_root, adapter, mqtt_port, out_jsonl):
    """config/locble.yaml's detectors and localizer on a live board: bluez + iio, MQTT link."""
    with open(os.path.join(ROOT, "config", "locble.yaml")) as f:
        replay = yaml.safe_load(f)
    template = next(d for d in replay["devices"] if d["id"] == "*")
    localizers = replay["localizers"]
    for loc in localizers:
        if loc["plugin"] == "locble":
            loc.setdefault("params", {})["device"] = observer
    return {
        "log_level": "info",
        "output": {"path": out_jsonl, "events": ["estimate", "ble_advertisement"]},
        "link": {"type": "mqtt", "params": {"host": "127.0.0.1", "port": mqtt_port, "connect_timeout_s": 10}},
        "devices": [{
            "id": observer,
            "imu": {"source": "iio", "params": {"root": iio_root, "device": "lsm6dsl", "mode": "buffered"}},
            "ble": {"source": "bluez", "params": {"adapter": adapter}},
            "detectors": template["detectors"],
        }],
        "localizers": localizers,
    }


def run_scene(layout, scene, observer, base_s, speed, run_dir):
    """The run's truth: the layout with the observer's clock on CLOCK_MONOTONIC. The feed played scene
    local time t at base + t / speed; local = true * (1 + skew) + offset, so live
    monotonic = true * (1 + skew) / speed + offset / speed + base."""
    shutil.rmtree(run_dir, ignore_errors=True)
    shutil.copytree(layout, run_dir)
    clocks = scene.setdefault("truth", {}).setdefault("clocks", {})
    c = clocks.get(observer) or {}
    offset, skew = float(c.get("offset_s", 0.0)), float(c.get("skew_ppm", 0.0))
    clocks[observer] = {"offset_s": base_s + offset / speed, "skew_ppm": ((1.0 + skew * 1e-6) / speed - 1.0) * 1e6}
    with open(os.path.join(run_dir, "scene.yaml"), "w") as f:
        yaml.safe_dump(scene, f, sort_keys=False)
    return run_dir


def evaluate(locus, scene_dir, est, json_out):
    """`locus eval --metric locble`: (printed table, summary dict, per-target list)."""
    r = subprocess.run([locus, "eval", scene_dir, est, "--metric", "locble"], capture_output=True, text=True)
    if r.returncode not in (0, 4):
        raise Failure(f"locus eval {scene_dir} {est} failed ({r.returncode}): {r.stderr}")
    subprocess.run([locus, "eval", scene_dir, est, "--metric", "locble", "--json", "--json-output", json_out],
                   capture_output=True, text=True)
    with open(json_out) as f:
        plugin = next(p for p in json.load(f)["plugins"] if p.get("metric") == "locble")
    return r.stdout, plugin["summary"], plugin["targets"]


def feed_said(log, pattern):
    with open(log) as f:
        return re.search(pattern, f.read())


def hil_locble(args, bin_dir, out, run):
    from map_measure import cpu_s  # tools/scripts (hil_common puts it on the path)
    locus, locusd = os.path.join(bin_dir, "locus"), os.path.join(bin_dir, "locusd")
    os.makedirs(os.path.join(out, "logs"), exist_ok=True)
    what = f"--scene {args.scene}" if args.scene else f"locus simulate locble --seed {args.seed}"
    print(f"== 1/5 layout: {what}", flush=True)
    layout, scene, observer = layout_for(args, locus, out)
    tags = {e["id"]: x["address"] for e in scene.get("emitters") or [] for x in e.get("emits") or [] if x.get("type") == "ble"}
    print(f"   observer {observer}, tags {', '.join(f'{k} ({v})' for k, v in tags.items())}", flush=True)

    print("== 2/5 private system bus (dbus-daemon), dbusmock bluez5 as bluetoothd, mosquitto", flush=True)
    sock = os.path.join(out, "system_bus.sock")
    with open(os.path.join(out, "bus.conf"), "w") as f:
        f.write(BUS_CONF.format(socket=sock))
    bus = run.start("dbus-daemon", ["dbus-daemon", "--config-file=" + os.path.join(out, "bus.conf"), "--nofork", "--nopidfile"])
    wait_for(lambda: os.path.exists(sock), 20, "the private dbus-daemon's socket", [("dbus-daemon", bus)])
    env = dict(os.environ, DBUS_SYSTEM_BUS_ADDRESS="unix:path=" + sock)
    mock = run.start("bluetoothd-dbusmock", ["/usr/bin/python3", "-m", "dbusmock", "--system", "--template", "bluez5",
                                               "--logfile", os.path.join(out, "logs", "dbusmock-calls.log")], env=env)
    mqtt_port, broker = start_mosquitto(run, out)

    print(f"== 3/5 locus feed (IMU -> fake IIO, advertisements -> BlueZ, speed {args.speed}); one locusd board "
          "(bluez, iio, steps, attitude, locble, MQTT link, live map)", flush=True)
    iio_root = os.path.join(out, "iio")
    shutil.rmtree(iio_root, ignore_errors=True)
    feed_log = os.path.join(out, "logs", "feed.out")
    feed = run.start("feed", [locus, "feed", layout, observer, "--iio-root", iio_root, "--adapter", "hci0",
                              "--speed", str(args.speed)], env=env, stdout=open(feed_log, "w"))
    wait_for(lambda: feed_said(feed_log, r"feed: ready"), 30, "locus feed's IIO device and BlueZ tags",
             [("feed", feed), ("dbusmock", mock), ("dbus-daemon", bus)])
    node_out = os.path.join(out, "node.jsonl")
    cfg_path = os.path.join(out, "node.yaml")
    with open(cfg_path, "w") as f:
        yaml.safe_dump(node_config(observer, iio_root, "hci0", mqtt_port, node_out), f, sort_keys=False)
    cmd = [locusd, "--config", cfg_path]
    events, stop_sse = [], threading.Event()
    map_url = None
    if args.map != "off":
        node, map_url = start_map_node(run, "node", cmd, env, args.map, f"HIL: locble live ({what})", events, stop_sse,
                                       f"{out}/logs/node.log")
    else:
        node = run.start("node", cmd, env=env)
    alive = [("locusd", node), ("feed", feed), ("dbusmock", mock), ("dbus-daemon", bus), ("mosquitto", broker)]
    wait_for(lambda: feed_said(feed_log, r"scene time 0 at CLOCK_MONOTONIC"), 60,
             "the node to open its IIO buffer and start discovery (locus feed starts the clock then)", alive)
    base_s = float(feed_said(feed_log, r"scene time 0 at CLOCK_MONOTONIC ([0-9.]+) s").group(1))
    pids = {"locusd": node.pid, "feed": feed.pid, "dbusmock": mock.pid, "dbus-daemon": bus.pid, "mosquitto": broker.pid}
    t0 = time.monotonic()
    cpu0 = {k: cpu_s(p) for k, p in pids.items()}
    peak_rss = {k: 0.0 for k in pids}
    # the scene plays; then one update period (1 s of data time) and a margin for the last estimates
    while not feed_said(feed_log, r"feed: (done|interrupted)"):
        watch(pids, peak_rss, alive, "the scene", out)
        time.sleep(0.1)
    done = feed_said(feed_log, r"feed: (done|interrupted) (.*)")
    fed = {k: float(v) for k, v in re.findall(r"(\w+)=([-0-9.naninf]+)", done.group(2))}
    if done.group(1) != "done":
        raise Failure(f"locus feed was interrupted: {done.group(2)}")
    settle_end = time.monotonic() + args.settle
    while time.monotonic() < settle_end:
        for k, p in pids.items():
            try:
                peak_rss[k] = max(peak_rss[k], rss_mb(p)[0])
            except (FileNotFoundError, ProcessLookupError):
                pass
        time.sleep(0.1)
    wall = time.monotonic() - t0
    cpu = {k: 100.0 * (cpu_s(p) - cpu0[k]) / wall for k, p in pids.items()}

    print("== 4/5 stop the node (its final estimates), the feed, mosquitto, bluetoothd, the bus", flush=True)
    stop_sent_ns = time.monotonic_ns()
    rc = run.stop("node")  # SIGTERM: the localizer's final update goes out (and to the map) as it stops
    stop_sse.set()
    if rc != 0:
        raise Failure(f"locusd exited with {rc}; see {out}/logs/node.log")
    with open(os.path.join(out, "logs", "node.log")) as f:
        node_log = f.read()
    for name in ("feed", "mosquitto", "bluetoothd-dbusmock", "dbus-daemon"):
        run.stop(name)

    print("== 5/5 locus eval --metric locble: live, then the same scene replayed", flush=True)
    lines = read_jsonl(node_out)
    est_path = os.path.join(out, "estimates.jsonl")
    with open(est_path, "w") as f:
        for e in lines:
            if e.get("type") == "estimate":
                f.write(json.dumps(e) + "\n")
    adverts = [e for e in lines if e.get("type") == "ble_advertisement"]
    truth_dir = run_scene(layout, scene, observer, base_s, args.speed, os.path.join(out, "run"))
    table, live, live_targets = evaluate(locus, truth_dir, est_path, os.path.join(out, "eval_live.json"))
    print(table, end="")
    replay_est = os.path.join(out, "replay.jsonl")
    r = subprocess.run([locus, "replay", layout, "-c", os.path.join(ROOT, "config", "locble.yaml"), "--speed", "max",
                        "-o", replay_est], capture_output=True, text=True)
    if r.returncode != 0:
        raise Failure(f"locus replay {layout} failed ({r.returncode}): {r.stderr}")
    _, rep, rep_targets = evaluate(locus, layout, replay_est, os.path.join(out, "eval_replay.json"))

    # delivery: what the feed set, what the node's bluez source read, what reached its output
    m = re.search(r"(\d+) adverts?, (\d+) dropped", node_log)
    scanner = {"adverts": int(m.group(1)), "dropped": int(m.group(2))} if m else None
    # latency: the last advertisement fed -> the last estimate update on the map. LocBLE updates every
    # update_period_s of data time and once more when it stops; the scene's IMU ends with its last
    # advertisement, so the update that includes it is the final one, published when the node is
    # stopped (--settle s after the scene's end): the figure is split into that wait and the stop.
    # Every update's data time (its t_s: CLOCK_MONOTONIC live) -> its arrival on the map, too.
    on_map = [(now, msg["event"]) for now, msg in events if msg["event"].get("type") == "estimate"]
    last_fed_ns = fed["last_advert_monotonic_s"] * 1e9
    last_on_map_ns = max(now for now, _ in on_map) if on_map else None
    last_latency_ms = (last_on_map_ns - last_fed_ns) / 1e6 if on_map else None
    stop_to_map_ms = (last_on_map_ns - stop_sent_ns) / 1e6 if on_map and last_on_map_ns >= stop_sent_ns else None
    data_to_map_ms = sorted((now - e["t_s"] * 1e9) / 1e6 for now, e in on_map if now < stop_sent_ns)  # periodic ones
    result = {
        "localizer": "locble", "layout": layout, "seed": None if args.scene else args.seed, "speed": args.speed,
        "observer": observer, "tags": len(tags),
        "live": {"located": live.get("targets_located"), "expected": live.get("targets_expected"),
                 "mean_error_m": live.get("mean_error_m"),
                 "final_error_m": {t["target"]: t.get("final_error_m") for t in live_targets}},
        "replay": {"located": rep.get("targets_located"), "expected": rep.get("targets_expected"),
                   "mean_error_m": rep.get("mean_error_m"),
                   "final_error_m": {t["target"]: t.get("final_error_m") for t in rep_targets}},
        "adverts_in_scene": int(fed["advert_rows"]), "adverts_fed": int(fed["adverts_fed"]),
        "adverts_failed": int(fed["adverts_failed"]), "ble_advertisement_events": len(adverts),
        "scanner": scanner, "imu_scans_written": int(fed["imu_written"]), "imu_rows": int(fed["imu_rows"]),
        "feed_lateness_ms": {"imu_median": fed["imu_late_median_ms"], "imu_max": fed["imu_late_max_ms"],
                             "ble_median": fed["ble_late_median_ms"], "ble_max": fed["ble_late_max_ms"]},
        "latency_last_advert_to_last_update_ms": last_latency_ms,
        "latency_last_advert_to_stop_ms": (stop_sent_ns - last_fed_ns) / 1e6, "latency_stop_to_final_update_ms": stop_to_map_ms,
        "estimates_written": sum(1 for e in lines if e.get("type") == "estimate"),
        "latency_update_data_time_to_map_ms": data_to_map_ms, "estimates_on_map": len(on_map),
        "cpu_pct_of_one_core": cpu, "peak_rss_mb": peak_rss, "wall_s": wall, "map_url": map_url, "out": out,
    }
    with open(os.path.join(out, "map_events.jsonl"), "w") as f:
        for now, msg in events:
            f.write(json.dumps({"monotonic_ns": now, "message": msg}) + "\n")

    def m_(v):
        return "-" if v is None else f"{v:.2f} m"
    print(f"live vs replay (same scene, config/locble.yaml): located {live.get('targets_located')}/{live.get('targets_expected')} "
          f"vs {rep.get('targets_located')}/{rep.get('targets_expected')}, mean final error {m_(live.get('mean_error_m'))} "
          f"vs {m_(rep.get('mean_error_m'))}")
    lost = result["adverts_fed"] - len(adverts)
    print(f"advertisements: {result['adverts_in_scene']} in ble.csv, {result['adverts_fed']} fed through BlueZ "
          f"({result['adverts_failed']} failed), {len(adverts)} ble_advertisement events from the node"
          + (f" (its bluez source: {scanner['adverts']} read, {scanner['dropped']} dropped)" if scanner else "")
          + (", none lost" if lost == 0 and result["adverts_failed"] == 0 else f", {lost} lost"))
    print(f"IMU: {result['imu_scans_written']} of {result['imu_rows']} scans written; feed lateness median/max "
          f"IMU {fed['imu_late_median_ms']:.2f}/{fed['imu_late_max_ms']:.2f} ms, BLE {fed['ble_late_median_ms']:.2f}/"
          f"{fed['ble_late_max_ms']:.2f} ms")
    if on_map:
        if stop_to_map_ms is not None:
            print(f"latency: last advertisement fed -> last estimate update on the map {last_latency_ms:.0f} ms (the node "
                  f"stopped {result['latency_last_advert_to_stop_ms']:.0f} ms after it, its final update on the map "
                  f"{stop_to_map_ms:.0f} ms after the stop"
                  + f"); {len(on_map)} of {result['estimates_written']} estimates on the map")
        else:
            print(f"latency: the final update (at the stop, {result['latency_last_advert_to_stop_ms']:.0f} ms after the last "
                  f"advertisement) did not reach the map before it closed ({len(on_map)} of {result['estimates_written']} "
                  f"estimates on it); the last one on it came {abs(last_latency_ms):.0f} ms "
                  f"{'after' if last_latency_ms >= 0 else 'before'} the last advertisement")
        print("latency: each periodic update's data time -> map: "
              + (f"median {statistics.median(data_to_map_ms):.1f} ms, max {max(data_to_map_ms):.1f} ms" if data_to_map_ms else "none"))
    else:
        print("latency: no estimate reached the map")
    print(f"CPU (% of one core over {wall:.1f} s): locusd {cpu['locusd']:.1f}, feed {cpu['feed']:.1f}, bluetoothd (dbusmock) "
          f"{cpu['dbusmock']:.1f}, dbus-daemon {cpu['dbus-daemon']:.1f}, mosquitto {cpu['mosquitto']:.1f}; peak RSS: locusd "
          f"{peak_rss['locusd']:.0f} MB, feed {peak_rss['feed']:.0f} MB, dbusmock {peak_rss['dbusmock']:.0f} MB")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result
