#!/usr/bin/env python3
"""Per-estimate position errors of a SpyLoc run against its scene's truth, and the std coverage.

usage: spyloc_errors.py SCENE ESTIMATES.jsonl [--verbose] [--json]

Why: `locus eval --metric spyloc` gives the error CDF but not how often the reported std_m covers the
true error (the calibration: ~68 % within 1 sigma, ~95 % within 2); this maps each estimate's t_s
(the walker's local clock) to true time with the scene's truth clocks, interpolates the walker's true
position in truth.csv and compares. --verbose prints one line per estimate (time, error, std, LoS,
flags). Needs python3-numpy and python3-yaml.
"""
import argparse
import csv
import json
import math
import os

import numpy as np
import yaml


def errors(scene, estimates):
    """[(t_s, error_m, std_m, los, flags)] for every estimate of the scene's audio device."""
    y = yaml.safe_load(open(os.path.join(scene, 'scene.yaml')))
    clocks = (y.get('truth') or {}).get('clocks', {}) or {}
    dev = [d['id'] for d in y['devices'] if d.get('audio')][0]
    c = clocks.get(dev, {}) or {}
    off, skew = c.get('offset_s', 0.0), c.get('skew_ppm', 0.0)
    rows = [r for r in csv.DictReader(open(os.path.join(scene, 'truth.csv'))) if r['id'] == dev]
    T = np.array([float(r['t']) for r in rows])
    X = np.array([float(r['x']) for r in rows])
    Y = np.array([float(r['y']) for r in rows])
    out = []
    for line in open(estimates):
        e = json.loads(line)
        if e.get('type') != 'estimate' or e.get('target') != dev:
            continue
        tt = (e['t_s'] - off) / (1.0 + skew * 1e-6)
        err = math.hypot(e['position_m'][0] - np.interp(tt, T, X), e['position_m'][1] - np.interp(tt, T, Y))
        out.append((e['t_s'], err, e.get('std_m') or float('nan'), e.get('los'), e.get('flags', [])))
    return out


def summary(rows):
    e = np.array([r[1] for r in rows])
    s = np.array([r[2] for r in rows])
    if len(e) == 0:
        return {'estimates': 0}
    return {'estimates': int(len(e)), 'median_m': float(np.median(e)), 'p90_m': float(np.percentile(e, 90)),
            'max_m': float(e.max()), 'within_1std': float(np.mean(e <= s)), 'within_2std': float(np.mean(e <= 2 * s))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('estimates')
    ap.add_argument('--verbose', action='store_true')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args()
    rows = errors(a.scene, a.estimates)
    if a.verbose:
        for t, err, std, los, flags in rows:
            print(f'{t:8.2f} error {err:6.2f} m  std {std:6.2f} m  los {los}  {" ".join(flags)}')
    s = summary(rows)
    if a.json:
        print(json.dumps(s))
    elif s['estimates']:
        print(f"{s['estimates']} estimates: median {s['median_m']:.2f} m, p90 {s['p90_m']:.2f} m, max {s['max_m']:.2f} m; "
              f"within 1 std {100 * s['within_1std']:.0f} %, within 2 std {100 * s['within_2std']:.0f} %")
    else:
        print('no estimates')


if __name__ == '__main__':
    main()
