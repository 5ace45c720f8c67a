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


def watch(pids, peak_rss, alive, during, out):
    """One look at a running HIL: each process's peak RSS (MB, in `peak_rss` by name) and a Failure naming
    the first of `alive` ((name, Popen)) that exited `during` what (see OUT/logs)."""
    for k, p in pids.items():
        try:
            peak_rss[k] = max(peak_rss[k], rss_mb(p)[0])
        except (FileNotFoundError, ProcessLookupError):
            pass
    for name, p in alive:
        if p.poll() is not None:
            raise Failure(f"{name} exited ({p.returncode}) during {during}; see {out}/logs")
