#!/usr/bin/env python3
"""Scores Gold-code detections of a Montage scene against every true arrival, by range, speed and near-far.

usage: check_montage_arrivals.py SCENE_DIR DETECTIONS.jsonl [--json] [--max-range M] [--min-found F]
                                 [--max-off10 N] [--list-bad]

Why: Montage ranges every pair from the arrival times of every user's code at every device (ETOA), so
a receiver is scored per arrival, and above all on the OTHER users' arrivals (a device's own code is
tens of dB louder at its microphone and easy). The issue-15 bar: >= 95 % of other-user arrivals within
--max-range (12 m) found within 2 samples, none of them > 10 samples off.

Truth: per (emission, device, mic) the local sample index of the direct path's first sample, from
truth-extra.yaml `arrivals` (independent reference generator) or, for a `locus simulate` scene, from
truth_emissions.csv + truth.csv + the truth clocks (check_tum_arrivals.py's readers, shared).
Detections: `audio_detection` JSON lines of the goldcode detector (`locus replay SCENE --config
config/montage-detect.yaml --events audio_detection -o F`); `template` k is the k-th Gold emitter of
scene.yaml in scene order (the detector's `from_scene: true`).

Matching: per (device, channel, emitter) every detection is paired with the nearest arrival of that
emitter (within half a code); each arrival keeps its nearest detection; the rest are false. Classes:
within 2 samples / 2-10 / more than 10 / missed. Other-user arrivals are also tabulated by range,
relative radial speed (truth.csv, at the emission) and near-far ratio (20 log10 of the arrival's range
over the own speaker-to-mic distance: the own emission's level advantage under 1/r spreading).
Exit status: 0, or 4 when a --min/--max bar is missed. Needs python3-numpy and python3-yaml.
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
from check_tum_arrivals import arrivals_from_extra, arrivals_from_geometry, load_scene  # noqa: E402


def gold_emitters(scene):
    """Scene-order Gold emitters -> (ids, code length in samples)."""
    ids, length = [], {}
    for group in ('devices', 'emitters'):
        for d in scene.get(group) or []:
            for sig in d.get('emits') or []:
                if sig.get('type') == 'gold':
                    ids.append(d['id'])
                    n = len(sig['chips']) if sig.get('chips') else (1 << int(sig['degree'])) - 1
                    length[d['id']] = n * int(sig['chip_samples'])
    return ids, length


def load_traj(scene_dir, scene):
    traj = {}
    with open(os.path.join(scene_dir, scene['truth'].get('trajectories', 'truth.csv'))) as f:
        for row in csv.DictReader(f):
            traj.setdefault(row['id'], []).append([float(row[k]) for k in 't x y z qw qx qy qz'.split()])
    return {k: np.array(v) for k, v in traj.items()}


def position(traj, i, t):
    a = traj[i]
    if len(a) == 1:
        return a[0, 1:4]
    return np.array([np.interp(t, a[:, 0], a[:, k]) for k in (1, 2, 3)])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('detections')
    ap.add_argument('--json', action='store_true', help='print the summary as one JSON object')
    ap.add_argument('--max-range', type=float, default=12.0, help='other-user arrivals up to this range count for '
                    'the bar (m, default 12)')
    ap.add_argument('--min-found', type=float, help='fail (exit 4) below this fraction of in-range other-user '
                    'arrivals found within 2 samples')
    ap.add_argument('--max-off10', type=int, help='fail when more in-range other-user arrivals are > 10 samples off')
    ap.add_argument('--list-bad', action='store_true', help='list every other-user arrival not within 2 samples')
    a = ap.parse_args()

    scene = load_scene(a.scene)
    tmpl, length = gold_emitters(scene)
    arrivals = arrivals_from_extra(a.scene)
    source = 'truth-extra.yaml'
    if arrivals is None:
        arrivals = arrivals_from_geometry(a.scene, scene)
        source = 'geometry (truth_emissions.csv, truth.csv)'
    # True emission times (for range and speed): truth-extra `emissions` or truth_emissions.csv.
    t_emit = {}
    p = os.path.join(a.scene, 'truth-extra.yaml')
    if os.path.exists(p):
        with open(p) as f:
            extra = yaml.load(f, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
        for e in extra.get('emissions') or []:
            t_emit[int(e['id'])] = float(e['t_emit_true'])
    else:
        with open(os.path.join(a.scene, 'truth_emissions.csv')) as f:
            for n, r in enumerate(csv.DictReader(f)):
                t_emit[n] = float(r['t_true'])
    traj = load_traj(a.scene, scene)
    devs = {d['id']: d for d in scene.get('devices') or []}

    def geometry(src, dev, mic, te):
        ps, pd = position(traj, src, te), position(traj, dev, te)
        r = float(np.linalg.norm(pd - ps))
        dt = 0.05
        r2 = float(np.linalg.norm(position(traj, dev, te + dt) - position(traj, src, te + dt)))
        speed = (r2 - r) / dt  # > 0: moving apart
        d = devs.get(dev, {})
        own = 0.02
        if 'speaker' in d and d.get('mics'):
            own = max(1e-3, float(np.linalg.norm(np.array(d['speaker'], float) - np.array(d['mics'][mic], float))))
        return r, speed, 20.0 * math.log10(max(r, own) / own)

    dets = []
    with open(a.detections) as f:
        for line in f:
            line = line.strip()
            if line:
                e = json.loads(line)
                if e.get('type', 'audio_detection') == 'audio_detection':
                    dets.append(e)

    table = {}
    for em, src, dev, mic, samp, *_ in arrivals:
        table.setdefault((dev, mic, src), []).append([samp, em, None, None])
    for v in table.values():
        v.sort()
    false = []
    for di, d in enumerate(dets):
        t = int(d.get('template', 0))
        if t >= len(tmpl):
            false.append((di, d, 'template index beyond the scene codes'))
            continue
        src = tmpl[t]
        best = None
        for row in table.get((d['device'], int(d['channel']), src), []):
            err = float(d['frame']) - row[0]
            if best is None or abs(err) < abs(best[0]):
                best = (err, row)
        if best is None or abs(best[0]) > 0.5 * length[src]:
            false.append((di, d, 'no arrival of that code within half a code'))
            continue
        err, row = best
        if row[2] is not None:
            if abs(err) < abs(row[2]):
                false.append((row[3], dets[row[3]], 'second detection of one arrival'))
                row[2], row[3] = err, di
            else:
                false.append((di, d, 'second detection of one arrival'))
        else:
            row[2], row[3] = err, di

    classes = ('within2', 'off2to10', 'off10', 'missed')
    summary = {g: dict.fromkeys(classes + ('arrivals',), 0) for g in ('own', 'other', 'other_in_range')}
    bins = {'range_m': [0, 3, 6, 9, 12, 15, 20, 1e9], 'speed_mps': [0, 0.5, 1.0, 1.5, 2.0, 1e9],
            'near_far_db': [0, 40, 45, 50, 55, 60, 1e9]}
    by = {k: [[0, 0] for _ in range(len(v) - 1)] for k, v in bins.items()}  # [found within 2, arrivals]
    bad, errs = [], []
    for (dev, mic, src), rows in sorted(table.items()):
        for samp, em, err, di in rows:
            if err is None:
                k = 'missed'
            elif abs(err) <= 2.0:
                k = 'within2'
            elif abs(err) <= 10.0:
                k = 'off2to10'
            else:
                k = 'off10'
            if dev == src:
                summary['own'][k] += 1
                summary['own']['arrivals'] += 1
                continue
            r, v, nf = geometry(src, dev, mic, t_emit.get(em, 0.0))
            groups = ['other'] + (['other_in_range'] if r <= a.max_range else [])
            for g in groups:
                summary[g][k] += 1
                summary[g]['arrivals'] += 1
            for key, val in (('range_m', r), ('speed_mps', abs(v)), ('near_far_db', nf)):
                e = bins[key]
                for i in range(len(e) - 1):
                    if e[i] <= val < e[i + 1]:
                        by[key][i][1] += 1
                        by[key][i][0] += k == 'within2'
            if k == 'within2':
                errs.append(err)
            else:
                bad.append((em, src, dev, mic, samp, k, err, r, v, nf))
    s = summary['other_in_range']
    n = s['arrivals']
    res = {
        'scene': a.scene, 'truth': source, 'detections': len(dets), 'false': len(false), 'groups': summary,
        'found_fraction_in_range': s['within2'] / n if n else 0.0,
        'rms_within2_samples': float(np.sqrt(np.mean(np.square(errs)))) if errs else float('nan'),
        'by': {k: [{'lo': bins[k][i], 'hi': bins[k][i + 1], 'found': by[k][i][0], 'arrivals': by[k][i][1]}
                   for i in range(len(bins[k]) - 1) if by[k][i][1]] for k in bins},
    }
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{a.scene}: {len(dets)} detections ({source}), {len(false)} false")
        print(f"{'group':15s} {'arrivals':>8s} {'<=2':>6s} {'2-10':>5s} {'>10':>5s} {'missed':>7s}  within 2 samples")
        for g, s2 in summary.items():
            if s2['arrivals']:
                print(f"{g:15s} {s2['arrivals']:8d} {s2['within2']:6d} {s2['off2to10']:5d} {s2['off10']:5d} "
                      f"{s2['missed']:7d}  {100.0 * s2['within2'] / s2['arrivals']:.1f} %")
        print(f"other users (range <= {a.max_range:g} m: the bar): "
              f"{100.0 * res['found_fraction_in_range']:.1f} % within 2 samples; rms error of those within 2: "
              f"{res['rms_within2_samples']:.2f} samples")
        for k, rows in res['by'].items():
            print(f"  by {k}: " + ', '.join(f"[{r['lo']:g},{r['hi'] if r['hi'] < 1e8 else 'inf'}) "
                                            f"{r['found']}/{r['arrivals']}" for r in rows))
    if a.list_bad:
        for em, src, dev, mic, samp, k, err, r, v, nf in bad:
            es = 'none' if err is None else f'{err:+.2f}'
            print(f"  emission {em} ({src}) at {dev} mic {mic}, sample {samp:.1f}: {k}, error {es}; "
                  f"{r:.1f} m, {v:+.2f} m/s, near-far {nf:.0f} dB")
        for di, d, why in false:
            print(f"  false: {d['device']} ch {d['channel']} template {d.get('template')} frame {d['frame']:.1f}: {why}")
    failed = []
    if a.min_found is not None and res['found_fraction_in_range'] < a.min_found:
        failed.append(f"found fraction {res['found_fraction_in_range']:.4f} < {a.min_found}")
    if a.max_off10 is not None and summary['other_in_range']['off10'] > a.max_off10:
        failed.append(f"{summary['other_in_range']['off10']} in-range arrivals > 10 samples off (max {a.max_off10})")
    for f in failed:
        print('FAIL: ' + f, file=sys.stderr)
    return 4 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
