#!/usr/bin/env python3
"""Montage localizer campaign (issue 15): simulate seeds (the hard settings: hall, free formation,
r = 7, 40-sample chips), replay them with config/montage.yaml, score with `locus eval --metric
montage`, and measure the std's coverage (fraction of position errors within 1 std, after the same
one-rigid-transform alignment `relative_trace` uses). Also scores given foreign scenes (--scene).

  tools/scripts/montage_campaign.py --bin build/bin --seeds 1-20 [--scene ../shared/scenes/montage-103]
      [--anchor USER]

--anchor USER: absolute positions (the `world` frame): each scene is replayed with a copy of the config
that names USER as the anchor user, its start (its true position at its radio start signal) and where
magnetic north points in the world (truth `magnetic_field_world`) — what a user knows from a site plan;
scenes whose truth lacks the field are replayed without the anchor (said in the output).
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from campaign_common import parse_seeds, pct, run  # noqa: E402

HARD = ['--difficulty', 'normal', '--duration', '12', '-o', 'room=hall', '-o', 'formation=free',
        '-o', 'degree=7', '-o', 'chip_samples=40']


def truth(scene):
    doc = yaml.safe_load(open(os.path.join(scene, 'scene.yaml')))
    clocks = (doc.get('truth') or {}).get('clocks') or {}
    rows = {}
    with open(os.path.join(scene, 'truth.csv')) as f:
        next(f)
        for line in f:
            p = line.strip().split(',')
            rows.setdefault(p[1], []).append((float(p[0]), float(p[2]), float(p[3])))
    return clocks, {k: np.array(v) for k, v in rows.items()}


def coverage(scene, est_file):
    """Fraction of estimates whose error after the best rigid 2D alignment is within std_m."""
    clocks, tr = truth(scene)
    est, tru, std = [], [], []
    world_est, world_tru, world_std = [], [], []
    for line in open(est_file):
        e = json.loads(line)
        if e.get('type') != 'estimate' or e.get('frame') not in ('relative_trace', 'world'):
            continue
        c = clocks.get(e['reference'], {})
        t = (e['t_s'] - c.get('offset_s', 0.0)) / (1 + c.get('skew_ppm', 0.0) * 1e-6)
        a = tr[e['target']]
        # `world` (anchor user): scored without alignment; `relative_trace`: after one rigid transform.
        lists = (world_est, world_tru, world_std) if e['frame'] == 'world' else (est, tru, std)
        lists[0].append(e['position_m'][:2])
        lists[1].append([np.interp(t, a[:, 0], a[:, 1]), np.interp(t, a[:, 0], a[:, 2])])
        lists[2].append(e['std_m'])
    if world_est:
        err = np.linalg.norm(np.array(world_est) - np.array(world_tru), axis=1)
        return float(np.mean(err <= np.array(world_std))), err.tolist()
    if len(est) < 2:
        return None, []
    P, Q = np.array(est), np.array(tru)
    pm, qm = P.mean(0), Q.mean(0)
    U, _, Vt = np.linalg.svd((P - pm).T @ (Q - qm))
    d = np.sign(np.linalg.det(U @ Vt))
    R = (U @ np.diag([1, d]) @ Vt).T
    err = np.linalg.norm((P - pm) @ R.T + qm - Q, axis=1)
    return float(np.mean(err <= np.array(std))), err.tolist()


def anchored_config(scene, config, user, work):
    """A copy of config with `user` as the anchor (its true start, the truth's magnetic north), or None
    when the scene's truth has no magnetic_field_world."""
    doc = yaml.safe_load(open(os.path.join(scene, 'scene.yaml')))
    t = doc.get('truth') or {}
    field = t.get('magnetic_field_world')
    if not field:
        return None
    dev = next(d for d in doc['devices'] if d['id'] == user)
    with open(os.path.join(scene, dev['sync'])) as f:
        next(f)
        t_sync_local = float(next(f).split(',')[0])
    c = (t.get('clocks') or {}).get(user, {})
    t_sync = (t_sync_local - c.get('offset_s', 0.0)) / (1 + c.get('skew_ppm', 0.0) * 1e-6)
    _, tr = truth(scene)
    a = tr[user]
    start = [float(np.interp(t_sync, a[:, 0], a[:, 1])), float(np.interp(t_sync, a[:, 0], a[:, 2]))]
    cfg = yaml.safe_load(open(config))
    for loc in cfg.get('localizers', []):
        if loc.get('plugin') == 'montage':
            loc.setdefault('params', {}).update({'anchor_user': user, 'anchor_start_m': start,
                                                 'magnetic_north_world_deg': math.degrees(math.atan2(field[1], field[0]))})
    out = os.path.join(work, os.path.basename(os.path.normpath(scene)) + '.anchored.yaml')
    with open(out, 'w') as f:
        yaml.safe_dump(cfg, f)
    return out


def score(locus, scene, config, work, anchor=None):
    if anchor:
        anchored = anchored_config(scene, config, anchor, work)
        if anchored is None:
            print(f'{scene}: no truth magnetic_field_world: replayed without the anchor', file=sys.stderr)
        config = anchored or config
    est = os.path.join(work, os.path.basename(os.path.normpath(scene)) + '.est.jsonl')
    run([os.path.join(locus, 'locus'), 'replay', scene, '--config', config, '--speed', 'max', '-o', est], 'montage_campaign')
    r = run([os.path.join(locus, 'locus'), 'eval', scene, est, '--metric', 'montage', '--json'], 'montage_campaign')
    p = json.loads(r.stdout)['plugins'][0]
    cov, _ = coverage(scene, est)
    s = p['summary']
    return {'mean': s.get('mean_error_m'), 'max': s.get('max_error_m'), 'located': s.get('targets_located'),
            'expected': s.get('targets_expected'), 'stride_mean': s.get('mean_stride_error_m'),
            'stride_max': s.get('max_stride_error_m'), 'steps_true': s.get('steps_true'),
            'steps_matched': s.get('steps_matched'), 'steps_detected': s.get('steps_detected'), 'coverage': cov}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', default='build/bin')
    ap.add_argument('--seeds', default='1-20')
    ap.add_argument('--config', default='config/montage.yaml')
    ap.add_argument('--scene', action='append', default=[])
    ap.add_argument('--work', default='/tmp/montage-campaign')
    ap.add_argument('--anchor', help='anchor user (absolute positions; see the module doc)')
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    res = []
    for scene in a.scene:
        r = score(a.bin, scene, a.config, a.work, a.anchor)
        r['name'] = os.path.basename(os.path.normpath(scene))
        res.append(r)
    for seed in parse_seeds(a.seeds):
        d = os.path.join(a.work, f'sim{seed}')
        if not os.path.exists(os.path.join(d, 'scene.yaml')):
            run([os.path.join(a.bin, 'locus'), 'simulate', 'montage', d, '--seed', str(seed)] + HARD, 'montage_campaign')
        r = score(a.bin, d, a.config, a.work, a.anchor)
        r['name'] = f'seed {seed}'
        res.append(r)
    f = lambda v, n=3: '-' if v is None or (isinstance(v, float) and math.isnan(v)) else (f'{v:.{n}f}' if isinstance(v, float) else str(v))
    print('scene | located | trace mean m | trace max m | stride mean m | stride max m | steps matched/true (detected) | std coverage')
    for r in res:
        print(f"{r['name']} | {r['located']}/{r['expected']} | {f(r['mean'])} | {f(r['max'])} | {f(r['stride_mean'])} | "
              f"{f(r['stride_max'])} | {r['steps_matched']}/{r['steps_true']} ({r['steps_detected']}) | {f(r['coverage'], 2)}")
    sims = [r for r in res if r['name'].startswith('seed')]
    if sims:
        means = [r['mean'] for r in sims if r['mean'] is not None]
        maxes = [r['max'] for r in sims if r['max'] is not None]
        st = [r['stride_mean'] for r in sims if r['stride_mean'] is not None]
        cov = [r['coverage'] for r in sims if r['coverage'] is not None]
        loc = sum(r['located'] or 0 for r in sims), sum(r['expected'] or 0 for r in sims)
        print(f"seeds: {len(sims)}, located {loc[0]}/{loc[1]}, trace mean of means {np.mean(means):.3f} m (median {pct(means, .5):.3f}), "
              f"max of maxes {max(maxes):.3f} m, seeds with mean <= 0.5 m: {sum(m <= 0.5 for m in means)}, with max <= 1 m: "
              f"{sum(m <= 1.0 for m in maxes)}; stride mean {np.mean(st):.3f} m; std coverage mean {np.mean(cov):.2f}")


if __name__ == '__main__':
    main()
