#!/usr/bin/env python3
"""Compares what `locus record` wrote with what the JACK player played.
Usage: check_recording.py PLAYED.wav SCENE_DIR DEVICE [DETECTIONS.jsonl START_FRAME...]
  1. SCENE_DIR/DEVICE/audio.wav is float32 at the played rate; the played signal appears in it at one
     fixed frame offset (found from the first non-zero sample), bit-exact, with silence around it;
     frames listed in gaps.csv (xruns) must be zero and are reported, not compared.
  2. With DETECTIONS: the replayed chirp detections are at offset + each START_FRAME (within 2 frames).
Prints 'ok ...' / 'FAIL ...' lines; exit status 1 if any check failed."""
import csv
import json
import sys

import numpy as np
from scipy.io import wavfile

fails = 0


def check(cond, what):
    global fails
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        fails += 1


played_path, scene, device = sys.argv[1:4]
rate_p, played = wavfile.read(played_path)
rate_r, rec = wavfile.read(f"{scene}/{device}/audio.wav")
check(rate_r == rate_p, f"recorded rate {rate_r} Hz = played rate {rate_p} Hz")
check(rec.dtype == np.float32, f"recorded as float32 (got {rec.dtype}), as JACK delivers")
if rec.ndim > 1:
    rec = rec[:, 0]
gaps = []
with open(f"{scene}/{device}/gaps.csv") as f:
    for row in csv.DictReader(f):
        gaps.append((int(row["frame"]), int(row["frames"])))
print(f"info recording: {len(rec)} frames, {len(gaps)} gap(s) {gaps}")
mask = np.ones(len(rec), dtype=bool)
for g0, gn in gaps:
    check(not np.any(rec[g0:g0 + gn]), f"gap at {g0} (+{gn}) is zero-filled")
    mask[g0:g0 + gn] = False

nz_p = np.flatnonzero(played)
nz_r = np.flatnonzero(rec)
check(len(nz_r) > 0, "the recording holds the signal")
offset = None
if len(nz_r):
    offset = int(nz_r[0] - nz_p[0])
    print(f"info offset: played frame 0 is recorded frame {offset}")
    check(offset >= 0 and offset + len(played) <= len(rec), "the whole played signal is inside the recording")
    if offset >= 0 and offset + len(played) <= len(rec):
        seg = rec[offset:offset + len(played)]
        m = mask[offset:offset + len(played)]
        same = np.array_equal(seg[m], played[m])
        check(same, f"recording == played signal at offset {offset}, bit-exact ({int(m.sum())} frames compared)")
        if not same:
            bad = np.flatnonzero((seg != played) & m)
            print(f"info first mismatches at played frames {bad[:10].tolist()}")
        outside = np.concatenate([rec[:offset][mask[:offset]], rec[offset + len(played):][mask[offset + len(played):]]])
        check(not np.any(outside), "silence before and after the played signal")

if len(sys.argv) > 4 and offset is not None:
    starts = [int(s) for s in sys.argv[5:]]
    dets = [json.loads(l) for l in open(sys.argv[4])]
    dets = [d for d in dets if d.get("type") == "audio_detection" and d.get("device") == device]
    frames = sorted(d["frame"] for d in dets)
    print(f"info detections at frames {[round(f, 2) for f in frames]}")
    check(len(frames) == len(starts), f"{len(starts)} chirps detected in the replay (got {len(frames)})")
    for s in starts:
        want = offset + s
        near = [f for f in frames if abs(f - want) <= 2.0]
        check(len(near) == 1, f"chirp at recorded frame {want} found (played frame {s})")

sys.exit(1 if fails else 0)
