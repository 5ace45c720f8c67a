#!/usr/bin/env python3
"""Compares what `locus record` wrote with what the JACK player played.
Usage: check_recording.py PLAYED.wav SCENE_DIR DEVICE [DETECTIONS.jsonl START_FRAME...]
  1. SCENE_DIR/DEVICE/audio.wav is float32 at the played rate; frames listed in gaps.csv (xruns) are
     zero; with them taken out, the played signal appears at one fixed frame offset (found from its
     first sample, never zero), bit-exact, with digital silence around it;
  2. With DETECTIONS: the replayed chirp detections are at the recorded frame of each START_FRAME
     (within 2 frames); a chirp cut by an xrun gap is not expected.
Prints 'ok ...' / 'FAIL ...' lines; exit status 1 if any check failed."""
import csv
import json
import sys
import warnings

import numpy as np
from scipy.io import wavfile

# libsndfile writes chunks scipy does not know (e.g. PEAK): harmless here.
warnings.filterwarnings("ignore", category=wavfile.WavFileWarning)
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
# A JACK xrun skips graph cycles: the recorder's stream clock moves on (the gap, zero-filled and listed)
# while the player, not called either, resumes where it was. So with the gaps taken out, the played
# signal must appear contiguously and bit-exact; `where` maps those frames back to recorded frames.
where = np.flatnonzero(mask)
compact = rec[mask]

nz_p = np.flatnonzero(played)
nz_r = np.flatnonzero(compact)
check(len(nz_r) > 0, "the recording holds the signal")
offset = None
if len(nz_r):
    offset = int(nz_r[0] - nz_p[0])
    check(offset >= 0 and offset + len(played) <= len(compact), "the whole played signal is inside the recording")
    if offset >= 0 and offset + len(played) <= len(compact):
        print(f"info offset: played frame 0 is recorded frame {where[offset]}")
        seg = compact[offset:offset + len(played)]
        same = np.array_equal(seg, played)
        inside = [g for g in gaps if where[offset] <= g[0] <= where[offset + len(played) - 1]]
        check(same, f"recording == played signal at recorded frame {where[offset]}, bit-exact "
                    f"({len(played)} frames; {len(inside)} xrun gap(s) inside)")
        if not same:
            bad = np.flatnonzero(seg != played)
            print(f"info first mismatches at played frames {bad[:10].tolist()}")
        outside = np.concatenate([compact[:offset], compact[offset + len(played):]])
        check(not np.any(outside), "silence before and after the played signal")
    else:
        offset = None

if len(sys.argv) > 4 and offset is not None:
    starts = [int(s) for s in sys.argv[5:]]
    dets = [json.loads(l) for l in open(sys.argv[4])]
    dets = [d for d in dets if d.get("type") == "audio_detection" and d.get("device") == device]
    frames = sorted(d["frame"] for d in dets)
    print(f"info detections at frames {[round(f, 2) for f in frames]}")
    chirp_frames = int(round(0.040 * rate_p))
    expected = []
    for s in starts:
        first, last = where[offset + s], where[offset + s + chirp_frames - 1]
        if last - first != chirp_frames - 1:
            print(f"info chirp at played frame {s} straddles an xrun gap: not expected whole")
            continue
        expected.append(first)
    check(len(frames) == len(expected), f"{len(expected)} chirps detected in the replay (got {len(frames)})")
    for want in expected:
        near = [f for f in frames if abs(f - want) <= 2.0]
        check(len(near) == 1, f"chirp at recorded frame {want} found")

sys.exit(1 if fails else 0)
