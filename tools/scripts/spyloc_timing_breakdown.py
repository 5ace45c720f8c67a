#!/usr/bin/env python3
"""Where the first-path timing error of SpyLoc LoS beeps comes from (issue 16).

usage: spyloc_timing_breakdown.py [--locus build/bin/locus] [--config config/spyloc.yaml]
                                  [--json OUT] SCENE_DIR...

Replays each scene (`locus replay --events audio_detection`), pairs the detections with the beeps as
tools/scripts/check_spyloc_arrivals.py does (its truth and matching), and splits the LoS beeps found
with the right identity by:
  * error class: within 1 sample; carrier-cycle slips (1-5 samples: one or two periods of ~2.3
    samples when the detector reports a carrier period); 5-20; beyond 20 samples (a lobe/echo: the
    error is compared with the floor and ceiling images' extra delay from the geometry);
  * the detector's snr_db, the floor image's extra delay (samples; room height from the scene), the
    walker's radial speed (Doppler) and the reported confidence;
  * with carrier-timed detections (envelope_frame, carrier_period): the envelope error's spread and
    the carrier-phase residual (error modulo one period), which separate "wrong cycle" from
    "sub-sample bias".
Prints one block per group of scenes (spyloc-104-like scenes with truth-extra.yaml apart from
simulated ones). Needs python3-numpy and python3-yaml.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_spyloc_arrivals as C  # noqa: E402  (its truth and event reading)


def rows_of(scene_dir, det_path):
    scene, fs, c, room = C.read_scene(scene_dir)
    if room is None:
        sys.exit(f'{scene_dir}/scene.yaml: environment.room is missing (needed for the image delays)')
    height = float(room[2])
    device = next(d['id'] for d in scene['devices'] if d.get('audio'))
    masks = {}
    for e in scene.get('emitters') or []:
        for s in e.get('emits') or []:
            if s.get('type') == 'multitone':
                masks[e['id']] = sum(1 << int(round((float(t) - 18000.0) / 250.0)) for t in s['tones_hz'])
    anchors = {e['id']: np.array(e['anchor']['position'], float) for e in scene['emitters'] if 'anchor' in e}
    beeps = C.beeps_from_extra(scene_dir)
    if beeps is None:
        beeps = C.beeps_from_geometry(scene_dir, scene, device)
    best, _ = C.match_detections(beeps, C.read_events(det_path, 'audio_detection', device), 0.03 * fs)
    with open(os.path.join(scene_dir, scene['truth'].get('trajectories', 'truth.csv'))) as f:
        traj = np.array([[float(r[k]) for k in ('t', 'x', 'y', 'z')] for r in csv.DictReader(f) if r['id'] == device])
    ck = scene['truth']['clocks'].get(device, {'offset_s': 0.0, 'skew_ppm': 0.0})
    out = []
    for j, b in enumerate(beeps):
        d = best.get(j)
        if not b['los'] or d is None or int(d['template']) != masks.get(b['beacon']):
            continue
        t = (b['first'] / fs - float(ck.get('offset_s', 0.0))) / (1.0 + float(ck.get('skew_ppm', 0.0)) * 1e-6)
        k = min(max(int(np.searchsorted(traj[:, 0], t)), 0), len(traj) - 1)
        pr, ps = traj[k, 1:4], anchors[b['beacon']]
        dh = np.linalg.norm(pr[:2] - ps[:2])
        direct = np.hypot(dh, pr[2] - ps[2])
        k1, k2 = max(k - 5, 0), min(k + 5, len(traj) - 1)
        vr = (np.linalg.norm(traj[k2, 1:4] - ps) - np.linalg.norm(traj[k1, 1:4] - ps)) / max(traj[k2, 0] - traj[k1, 0], 1e-9)
        period = float(d.get('carrier_period') or 0.0)
        out.append({'scene': os.path.basename(os.path.normpath(scene_dir)), 'foreign': 'extra' if C.beeps_from_extra(scene_dir) else 'sim',
                    'err': float(d['frame']) - b['first'], 'snr': float(d['snr_db']), 'conf': float(d['confidence']),
                    'env_err': (float(d['envelope_frame']) - b['first']) if period > 0 else None, 'period': period,
                    'floor_delay': (np.hypot(dh, pr[2] + ps[2]) - direct) / c * fs,
                    'ceil_delay': (np.hypot(dh, 2 * height - pr[2] - ps[2]) - direct) / c * fs, 'vr': abs(vr)})
    return out


def pct(x):
    return f'{100.0 * x:.0f} %'


def report(label, rows):
    if not rows:
        return
    e = np.array([r['err'] for r in rows])
    a = np.abs(e)
    snr = np.array([r['snr'] for r in rows])
    fd = np.array([r['floor_delay'] for r in rows])
    img = np.minimum(fd, np.array([r['ceil_delay'] for r in rows]))
    vr = np.array([r['vr'] for r in rows])
    conf = np.array([r['conf'] for r in rows])
    print(f'== {label}: {len(rows)} LoS beeps found with the right identity')
    print(f'  within 1 sample {pct(np.mean(a <= 1))}; 1-5 {pct(np.mean((a > 1) & (a <= 5)))}; 5-20 {pct(np.mean((a > 5) & (a <= 20)))}; '
          f'> 20 {pct(np.mean(a > 20))} (early {int(np.sum(e < -20))}, late {int(np.sum(e > 20))}); median |err| {np.median(a):.2f}')
    late = e > 20
    if late.any():
        print(f'  late > 20: error / nearest image delay, median {np.median(e[late] / img[late]):.2f} '
              f'(quartiles {np.percentile(e[late] / img[late], 25):.2f}-{np.percentile(e[late] / img[late], 75):.2f})')
    for name, v, edges in (('snr_db', snr, (0, 20, 25, 30, 99)), ('floor image delay', fd, (0, 50, 80, 120, 1e4)),
                           ('|radial speed| m/s', vr, (0, 0.3, 0.7, 1.1, 9)), ('confidence', conf, (0, 0.2, 0.5, 0.8, 1.01))):
        parts = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            m = (v >= lo) & (v < hi)
            if m.any():
                parts.append(f'[{lo:g}, {hi:g}): n {int(m.sum())}, within 1 {pct(np.mean(a[m] <= 1))}, > 20 {pct(np.mean(a[m] > 20))}')
        print(f'  by {name}: ' + '; '.join(parts))
    env = np.array([r['env_err'] for r in rows if r['env_err'] is not None])
    if len(env):
        per = np.array([r['period'] for r in rows if r['env_err'] is not None])
        ee = np.array([r['err'] for r in rows if r['env_err'] is not None])
        m = np.abs(env) < 10
        resid = (ee + per / 2) % per - per / 2
        mid = (np.abs(ee) > 1) & (np.abs(ee) <= 5)
        slips = np.abs(np.abs(ee[mid]) / per[mid] - np.round(np.abs(ee[mid]) / per[mid])) * per[mid] < 0.3
        print(f'  carrier-timed: envelope error (|.| < 10) mean {env[m].mean():+.2f} std {env[m].std():.2f} samples, '
              f'within half a period {pct(np.mean(np.abs(env) <= per / 2))}; carrier-phase residual (error modulo the '
              f'period) std {resid[m].std():.3f} samples; of the 1-5 sample errors, whole periods (±0.3) '
              f'{pct(np.mean(slips)) if mid.any() else "-"}')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--locus', default='build/bin/locus')
    ap.add_argument('--config', default='config/spyloc.yaml')
    ap.add_argument('--json', default=None, help='write the per-beep rows here')
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix='spyloc-timing-') as tmp:
        for i, sc in enumerate(a.scenes):
            if not os.path.exists(os.path.join(sc, 'scene.yaml')):
                sys.exit(f'{sc}: no scene.yaml')
            det = os.path.join(tmp, f'{i}.jsonl')
            with open(det, 'w') as f:
                r = subprocess.run([a.locus, 'replay', sc, '--config', a.config, '--speed', 'max', '--events', 'audio_detection'],
                                   stdout=f, stderr=subprocess.PIPE, text=True)
            if r.returncode != 0:
                sys.exit(f'{sc}: locus replay failed (exit {r.returncode}): {r.stderr.strip()[-500:]}')
            rows += rows_of(sc, det)
    if a.json:
        with open(a.json, 'w') as f:
            json.dump(rows, f)
    report('scenes with truth-extra.yaml (foreign generator)', [r for r in rows if r['foreign'] == 'extra'])
    report('simulated scenes', [r for r in rows if r['foreign'] == 'sim'])


if __name__ == '__main__':
    main()
