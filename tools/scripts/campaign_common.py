"""Shared by the campaign scripts (tools/scripts/*_campaign.py): seed lists, running a locus command,
percentiles. Import with the scripts' folder on sys.path (they are run as files, so it is)."""
import math
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
