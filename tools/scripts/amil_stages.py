#!/usr/bin/env python3
"""AMIL stage-by-stage check against a scene's truth-extra.yaml (the foreign generator's truth).

usage: amil_stages.py SCENE_DIR DETECTIONS.jsonl [TRACK.csv]
  DETECTIONS.jsonl: `locus replay SCENE --config config/amil.yaml --events audio_detection,estimate -o F`
  TRACK.csv:       the player's `track_csv` (session,t0_s,kind,t_s,x_m,y_m)
Prints, per device, every detection matched to the nearest true arrival (local samples) and the
misses / spurious ones; then the tracked beep positions against truth-extra's speaker positions.
Needs python3-numpy and python3-yaml (Debian's /usr/bin/python3).
"""
import csv, json, sys
import numpy as np
import yaml

scene, det_path = sys.argv[1], sys.argv[2]
track_path = sys.argv[3] if len(sys.argv) > 3 else None
X = yaml.safe_load(open(f"{scene}/truth-extra.yaml"))
cols = X['arrivals']['columns']
rows = [dict(zip(cols, r)) for r in X['arrivals']['rows']]
truth = {}
for r in rows:
    truth.setdefault((r['device'], r['mic']), []).append((r['emission'], r['local_sample']))
dets = [json.loads(l) for l in open(det_path) if l.strip()]
ad = [d for d in dets if d['type'] == 'audio_detection']
est = [d for d in dets if d['type'] == 'estimate']
all_err = []
print("== detections vs truth arrivals (samples)")
for (dev, mic), arr in sorted(truth.items()):
    mine = sorted(d['frame'] for d in ad if d['device'] == dev and d['channel'] == mic)
    used = set()
    line = []
    for k, s in arr:
        if not mine:
            line.append(f"#{k}:miss"); continue
        j = int(np.argmin([abs(m - s) for m in mine]))
        e = mine[j] - s
        if abs(e) > 2000:
            line.append(f"#{k}:miss"); continue
        used.add(j); all_err.append(e)
        line.append(f"#{k}:{e:+.2f}")
    extra = [f"{mine[j]:.1f}" for j in range(len(mine)) if j not in used]
    print(f"  {dev:4s} m{mic} " + " ".join(line) + (f"  spurious at {extra}" if extra else ""))
e = np.array(all_err)
if len(e):
    print(f"  matched {len(e)}: |e|<=1: {(abs(e)<=1).sum()}, >5: {(abs(e)>5).sum()}, median |e| {np.median(abs(e)):.3f}")
if track_path:
    print("== tracked beep (speaker) positions vs truth (mm, start frame vs body frame at t=0)")
    tb = [r for r in csv.DictReader(open(track_path)) if r['kind'] == 'beep']
    tp = np.array([[float(r['x_m']), float(r['y_m'])] for r in tb])
    bp = np.array([b['speaker_pos'][:2] for b in X['beeps']])
    n = min(len(tp), len(bp))
    for k in range(max(len(tp), len(bp))):
        a = tp[k] * 1000 if k < len(tp) else None
        b = bp[k] * 1000 if k < len(bp) else None
        if a is not None and b is not None:
            print(f"  beep {k}: tracked {a.round(1)} truth {b.round(1)} err {(a - b).round(1)} |{np.linalg.norm(a-b):.1f}|")
        else:
            print(f"  beep {k}: tracked {a} truth {b}")
    if n:
        # error after removing the common translation of beep 0 (the frame origin is the body, not the speaker)
        d = tp[:n] - bp[:n]
        print(f"  rms error {np.sqrt((d**2).sum(1).mean())*1000:.1f} mm")
if est:
    L = {l['id']: l for l in X['listeners']}
    print("== estimates")
    for s in est:
        l = L.get(s['target'])
        if not l: continue
        tb = np.radians(90 - l['bearing_deg']) if False else None
        td = l['dist_2d_m']; tpos = np.array(l['mic_pos'][:2])
        tdir = np.degrees(np.arctan2(tpos[1], tpos[0]))
        edir = np.degrees(s['direction_rad']) if s['direction_rad'] is not None else float('nan')
        dd = s['distance_m']
        print(f"  {s['target']}: dir err {((edir - tdir + 180) % 360 - 180):+.2f} deg, true dist {np.linalg.norm(tpos):.2f} "
              f"est {dd if dd is None else round(dd, 2)} std_m {s['std_m']} conf {s['confidence']:.2f}")
