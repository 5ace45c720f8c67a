#!/usr/bin/env python3
"""AMIL tracker check: tracked beep (speaker) positions and their std against the scene's truth.

usage: amil_track_check.py SCENE_DIR TRACK.csv [--json]
TRACK.csv is the player's `track_csv` (config param of the amil localizer). Truth: the foreign
generator's truth-extra.yaml (beeps[].speaker_pos, player body frame at t=0) when present, else
locus simulate's truth.csv + truth_emissions.csv (speaker position at each emission, in the player's
level frame at the first beep). Prints per-beep error (mm), the std the tracker claims, and the
normalised error per axis (should look like N(0,1) over many scenes). Needs numpy + yaml.
"""
import csv, json, math, os, sys
import numpy as np
import yaml

scene, track = sys.argv[1], sys.argv[2]
as_json = '--json' in sys.argv
S = yaml.safe_load(open(f"{scene}/scene.yaml"))
rows = [r for r in csv.DictReader(open(track)) if r['kind'] == 'beep']
tp = np.array([[float(r['x_m']), float(r['y_m'])] for r in rows])
ts = np.array([float(r.get('std_m') or 'nan') for r in rows])

def quat_rot(q, v):
    w, x, y, z = q
    R = np.array([[1-2*(y*y+z*z), 2*(x*y-w*z), 2*(x*z+w*y)], [2*(x*y+w*z), 1-2*(x*x+z*z), 2*(y*z-w*x)],
                  [2*(x*z-w*y), 2*(y*z+w*x), 1-2*(x*x+y*y)]])
    return R @ v

if os.path.exists(f"{scene}/truth-extra.yaml"):
    X = yaml.safe_load(open(f"{scene}/truth-extra.yaml"))
    bp = np.array([b['speaker_pos'][:2] for b in X['beeps']])
else:
    player = [d for d in S['devices'] if d.get('emits')][0]
    pid = player['id']; spk = np.array(player['speaker'])
    tr = np.array([[float(r[k]) for k in 't x y z qw qx qy qz'.split()]
                   for r in csv.DictReader(open(f"{scene}/truth.csv")) if r['id'] == pid])
    em = [float(r['t_true']) for r in csv.DictReader(open(f"{scene}/truth_emissions.csv")) if r['id'] == pid]
    def pose(t):
        j = min(max(np.searchsorted(tr[:, 0], t), 1), len(tr) - 1)
        f = (t - tr[j-1, 0]) / (tr[j, 0] - tr[j-1, 0]); p = tr[j-1, 1:4] + f * (tr[j, 1:4] - tr[j-1, 1:4])
        q = tr[j-1, 4:8] + f * (tr[j, 4:8] - tr[j-1, 4:8]); return p, q / np.linalg.norm(q)
    p0, q0 = pose(em[0])
    yb = quat_rot(q0, np.array([0, 1.0, 0])); yaw = math.atan2(yb[1], yb[0]) - math.pi / 2
    c, s = math.cos(-yaw), math.sin(-yaw)
    out = []
    for t in em:
        p, q = pose(t + 0.025)
        d = p + quat_rot(q, spk) - p0
        out.append([c * d[0] - s * d[1], s * d[0] + c * d[1]])
    bp = np.array(out)
n = min(len(tp), len(bp))
err = tp[:n] - bp[:n]
z = err / ts[:n, None]
res = {'beeps_tracked': len(tp), 'beeps_true': len(bp), 'err_mm': (err * 1000).round(2).tolist(),
       'std_mm': (ts[:n] * 1000).round(2).tolist(), 'z': z.round(2).tolist()}
if as_json:
    print(json.dumps(res))
else:
    for k in range(n):
        print(f"beep {k}: err {np.round(err[k]*1000, 2)} mm, std {ts[k]*1000:.2f} mm, z {np.round(z[k], 2)}")
    print(f"tracked {len(tp)} beeps, truth {len(bp)}")
