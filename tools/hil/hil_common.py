"""What every hardware-in-the-loop run (tools/hil/hil.py: `./run hil NAME`, docs/room.md) shares: the
runner that starts each child process in its own process group and stops them all (SIGTERM, then
SIGKILL) on every exit path, waiting on a condition while watching the children, the broker, free
ports, per-process RSS, and reading a node's JSON-lines output while it is being written.
"""
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "scripts"))
from campaign_common import kill_group  # noqa: E402


class Failure(Exception):
    pass


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(cond, timeout_s, what, procs=()):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return
        for name, p in procs:
            if p.poll() is not None:
                raise Failure(f"{name} exited ({p.returncode}) while waiting for {what}")
        time.sleep(0.05)
    raise Failure(f"timed out after {timeout_s:.0f} s waiting for {what}")


def rss_mb(pid):
    """(VmRSS, RssShmem) in MB: the resident set, and its shared-memory part (JACK's segments,
    mapped into every client)."""
    rss = shm = float("nan")
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024.0
            elif line.startswith("RssShmem:"):
                shm = int(line.split()[1]) / 1024.0
    return rss, shm


class Run:
    """Every child process of the run, stopped in reverse order by close()."""

    def __init__(self, out):
        self.out = out
        self.procs = []  # (name, Popen)

    def start(self, name, cmd, env=None, stdout=None):
        log = open(os.path.join(self.out, "logs", name + ".log"), "w")
        p = subprocess.Popen(cmd, stdout=stdout if stdout is not None else log, stderr=log, stdin=subprocess.DEVNULL,
                             env=env, start_new_session=True, text=True)
        self.procs.append((name, p))
        return p

    def stop(self, name, timeout_s=20):
        for n, p in self.procs:
            if n == name and p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(timeout=timeout_s)
                except subprocess.TimeoutExpired:
                    kill_group(p)
                return p.returncode
        return None

    def close(self):
        for _, p in reversed(self.procs):
            kill_group(p)


def read_jsonl(path):
    out = []
    if not os.path.exists(path):
        return out
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line:
                try:
                    out.append(json.loads(line))
                except json.JSONDecodeError:
                    pass  # a line being written
    return out


def start_mosquitto(run, out):
    """mosquitto on a free loopback port (the run's own), up when this returns; its port."""
    port = free_port()
    conf = os.path.join(out, "mosquitto.conf")
    with open(conf, "w") as f:
        f.write(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
    broker = run.start("mosquitto", ["mosquitto", "-c", conf])

    def broker_up():
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", port)) == 0
    wait_for(broker_up, 20, "mosquitto", [("mosquitto", broker)])
    return port, broker


def start_map_node(run, name, cmd, env, listen, title, events, stop_sse, log_hint):
    """locusd `cmd` serving the live map at `listen` ([HOST:]PORT): started, its first stdout line
    (`map: URL`) read and printed, and an SSE client (map_measure.sse_client) appending (arrival
    CLOCK_MONOTONIC ns, message) to `events` until `stop_sse` is set. (process, url)."""
    from map_measure import sse_client
    p = run.start(name, cmd + ["--http", listen, "--http-param", f"title={title}"], env=env, stdout=subprocess.PIPE)
    line = p.stdout.readline()
    if not line.startswith("map: "):
        raise Failure(f"{name} did not serve the map: {line!r}; see {log_hint}")
    url = line.split(" ", 1)[1].strip()
    print(f"   live map (open it now): {url}", flush=True)
    host, port = url[len("http://"):].rstrip("/").rsplit(":", 1)
    threading.Thread(target=sse_client, args=(host, int(port), [], stop_sse, lambda m, now: events.append((now, m))),
                     daemon=True).start()
    return p, url


def family_layout(locus, family, out, seed, scene_dir=None, extra=()):
    """The layout of a run: `scene_dir` as given (any scene of the family), else `locus simulate FAMILY
    OUT/layout --seed SEED EXTRA...`; (its directory, scene.yaml as a dict)."""
    if scene_dir:
        layout = os.path.abspath(scene_dir)
    else:
        layout = os.path.join(out, "layout")
        cmd = [locus, "simulate", family, layout, "--seed", str(seed), "-q", *extra]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise Failure(f"{' '.join(cmd)} failed: {r.stderr}")
    path = os.path.join(layout, "scene.yaml")
    import yaml
    try:
        with open(path) as f:
            return layout, yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as e:
        raise Failure(f"--scene: cannot read {path}: {e}")


def start_jackd(run, out, server, period, realtime):
    """jackd (dummy driver, 44.1 kHz, synchronous, one period of `period` frames, SCHED_FIFO process
    threads when `realtime` and the user may) as server `server`, answering when this returns; (process,
    the environment its clients use). A full JACK server registry is named with the command that frees it."""
    env = dict(os.environ, JACK_NO_AUDIO_RESERVATION="1", JACK_DEFAULT_SERVER=server)
    rt = ["-R", "-P", "70"] if realtime else ["-r"]
    jackd = run.start("jackd", ["jackd", "-n", server, *rt, "-S", "-d", "dummy", "-r", "44100", "-p", str(period)], env=env)
    try:
        wait_for(lambda: subprocess.run(["jack_lsp", "-s", server], capture_output=True, env=env).returncode == 0, 20,
                 "jackd to answer", [("jackd", jackd)])
    except Failure as e:
        with open(os.path.join(out, "logs", "jackd.log"), errors="replace") as f:
            if "Too many servers already active" in f.read():  # JACK's registry: 8 slots, dead servers keep theirs
                raise Failure(f"{e}: JACK's server registry is full; `python3 tools/jack/reclaim_registry.py` "
                              "frees the slots that dead servers still hold (--list shows them)") from None
        raise
    return jackd, env


def node_log_figures(out, ident):
    """From logs/node-<ident>.log of a stopped locusd: (audio origin on CLOCK_MONOTONIC or None, frames
    lost or None, playback xruns or None, the log's text)."""
    import re
    with open(os.path.join(out, "logs", f"node-{ident}.log"), errors="replace") as f:
        text = f.read()
    mo = re.search(rf"device {re.escape(ident)}: audio frame 0 at CLOCK_MONOTONIC ([0-9.]+) s", text)
    ms = re.search(rf"device {re.escape(ident)}: (\d+) frames processed, (\d+) lost .*playback: (\d+) xruns", text)
    return (float(mo.group(1)) if mo else None, int(ms.group(2)) if ms else None, int(ms.group(3)) if ms else None, text)


def sample_peaks(pids, peak_rss, peak_shm=None):
    """Raises each process's peak RSS (and its shared-memory part) to what /proc shows now."""
    for k, p in pids.items():
        try:
            rss, shm = rss_mb(p)
        except (FileNotFoundError, ProcessLookupError):
            continue
        peak_rss[k] = max(peak_rss[k], rss)
        if peak_shm is not None:
            peak_shm[k] = max(peak_shm[k], shm)


def check_alive(alive, during, out):
    """Failure naming the first of `alive` ((name, Popen)...) that has exited."""
    for name, p in alive:
        if p.poll() is not None:
            raise Failure(f"{name} exited ({p.returncode}) during {during}; see {out}/logs")


def watch(pids, peak_rss, alive, during, out):
    """One look at a running HIL: each process's peak RSS (MB, in `peak_rss` by name) and a Failure naming
    the first of `alive` ((name, Popen)) that exited `during` what (see OUT/logs)."""
    sample_peaks(pids, peak_rss)
    check_alive(alive, during, out)


def stop_nodes(run, out, idents, origins_csv):
    """Stops the locusd nodes `idents` (SIGTERM; a non-zero exit is a Failure), reads each one's audio
    origin, frames lost and playback xruns from its log and writes the origins for `locus room
    --node-origins`. (origins, frames lost, xruns, log texts), by id."""
    origins, lost, xruns, logs = {}, {}, {}, {}
    for ident in idents:
        rc = run.stop("node-" + ident)
        if rc != 0:
            raise Failure(f"locusd {ident} exited with {rc}; see {out}/logs/node-{ident}.log")
        origin, frames_lost, node_xruns, logs[ident] = node_log_figures(out, ident)
        if origin is not None:
            origins[ident] = origin
        if frames_lost is not None:
            lost[ident], xruns[ident] = frames_lost, node_xruns
    with open(origins_csv, "w") as f:
        f.write("device,audio_origin_monotonic_s\n")
        for k, v in origins.items():
            f.write(f"{k},{v:.9f}\n")
    return origins, lost, xruns, logs


def stop_room(run, out, room_log):
    """Stops the room (it writes the truth; a non-zero exit is a Failure), then mosquitto and jackd;
    the room's summary line."""
    rc = run.stop("room")
    if rc != 0:
        raise Failure(f"locus room exited with {rc}; see {room_log}")
    run.stop("mosquitto")
    run.stop("jackd")
    with open(room_log) as f:
        return f.read().strip().splitlines()[-1]


class Room:
    """What start_room() started: the JACK server's name and environment, the processes, the paths."""

    def __init__(self, **kw):
        self.__dict__.update(kw)

    def said(self, pattern):
        """The first match of `pattern` in the room's output so far (or None)."""
        import re
        with open(self.log) as f:
            return re.search(pattern, f.read())


def start_room(run, out, locus, layout, args, extra=()):
    """jackd (its own server name), mosquitto and `locus room LAYOUT OUT/run` on them (the layout's skews,
    --seed, --reflections, --self-gain of `args`, the nodes' origins from OUT/node_origins.csv; `extra`
    room options), its ports and IIO trees up when this returns. A Room."""
    server = f"locus_hil_{os.getpid()}"
    jackd, env = start_jackd(run, out, server, args.period, args.realtime)
    mqtt_port, broker = start_mosquitto(run, out)
    r = Room(server=server, env=env, jackd=jackd, mqtt_port=mqtt_port, broker=broker, out=os.path.join(out, "run"),
             origins_csv=os.path.join(out, "node_origins.csv"), log=os.path.join(out, "logs", "room.out"))
    r.proc = run.start("room", [locus, "room", layout, r.out, "--server", server, "--skew", "scene", "--seed", str(args.seed),
                                "--lead-in", "2", "--reflections", str(args.reflections), "--self-gain", str(args.self_gain),
                                "--node-origins", r.origins_csv, *extra], env=env, stdout=open(r.log, "w"))
    wait_for(lambda: r.said(r"room: \d+ devices of"), 30, "the room's ports and IIO trees", [("room", r.proc)])
    return r
