#!/usr/bin/env python3
"""Decay features (T5..T30) of a SpyLoc scene's beeps, per truth class (LoS / NLoS).

usage: spyloc_decay_stats.py SCENE_DIR DETECTIONS.jsonl [SCENE_DIR DETECTIONS.jsonl ...] [--json]

Why (issue 16): the LoS/NLoS classifier learns from the decay features of simulated beeps; when the
simulator's NLoS beeps decay unlike the world's, a model trained on it misses the world's NLoS. This
prints, per class, the median and quartiles of each T_x (NaN = not reached, counted apart) and of
the detection's first-path error, so the simulator can be compared with a foreign scene.
The detections come from `locus replay SCENE --config config/spyloc.yaml --events
audio_detection,decay_features`; beeps are matched as in check_spyloc_arrivals.py (its truth readers).
"""
import argparse
import json
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_spyloc_arrivals as csa  # noqa: E402


def rows_of(scene_dir, det_path):
    with open(os.path.join(scene_dir, 'scene.yaml')) as f:
        scene = yaml.safe_load(f)
    fs = float(scene['sample_rate'])
    device = next(d['id'] for d in scene['devices'] if d.get('audio'))
    beeps = csa.beeps_from_extra(scene_dir) or csa.beeps_from_geometry(scene_dir, scene, device)
    firsts = np.array([b['los_sample'] for b in beeps])
    feats = csa.read_events(det_path, 'decay_features', device)
    best = {}
    for ev in feats:
        fr = float(ev['frame'])
        # nearest beep whose direct (LoS) arrival is before the detection (NLoS: timed late)
        j = int(np.argmin(np.abs(firsts - fr)))
        if abs(firsts[j] - fr) > 0.03 * fs:
            continue
        if j not in best or abs(float(best[j]['frame']) - firsts[j]) > abs(fr - firsts[j]):
            best[j] = ev
    out = []
    for j, ev in best.items():
        b = beeps[j]
        d = [np.nan if v is None else float(v) for v in ev['decay_s']]
        out.append({'los': b['los'], 'decay': d, 'err': float(ev['frame']) - b['first'],
                    'margin': ev.get('noise_margin_db')})
    return out, len(beeps)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('pairs', nargs='+')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args()
    if len(a.pairs) % 2:
        sys.exit('expected pairs SCENE_DIR DETECTIONS.jsonl')
    rows = []
    for i in range(0, len(a.pairs), 2):
        r, _ = rows_of(a.pairs[i], a.pairs[i + 1])
        rows += r
    res = {}
    for name, sel in (('los', [r for r in rows if r['los']]), ('nlos', [r for r in rows if not r['los']])):
        D = np.array([r['decay'] for r in sel]) if sel else np.zeros((0, 6))
        e = np.array([r['err'] for r in sel])
        m = np.array([r['margin'] for r in sel if r['margin'] is not None], float)
        res[name] = {'n': len(sel),
                     'median_ms': [float(np.nanmedian(D[:, k]) * 1e3) if np.isfinite(D[:, k]).any() else None for k in range(6)],
                     'q25_ms': [float(np.nanpercentile(D[:, k], 25) * 1e3) if np.isfinite(D[:, k]).any() else None for k in range(6)],
                     'q75_ms': [float(np.nanpercentile(D[:, k], 75) * 1e3) if np.isfinite(D[:, k]).any() else None for k in range(6)],
                     'nan_frac': [float(np.isnan(D[:, k]).mean()) if len(D) else None for k in range(6)],
                     'median_err_samples': float(np.median(e)) if len(e) else None,
                     'median_noise_margin_db': float(np.median(m)) if len(m) else None}
    if a.json:
        print(json.dumps(res, indent=1))
        return 0
    fmt = lambda v: '  nan' if v is None else f'{v:6.1f}'
    for name in ('los', 'nlos'):
        s = res[name]
        print(f"{name:4s} n={s['n']:4d}  err median {s['median_err_samples']} samples, noise margin {s['median_noise_margin_db']} dB")
        print('       T5..T30 median ms:', ' '.join(fmt(v) for v in s['median_ms']))
        print('                  q25 ms:', ' '.join(fmt(v) for v in s['q25_ms']))
        print('                  q75 ms:', ' '.join(fmt(v) for v in s['q75_ms']))
        print('            not reached :', ' '.join(f'{v:6.2f}' for v in s['nan_frac']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
