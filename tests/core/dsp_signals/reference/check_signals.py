#!/usr/bin/env python3
"""Independent check of Locus's signal generators against the scene format's definitions.

Gold codes are rebuilt with scipy.signal.max_len_seq: for a characteristic polynomial
x^r + c_{r-1}x^{r-1} + ... + c_1 x + 1 the recurrence a[n+r] = sum_i c_i a[n+i] is scipy's LFSR with
taps {i : c_i = 1, 0 < i < r} and an all-ones state. LFM uses scipy.signal.chirp (a cosine, so
phi=-90 gives the format's sine); the fade is the format's raised cosine. Exit 1 on any mismatch.
"""
import subprocess
import sys

import numpy as np
from scipy.signal import chirp, max_len_seq

DUMP = sys.argv[1]
PAIRS = {5: (0o45, 0o75), 6: (0o103, 0o147), 7: (0o211, 0o217), 9: (0o1021, 0o1131),
         10: (0o2011, 0o2415), 11: (0o4005, 0o4445)}


def run(*args):
    return subprocess.run([DUMP, *map(str, args)], check=True, capture_output=True, text=True).stdout


def mseq(r, poly):
    taps = [i for i in range(1, r) if (poly >> i) & 1]
    seq, _ = max_len_seq(r, state=np.ones(r, dtype=np.int8), taps=taps)
    return seq.astype(np.uint8)


def gold(r, k):
    u, v = (mseq(r, p) for p in PAIRS[r])
    if k == 0:
        return u
    if k == 1:
        return v
    return u ^ np.roll(v, -(k - 2))


def fade(t, d, f):
    w = np.ones_like(t)
    if f > 0:
        f = min(f, d / 2)
        a = t < f
        w[a] = 0.5 * (1 - np.cos(np.pi * t[a] / f))
        b = (d - t) < f
        w[b] = 0.5 * (1 - np.cos(np.pi * (d - t[b]) / f))
    return w


failures = 0
for r in PAIRS:
    length = 2 ** r - 1
    for k in [0, 1, 2, 3, length // 2, length + 1]:
        ours = np.frombuffer(run("gold", r, k).strip().encode(), dtype=np.uint8) - ord("0")
        ref = gold(r, k)
        if not np.array_equal(ours, ref):
            print(f"gold degree {r} index {k}: mismatch at chip {np.argmax(ours != ref)}")
            failures += 1
    # the family is a Gold family: periodic cross-correlation of u and v takes three values
    u, v = (1 - 2 * mseq(r, p).astype(int) for p in PAIRS[r])
    xc = {int(np.dot(u, np.roll(v, s))) for s in range(length)}
    t = 2 ** ((r + 2) // 2)
    if not xc <= {-1, -t - 1, t - 1}:
        print(f"degree {r}: cross-correlation values {sorted(xc)} are not the Gold triple {-1, -t - 1, t - 1}")
        failures += 1

fs = 44100.0
for f0, f1, d, fd in [(2000, 8000, 0.040, 0.005), (18000, 22000, 0.025, 0.0), (8000, 2000, 0.1, 0.01)]:
    ours = np.array(run("lfm", f0, f1, d, fd, fs).split(), dtype=float)
    t = np.arange(int(np.floor(d * fs + 0.5))) / fs
    ref = fade(t, d, fd) * chirp(t, f0=f0, t1=d, f1=f1, method="linear", phi=-90)
    err = np.max(np.abs(ours - ref))
    if len(ours) != len(ref) or err > 1e-6:
        print(f"lfm {f0}-{f1} Hz {d} s: max error {err}")
        failures += 1

tones = [18000 + 250 * i for i in range(10)]
ours = np.array(run("multitone", 0.05, 0.005, fs, *tones).split(), dtype=float)
t = np.arange(int(np.floor(0.05 * fs + 0.5))) / fs
ref = fade(t, 0.05, 0.005) * np.mean([np.sin(2 * np.pi * f * t) for f in tones], axis=0)
err = np.max(np.abs(ours - ref))
if err > 1e-6:
    print(f"multitone: max error {err}")
    failures += 1

print("signals agree with the scipy reference" if failures == 0 else f"{failures} mismatches")
sys.exit(1 if failures else 0)
