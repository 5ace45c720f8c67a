#!/usr/bin/env python3
"""Arrival-time check of audio detections against a simulated scene's ground truth.

usage: check_arrivals.py SCENE_DIR DETECTIONS.jsonl
For every audio_detection event (JSON lines from `locus replay ... --events audio_detection`), finds the
emission in SCENE_DIR/truth_emissions.csv whose predicted arrival is nearest and prints the error in
samples: predicted = fs * local_clock(t_emit + |mic(t) - speaker(t_emit)| / c), from truth.csv poses,
scene.yaml geometry and truth clocks (direct path only). Needs python3-numpy and python3-yaml.
"""
import json, sys, csv, math
import numpy as np
scene = sys.argv[1]; det = sys.argv[2]
import yaml
S = yaml.safe_load(open(f"{scene}/scene.yaml"))
fs = S['sample_rate']; c = S['speed_of_sound']
clocks = S['truth']['clocks']
mics = {d['id']: np.array(d['mics'][0]) for d in S['devices']}
spk = {d['id']: np.array(d['speaker']) for d in S['devices'] if 'speaker' in d}
tr = {}
for row in csv.DictReader(open(f"{scene}/truth.csv")):
    tr.setdefault(row['id'], []).append([float(row[k]) for k in 't x y z qw qx qy qz'.split()])
tr = {k: np.array(v) for k, v in tr.items()}
def pose(i, t):
    a = tr[i]
    if len(a) == 1: return a[0,1:4], a[0,4:8]
    j = np.searchsorted(a[:,0], t); j = min(max(j,1), len(a)-1)
    f = (t-a[j-1,0])/(a[j,0]-a[j-1,0]); p = a[j-1,1:4]+f*(a[j,1:4]-a[j-1,1:4]); q = a[j-1,4:8]+f*(a[j,4:8]-a[j-1,4:8]); q/=np.linalg.norm(q)
    return p, q
def rot(q, v):
    w,x,y,z = q
    R = np.array([[1-2*(y*y+z*z),2*(x*y-w*z),2*(x*z+w*y)],[2*(x*y+w*z),1-2*(x*x+z*z),2*(y*z-w*x)],[2*(x*z-w*y),2*(y*z+w*x),1-2*(x*x+y*y)]])
    return R@v
em = [(float(r['t_true']), r['id']) for r in csv.DictReader(open(f"{scene}/truth_emissions.csv"))]
dets = [json.loads(l) for l in open(det)]
errs = []
for d in dets:
    dev = d['device']; ck = clocks[dev]
    best = None
    for te, src in em:
        p, q = pose(src, te); ps = p + rot(q, spk[src])
        # iterate arrival time
        t = te
        for _ in range(5):
            pm, qm = pose(dev, t); pmic = pm + rot(qm, mics[dev])
            t = te + np.linalg.norm(pmic-ps)/c
        frame = fs*(t*(1+ck['skew_ppm']*1e-6)+ck['offset_s'])
        e = d['frame'] - frame
        if best is None or abs(e) < abs(best): best = e
    errs.append((dev, best))
e = np.array([x[1] for x in errs])
print(f"{len(e)} detections; error vs truth (samples): mean {e.mean():+.3f} rms {np.sqrt((e**2).mean()):.3f} "
      f"max|e| {np.abs(e).max():.3f}; |e| <= 0.05: {(np.abs(e) <= 0.05).sum()}, |e| > 1 (cycle slips): {(np.abs(e) > 1).sum()}")
for dev in sorted(set(x[0] for x in errs)):
    v = np.array([x[1] for x in errs if x[0]==dev]); print(f"  {dev:7s} n={len(v)} mean {v.mean():+.3f} sd {v.std():.3f}")
