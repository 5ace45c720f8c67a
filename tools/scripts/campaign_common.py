"""Shared by the campaign and measuring scripts (tools/scripts/*_campaign.py, map_measure.py) and the
map's browser test: seed lists, running a locus command, percentiles, stopping a process group, a
quaternion's rotation matrix.
Import with the scripts' folder on sys.path (scripts run as files here have it)."""
import math
import os
import signal
import subprocess
import sys


def parse_seeds(s):
    """'1-3,7' -> [1, 2, 3, 7]."""
    out = []
    for part in filter(None, s.split(',')):
        if '-' in part:
            a, b = part.split('-')
            out += list(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def run(cmd, who):
    """Runs cmd; exit 0 and 4 (bars missed, from locus eval) are results, anything else ends `who`."""
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode not in (0, 4):
        sys.exit(f"{who}: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return r


def pct(v, q):
    """Linear-interpolated quantile q (0..1) of v; NaN when empty."""
    if not v:
        return float('nan')
    v = sorted(v)
    k = (len(v) - 1) * q
    f = math.floor(k)
    c = min(f + 1, len(v) - 1)
    return v[f] + (v[c] - v[f]) * (k - f)


def kill_group(proc):
    """Stops a child started with start_new_session=True, and its children: SIGTERM to the group,
    SIGKILL after 10 s; nothing when it is None or already ended."""
    if proc is None or proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=10)
    except (subprocess.TimeoutExpired, ProcessLookupError):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


def quat_matrix(q):
    """Rotation matrix (nested lists) of a unit quaternion (w, x, y, z): body vectors into the reference frame."""
    w, x, y, z = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
