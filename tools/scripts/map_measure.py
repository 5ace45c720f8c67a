#!/usr/bin/python3
"""Measures the live map during a real-time replay (docs/map.md, "Measured").

Replays a scene through `locusd --scene ... --speed realtime`, once without the map and once with
`--http` and the page open in headless Chromium plus an SSE client of our own, and reports:
  - latency: for every estimate (and every audio detection, more samples of the same path), the time from its hand-over to the map (`mono_ns` in the stream, the
    CLOCK_MONOTONIC time the pipeline's dispatcher handed it over, i.e. when the localizer published it)
    to its arrival at this script's SSE client (time.monotonic_ns(), same clock, same machine);
  - locusd's CPU time (user + system, % of one core over the replay's wall time) and its peak RSS
    (VmHWM), from /proc, for both runs.

    tools/scripts/map_measure.py --bin build/bin --config config/amil.yaml --gestures 3 --seed 1

Every process it starts is killed at the end, also on failure.
"""
import argparse
import http.client
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from campaign_common import kill_group

TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime + stime


def hwm_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def sse_client(host, port, latencies, stop, on_event=None):
    """Reads the map's /events until `stop`: appends (event type, ms from its hand-over to its arrival
    here) to `latencies` and, when given, calls on_event(message, arrival CLOCK_MONOTONIC ns)."""
    conn = http.client.HTTPConnection(host, port, timeout=30)
    conn.request("GET", "/events")
    resp = conn.getresponse()
    event, data = None, None
    while not stop.is_set():
        line = resp.readline()
        if not line:
            break
        now = time.monotonic_ns()
        line = line.decode().rstrip("\n")
        if line.startswith("event: "):
            event = line[7:]
        elif line.startswith("data: "):
            data = line[6:]
        elif line == "":
            if event == "locus" and data:
                msg = json.loads(data)
                latencies.append((msg["event"]["type"], (now - msg["mono_ns"]) / 1e6))
                if on_event is not None:
                    on_event(msg, now)
            event, data = None, None


def run(args, scene, with_map, tmp):
    cmd = [os.path.join(args.bin, "locusd"), "--config", args.config, "--scene", scene, "--speed", "realtime",
           "-o", os.path.join(tmp, "est.jsonl")]
    if with_map:
        cmd += ["--http", "127.0.0.1:0", "--http-param", "linger_s=30"]
    locusd = browser = None
    latencies, stop = [], threading.Event()
    try:
        t0 = time.monotonic()
        locusd = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                  start_new_session=True)
        reader = None
        if with_map:
            url = locusd.stdout.readline().split(" ", 1)[1].strip()
            host, port = url[len("http://"):].rstrip("/").rsplit(":", 1)
            reader = threading.Thread(target=sse_client, args=(host, int(port), latencies, stop), daemon=True)
            reader.start()
            chromium = shutil.which("chromium")
            if chromium:
                browser = subprocess.Popen([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                                            f"--user-data-dir={tmp}/profile", "--window-size=1280,800",
                                            "--remote-debugging-port=0", url],
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
            # The replay is over when the state says so (then locusd lingers: read /proc before it exits).
            while True:
                conn = http.client.HTTPConnection(host, int(port), timeout=10)
                conn.request("GET", "/api/state")
                state = json.loads(conn.getresponse().read())
                if state["finished"]:
                    break
                time.sleep(0.2)
            wall = time.monotonic() - t0
            cpu, hwm = cpu_s(locusd.pid), hwm_mb(locusd.pid)
            time.sleep(0.5)
        else:
            # Sample while it runs; the last sample before exit is the figure.
            cpu = hwm = 0.0
            while locusd.poll() is None:
                try:
                    cpu, hwm = cpu_s(locusd.pid), hwm_mb(locusd.pid)
                except (FileNotFoundError, ProcessLookupError, IndexError):
                    break
                time.sleep(0.05)
            wall = time.monotonic() - t0
        return wall, cpu, hwm, latencies
    finally:
        stop.set()
        kill_group(browser)
        kill_group(locusd)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="build/bin")
    ap.add_argument("--config", default="config/amil.yaml")
    ap.add_argument("--seed", default="1")
    ap.add_argument("--gestures", default="3")
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="locus-map-measure-")
    try:
        scene = os.path.join(tmp, "scene")
        subprocess.run([os.path.join(args.bin, "locus"), "simulate", "amil", scene, "--seed", args.seed, "-o",
                        f"gestures={args.gestures}"], check=True, stdout=subprocess.DEVNULL)
        base = run(args, scene, False, tmp)
        mapped = run(args, scene, True, tmp)
        lat = sorted(ms for t, ms in mapped[3] if t == "estimate")
        det = sorted(ms for t, ms in mapped[3] if t == "audio_detection")
        print(f"scene: locus simulate amil --seed {args.seed} -o gestures={args.gestures}; replay at realtime")
        print(f"without the map: wall {base[0]:.1f} s, locusd CPU {base[1]:.2f} s = {100 * base[1] / base[0]:.1f} % "
              f"of one core, peak RSS {base[2]:.0f} MB")
        print(f"with the map open (headless Chromium + an SSE client): wall {mapped[0]:.1f} s, locusd CPU "
              f"{mapped[1]:.2f} s = {100 * mapped[1] / mapped[0]:.1f} % of one core, peak RSS {mapped[2]:.0f} MB")
        if lat:
            print(f"estimate published -> SSE client: {len(lat)} estimates, median {statistics.median(lat):.2f} ms, "
                  f"max {lat[-1]:.2f} ms")
            if det:
                print(f"audio detection published -> SSE client: {len(det)} detections, median "
                      f"{statistics.median(det):.2f} ms, max {det[-1]:.2f} ms")
        else:
            print("no estimate reached the SSE client")
            return 1
        return 0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
