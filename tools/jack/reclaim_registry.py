#!/usr/bin/env python3
"""Free the JACK server registry slots that dead servers still hold.

Why: JACK2 keeps at most 8 servers in /dev/shm/jack-shm-registry. A jackd that ends by SIGKILL (a
crash, a timed-out test, `kill -9`) never unregisters, and JACK reclaims a dead entry only when a
server of the *same name* starts again. Servers with one-off names (locus_rec_<pid>, ...) therefore
leak a slot each, and after eight of them every jackd on the machine fails with "Too many servers
already active" until someone deletes the registry by hand.

How: JACK's own reclaim path, not an edit of its shared memory. For every registered server whose
process is gone, start `jackd -n <that name>` (dummy driver): it reclaims the dead entry under JACK's
registry lock and registers itself; then stop it with SIGTERM, which unregisters it cleanly. Entries of
live servers and of other users are listed and left alone.

Usage: reclaim_registry.py [--list] [--if-full] [--prefix P] [--registry PATH] [--jackd PATH]
  --list     print the registry (slot, pid, alive, name) and change nothing
  --if-full  reclaim only when every slot is taken
  --prefix P reclaim only dead servers whose name starts with P (the tests use locus_: a user's own
             dead servers are theirs to deal with)
Exit status: 0 when nothing was left to reclaim, 1 when a dead entry could not be reclaimed (the
reason is printed), 2 for a registry this script does not understand (path and field named).
"""
import argparse
import os
import signal
import struct
import subprocess
import sys
import time

MAGIC = 0x4A41434B  # "JACK" as jack2 writes it (little-endian "KCAJ")
HEADER = struct.Struct("<IHHiiii")  # magic, protocol, pad, type, size, hdr_len, entry_len
SERVER_PID = struct.Struct("<i")
MAX_SERVERS = 8  # jack2 common/shm.h


class RegistryError(Exception):
    pass


def read_servers(path):
    """[(slot, pid, prefix)] of the occupied server slots; [] when there is no registry."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        return []
    if len(data) < HEADER.size:
        raise RegistryError(f"{path}: {len(data)} bytes, shorter than JACK's {HEADER.size}-byte header")
    magic, _protocol, _pad, _type, _size, hdr_len, _entry_len = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise RegistryError(f"{path}: magic 0x{magic:08x}, expected 0x{MAGIC:08x} (a jack2 registry)")
    slot_len = (hdr_len - HEADER.size) // MAX_SERVERS
    if slot_len <= SERVER_PID.size or HEADER.size + MAX_SERVERS * slot_len > len(data):
        raise RegistryError(f"{path}: hdr_len {hdr_len} does not hold {MAX_SERVERS} server slots")
    servers = []
    for slot in range(MAX_SERVERS):
        off = HEADER.size + slot * slot_len
        (pid,) = SERVER_PID.unpack_from(data, off)
        raw = data[off + SERVER_PID.size: off + slot_len].split(b"\0", 1)[0]
        if pid != 0:
            servers.append((slot, pid, raw.decode("utf-8", "replace")))
    return servers


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def server_name(prefix):
    """'jack-<uid>:<name>:' -> (uid, name), or None for a prefix of another shape."""
    parts = prefix.split(":")
    if len(parts) < 3 or not parts[0].startswith("jack-") or not parts[0][5:].isdigit():
        return None
    return int(parts[0][5:]), ":".join(parts[1:-1])


def reclaim(name, registry, jackd, timeout_s=10.0):
    """Start and cleanly stop a jackd named `name`; returns None on success, else the reason."""
    proc = subprocess.Popen([jackd, "-n", name, "-r", "-d", "dummy", "-r", "44100", "-p", "1024"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + timeout_s
    registered = False
    while time.monotonic() < deadline and proc.poll() is None:
        if any(pid == proc.pid for _, pid, _ in read_servers(registry)):
            registered = True
            break
        time.sleep(0.05)
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            return f"jackd -n {name} did not stop within {timeout_s:.0f} s of SIGTERM (killed: the slot leaks again)"
    out = proc.stdout.read().decode("utf-8", "replace").strip().splitlines()
    if not registered:
        return f"jackd -n {name} did not register (exit {proc.returncode}): {' | '.join(out[:3])}"
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--if-full", action="store_true")
    ap.add_argument("--prefix", default="")
    ap.add_argument("--registry", default="/dev/shm/jack-shm-registry")
    ap.add_argument("--jackd", default="jackd")
    a = ap.parse_args()
    try:
        servers = read_servers(a.registry)
    except RegistryError as e:
        print(f"reclaim_registry: {e}", file=sys.stderr)
        return 2
    for slot, pid, prefix in servers:
        print(f"slot {slot}: pid {pid} {'alive' if alive(pid) else 'dead'} {prefix}")
    if a.list:
        return 0
    if a.if_full and len(servers) < MAX_SERVERS:
        print(f"{len(servers)} of {MAX_SERVERS} slots taken: nothing to do")
        return 0
    status = 0
    reclaimed = 0
    for slot, pid, prefix in servers:
        if alive(pid):
            continue
        parsed = server_name(prefix)
        if parsed is None or parsed[0] != os.getuid():
            print(f"slot {slot}: dead server {prefix!r} is not this user's (uid {os.getuid()}): left alone")
            continue
        if not parsed[1].startswith(a.prefix):
            continue
        why = reclaim(parsed[1], a.registry, a.jackd)
        if why:
            print(f"slot {slot}: {why}", file=sys.stderr)
            status = 1
        else:
            reclaimed += 1
            print(f"slot {slot}: reclaimed dead server '{parsed[1]}' (pid {pid})")
    left = len(read_servers(a.registry))
    print(f"reclaimed {reclaimed}; {left} of {MAX_SERVERS} slots taken now")
    return status


if __name__ == "__main__":
    sys.exit(main())
