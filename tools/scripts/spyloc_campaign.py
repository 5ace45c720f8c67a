#!/usr/bin/env python3
"""SpyLoc campaign: simulate seeds, replay through config/spyloc.yaml, score detection and position.

usage: spyloc_campaign.py [--seeds 1-20] [--difficulty normal] [--sim-opt key=value ...]
                          [--locus build/bin/locus] [--config config/spyloc.yaml] [--keep DIR] [--json]

Why: one seed says little about a walking localizer (NLoS stretches, lost syncs and the fix's mirror
ambiguity vary with the layout); the figures of docs/spyloc.md are per-seed and pooled over seeds.
Per seed: `locus simulate spyloc`, `locus replay` (estimates + detections), `locus eval --metric
spyloc` (position error CDF) and tools/scripts/check_spyloc_arrivals.py (detection). Prints one row
per seed and the pooled p90 (all estimates of all seeds). Needs python3-numpy and python3-yaml.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np


from campaign_common import parse_seeds as seeds_of
from spyloc_errors import errors as estimate_errors, summary as error_summary


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seeds', default='1-20')
    ap.add_argument('--difficulty', default='normal')
    ap.add_argument('--sim-opt', action='append', default=[])
    ap.add_argument('--locus', default='build/bin/locus')
    ap.add_argument('--config', default='config/spyloc.yaml')
    ap.add_argument('--keep', default=None, help='keep scenes and outputs in this directory')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    work = a.keep or tempfile.mkdtemp(prefix='spyloc-campaign-')
    os.makedirs(work, exist_ok=True)
    rows = []
    pooled = []
    for seed in seeds_of(a.seeds):
        # A kept scene is reused only for the same difficulty and simulator options (the folder names
        # them when they are not the defaults; `s<seed>` otherwise, as docs/spyloc.md's commands use).
        extra = ([a.difficulty] if a.difficulty != 'normal' else []) + a.sim_opt
        slug = ''.join(ch if ch.isalnum() or ch in '=.' else '_' for ch in '_'.join(extra))
        sc = os.path.join(work, f's{seed}' + (f'-{slug}' if slug else ''))
        cmd = [a.locus, 'simulate', 'spyloc', sc, '--seed', str(seed), '--difficulty', a.difficulty, '-q']
        for o in a.sim_opt:
            cmd += ['-o', o]
        if not os.path.exists(os.path.join(sc, 'scene.yaml')):
            subprocess.run(cmd, check=True)
        est = sc + '.jsonl'
        with open(est, 'w') as f:
            subprocess.run([a.locus, 'replay', sc, '--config', a.config, '--speed', 'max',
                            '--events', 'estimate,audio_detection,decay_features,step'], stdout=f, check=True,
                           stderr=subprocess.DEVNULL)
        ev = subprocess.run([a.locus, 'eval', sc, est, '--metric', 'spyloc', '--json'], capture_output=True, text=True)
        res = json.loads(ev.stdout) if ev.stdout.strip().startswith('{') else {}
        det = subprocess.run([sys.executable, os.path.join(here, 'check_spyloc_arrivals.py'), sc, est, '--json'],
                             capture_output=True, text=True)
        d = json.loads(det.stdout) if det.returncode == 0 else {}
        summ = {}
        for p in res.get('plugins', []) if isinstance(res.get('plugins'), list) else []:
            summ = p.get('summary', p)
        if not summ and 'summary' in res:
            summ = res['summary']
        row = {'seed': seed, 'eval': summ,
               'los_found': d.get('los', {}).get('found_ok_frac'), 'los_within1': d.get('los', {}).get('within1_frac'),
               'verdicts': d.get('verdicts', {})}
        pooled += estimate_errors(sc, est)
        rows.append(row)
        if not a.json:
            print(f"seed {seed:3d}: p90 {summ.get('p90_error_m', float('nan')):.2f} m, median "
                  f"{summ.get('median_error_m', float('nan')):.2f} m, estimates {summ.get('estimates', '?')}, "
                  f"stride p90 {100 * (summ.get('p90_stride_error_m') or float('nan')):.1f} cm; "
                  f"LoS beeps found {100 * (row['los_found'] or 0):.1f} %, within 1 sample {100 * (row['los_within1'] or 0):.1f} %; "
                  f"LoS/NLoS verdicts {100 * (row['verdicts'].get('all', {}).get('accuracy') or float('nan')):.1f} %",
                  flush=True)
    p90s = np.array([r['eval'].get('p90_error_m', np.nan) for r in rows], float)
    strides = np.array([r['eval'].get('p90_stride_error_m') or np.nan for r in rows], float)
    verdicts = {k: [sum(r['verdicts'].get(k, {}).get(f, 0) for r in rows) for f in ('right', 'estimates')]
                for k in ('all', 'los', 'nlos')}
    out = {'seeds': rows, 'verdicts': verdicts, 'stride_p90_worst_m': float(np.nanmax(strides)) if np.isfinite(strides).any() else None, 'median_of_p90_m': float(np.nanmedian(p90s)), 'worst_p90_m': float(np.nanmax(p90s)),
           'seeds_p90_le_0_8': int(np.sum(p90s <= 0.8)), 'pooled': error_summary(pooled), 'work': work}
    if a.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"{len(rows)} seeds: p90 median over seeds {out['median_of_p90_m']:.2f} m, worst {out['worst_p90_m']:.2f} m, "
              f"{out['seeds_p90_le_0_8']} seeds with p90 <= 0.8 m (scenes in {work})")
        if out['stride_p90_worst_m'] is not None:
            print(f"stride error p90 per seed: {100 * np.nanmin(strides):.1f}-{100 * np.nanmax(strides):.1f} cm")
        v = out['verdicts']
        if v['all'][1]:
            print(f"LoS/NLoS verdicts (per estimate vs the beep's label): {v['all'][0]}/{v['all'][1]} "
                  f"({100 * v['all'][0] / v['all'][1]:.1f} %): LoS {v['los'][0]}/{v['los'][1]}, NLoS {v['nlos'][0]}/{v['nlos'][1]}")
        p = out['pooled']
        if p.get('estimates'):
            print(f"pooled: {p['estimates']} estimates, median {p['median_m']:.2f} m, p90 {p['p90_m']:.2f} m; "
                  f"within 1 std {100 * p['within_1std']:.0f} %, within 2 std {100 * p['within_2std']:.0f} %")


if __name__ == '__main__':
    main()
