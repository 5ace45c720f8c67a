#!/usr/bin/env python3
"""Heading error of every still device's attitude detector, relative to a reference device's
(docs/tum.md "The bound": the heading prior `tum_bound.py --yaw-std-rad` takes from it).

usage: heading_errors.py --locus BIN SCENE... [--config config/tum.yaml] [--reference ID] [--after-s 5]

Each scene is replayed through --config with `attitude` events written; per device, the circular mean
of the detector's heading of the body y axis after --after-s (local time, the filter settled) minus
the truth's (truth.csv's first row: still devices) is its error; the reference (default: the first
device of scene.yaml) is subtracted, which removes the magnetic declination common to all. Prints
each scene's errors and the rms over every device of every scene. Needs python3-yaml.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from campaign_common import quat_matrix  # noqa: E402


def heading_of(q):
    r = quat_matrix(q)
    return math.atan2(r[1][1], r[0][1])  # the body y axis in the reference frame


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def scene_errors(locus, scene, config, reference, after_s):
    with open(os.path.join(scene, 'scene.yaml')) as f:
        ids = [d['id'] for d in yaml.safe_load(f)['devices']]
    reference = reference or ids[0]
    truth = {}
    with open(os.path.join(scene, 'truth.csv')) as f:
        for r in csv.DictReader(f):
            truth.setdefault(r['id'], [float(r[c]) for c in ('qw', 'qx', 'qy', 'qz')])
    with tempfile.NamedTemporaryFile(suffix='.jsonl') as out:
        subprocess.run([locus, 'replay', scene, '--config', config, '--speed', 'max', '--events', 'attitude', '-o', out.name],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        sums = {}
        with open(out.name) as f:
            for line in f:
                e = json.loads(line)
                if e.get('type') != 'attitude' or e['t_s'] < after_s:
                    continue
                h = heading_of(e['q_wxyz'])
                s = sums.setdefault(e['device'], [0.0, 0.0])
                s[0] += math.sin(h)
                s[1] += math.cos(h)
    if reference not in sums:
        raise SystemExit(f'heading_errors: {scene}: no attitude events of the reference device {reference}')
    err = {d: wrap(math.atan2(*s) - heading_of(truth[d])) for d, s in sums.items() if d in truth}
    return {d: wrap(e - err[reference]) for d, e in err.items() if d != reference}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--locus', required=True)
    ap.add_argument('--config', default='config/tum.yaml')
    ap.add_argument('--reference')
    ap.add_argument('--after-s', type=float, default=5.0)
    a = ap.parse_args()
    every = []
    for scene in a.scenes:
        e = scene_errors(a.locus, scene, a.config, a.reference, a.after_s)
        every += list(e.values())
        print(os.path.basename(os.path.normpath(scene)) + ': ' + ', '.join(f'{d} {math.degrees(v):+.1f} deg' for d, v in sorted(e.items())))
    rms = math.sqrt(sum(v * v for v in every) / len(every))
    print(f'rms over {len(every)} device headings: {math.degrees(rms):.1f} deg = {rms:.3f} rad '
          f'(largest {math.degrees(max(abs(v) for v in every)):.1f} deg)')


if __name__ == '__main__':
    main()
