#!/usr/bin/env python3
"""Pairwise ETOA ranges from a Montage scene's goldcode detections, scored against the true distances.

usage: montage_etoa_check.py SCENE_DIR DETECTIONS.jsonl [--json] [--max-range M] [--window-s S]

What it measures: how well the detections alone range every pair (the paper's ETOA, no clock sync),
before any localizer exists (issue 15; the `plugins/montage` localizer will do this live). Per round
and pair (A, B): A hears its own code at local frame f_AA and B's at f_AB, B hears its own at f_BB and
A's at f_BA; with skews of tens of ppm over < 0.1 s negligible,
    d_AB = c/2 · ((f_AB − f_AA) + (f_BA − f_BB)) / fs + (s_A + s_B)/2,
s_X the device's speaker-to-mic distance (scene.yaml geometry), c the scene's speed_of_sound.
Rounds: a device's own detections in time order (every user emits once per round after the radio
start signal, so the k-th own emission of A and of B belong to round k); the other codes' detections
of a round are those within --window-s of the device's own detection (the nearest one).
Truth: truth-extra.yaml `pairwise` (mean of the two speaker-to-microphone distances) when present, else
truth.csv body positions at the round's mean own-arrival time on the truth clock.
Prints the median / 90th percentile / max absolute error for pairs within --max-range (default 15 m).
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from campaign_common import pct  # noqa: E402
from check_montage_arrivals import gold_emitters  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('detections')
    ap.add_argument('--json', action='store_true')
    ap.add_argument('--max-range', type=float, default=15.0)
    ap.add_argument('--window-s', type=float, default=0.25)
    a = ap.parse_args()
    with open(os.path.join(a.scene, 'scene.yaml')) as f:
        scene = yaml.safe_load(f)
    fs = float(scene['sample_rate'])
    c = float(scene.get('speed_of_sound') or 331.3 + 0.606 * float(scene.get('temperature_c', 20.0)))
    ids, _ = gold_emitters(scene)
    devs = {d['id']: d for d in scene.get('devices') or []}
    spk = {}
    for i in ids:
        d = devs.get(i, {})
        spk[i] = float(np.linalg.norm(np.array(d['speaker'], float) - np.array(d['mics'][0], float))) \
            if 'speaker' in d and d.get('mics') else 0.0
    det = {}  # (device, code id) -> sorted frames (channel 0)
    with open(a.detections) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            e = json.loads(line)
            if e.get('type', 'audio_detection') != 'audio_detection' or int(e.get('channel', 0)) != 0:
                continue
            t = int(e.get('template', 0))
            if t < len(ids):
                det.setdefault((e['device'], ids[t]), []).append(float(e['frame']))
    for v in det.values():
        v.sort()

    def heard(dev, src, own_frame):
        best = None
        for fr in det.get((dev, src), []):
            if abs(fr - own_frame) <= a.window_s * fs and (best is None or abs(fr - own_frame) < abs(best - own_frame)):
                best = fr
        return best

    pairwise = None
    p = os.path.join(a.scene, 'truth-extra.yaml')
    if os.path.exists(p):
        with open(p) as f:
            extra = yaml.load(f, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
        if extra.get('pairwise'):
            pairwise = {int(r['round']): r['pairs'] for r in extra['pairwise']}
    traj = {}
    clocks = (scene.get('truth') or {}).get('clocks') or {}
    if pairwise is None:
        with open(os.path.join(a.scene, scene['truth'].get('trajectories', 'truth.csv'))) as f:
            for row in csv.DictReader(f):
                traj.setdefault(row['id'], []).append([float(row[k]) for k in ('t', 'x', 'y', 'z')])
        traj = {k: np.array(v) for k, v in traj.items()}

    def truth(rnd, i, j, t_local_i):
        if pairwise is not None:
            pr = pairwise.get(rnd, {})
            r = pr.get(f'{i}-{j}') or pr.get(f'{j}-{i}')
            return None if r is None else 0.5 * (float(r['spk_a_to_mic_b_m']) + float(r['spk_b_to_mic_a_m']))
        ck = clocks[i]
        t = (t_local_i - float(ck['offset_s'])) / (1.0 + float(ck['skew_ppm']) * 1e-6)
        pa = np.array([np.interp(t, traj[i][:, 0], traj[i][:, k]) for k in (1, 2, 3)])
        pb = np.array([np.interp(t, traj[j][:, 0], traj[j][:, k]) for k in (1, 2, 3)])
        return float(np.linalg.norm(pa - pb))

    errs, rows, missing = [], [], 0
    nrounds = min((len(det.get((i, i), [])) for i in ids), default=0)
    for rnd in range(nrounds):
        for ia, A in enumerate(ids):
            for B in ids[ia + 1:]:
                faa, fbb = det[(A, A)][rnd], det[(B, B)][rnd]
                fab, fba = heard(A, B, faa), heard(B, A, fbb)
                d_true = truth(rnd, A, B, faa / fs)
                if d_true is None or d_true > a.max_range:
                    continue
                if fab is None or fba is None:
                    missing += 1
                    continue
                d = 0.5 * c * ((fab - faa) + (fba - fbb)) / fs + 0.5 * (spk[A] + spk[B])
                errs.append(abs(d - d_true))
                rows.append((rnd, A, B, d, d_true))
    res = {'scene': a.scene, 'pairs_within_range': len(errs) + missing, 'ranged': len(errs), 'missing': missing,
           'median_abs_error_m': pct(errs, 0.5), 'p90_abs_error_m': pct(errs, 0.9),
           'max_abs_error_m': max(errs) if errs else float('nan'),
           'within_0_3_m': sum(e <= 0.3 for e in errs)}
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{a.scene}: {res['ranged']} of {res['pairs_within_range']} pair-rounds within {a.max_range:g} m ranged "
              f"({missing} lack a detection); |error| median {res['median_abs_error_m']:.3f} m, 90 % "
              f"{res['p90_abs_error_m']:.3f} m, max {res['max_abs_error_m']:.2f} m; {res['within_0_3_m']} within 0.3 m")
    return 0


if __name__ == '__main__':
    sys.exit(main())
