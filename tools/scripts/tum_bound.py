#!/usr/bin/env python3
"""TUM: what the arrivals of a static formation can tell (docs/tum.md, "The bound").

usage: tum_bound.py SCENE... [--timing-std-samples 0.06] [--bias-std-samples 0.04] [--yaw-std-rad 0.2]
                    [--height-std-m 0.1] [--exchanges N] [--no-roots] [--draws 4000]
                    [--locus build/bin/locus --config config/tum.yaml] [--json]

Why: issue 14's static bars (Eq. 23 median <= 5 cm, p90 <= 12 cm on 20 static seeds) are only worth
chasing if the arrivals can carry them. A still device that only listens (a monitor) hears the two
working devices' tones at its two microphones: four arrival times, one unknown clock offset, so three
numbers for its four unknowns (x, y, z and heading; its tilt comes from gravity). The priors on
heading (the magnetometer) and height supply the fourth, and the three equations can have several
exact roots, which only the heading tells apart. Every exchange of a still scene repeats the same
geometry: more exchanges average the timing noise but add nothing else.

Model, from the scene's truth: every arrival the exchange produces (each working device's tone at
each microphone of every device, its own included), at the true positions and attitudes of truth.csv,
for every exchange of the scene (truth_emissions.csv of `locus simulate tum`, or truth-extra.yaml's
emissions of the foreign generator); timing error per arrival = a part that repeats at every exchange
(per path: device, mic, emitter; --bias-std-samples: reflections of a still room) + one that does
not (--timing-std-samples); measured with tools/scripts/check_tum_arrivals.py on our simulator:
0.013-0.038 and 0.054-0.060 samples. Unknown per exchange: the two emission times and every device's
clock offset except device 1's (loose clocks; Eq. 2-4 and 17-21 use local time differences only).
Unknown per device other than device 1 (the frame, docs/eval.md): its position and its heading with
the prior --yaw-std-rad (our attitude detector's heading relative to device 1's over the 60 device
headings of `-o heights=table` seeds 1-20, tools/scripts/heading_errors.py: 11.5 deg = 0.20 rad rms with the world's hard iron that
`locus simulate tum` now draws, 4.8 deg = 0.085 rad with the 1 uT it drew before; tum-102: B 14 deg,
C 1-2, D 2-7),
and its height with the prior --height-std-m.

Two parts, combined per scene in --draws Monte Carlo draws of Eq. 23 (locus eval --metric tum: the
mean absolute error of the pairwise distances):
  local    the Bayesian Cramer-Rao bound: the Fisher information at the truth plus the priors',
           inverted; its position block drawn as a Gaussian error about the chosen root;
  roots    per device, every exact root of one noiseless exchange with the other devices at their
           truth (Gauss-Newton from a grid of starts; --root-tol-samples), each with its residuals.
           In every draw the ideal estimator knows them all and picks the most probable: the heading
           prior about a heading drawn with the attitude error, the height prior about the TRUE height
           (more than any estimator knows) and the residuals against path errors drawn as above.
           A wrong root moves the device by the root's offset.
The draws of all scenes pooled give the median and p90 such an estimator would show (the local part
bounds the mean squared error, not strictly a quantile of a non-Gaussian error). Only static scenes
(a moving device's motion prior is the estimator's choice): a scene with a moving device is refused.
Where heights differ (tripods) the roots form a continuum along the unobserved direction and the
local part alone is the bound: --no-roots.

With --locus each scene is also replayed through --config and its measured Eq. 23 median / p90
printed beside the bound. Needs python3-numpy and python3-yaml.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from campaign_common import quat_matrix  # noqa: E402


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class Scene:
    """Devices (mics, speaker, emits), static truth poses, the exchanges' emitters."""

    def __init__(self, path):
        self.path = path
        with open(os.path.join(path, 'scene.yaml')) as f:
            y = yaml.safe_load(f)
        self.fs = float(y.get('sample_rate', 44100))
        self.c = float(y.get('speed_of_sound', 343.0))
        self.devices = []
        for d in y['devices']:
            if len(d.get('mics') or []) < 2:
                continue
            self.devices.append({'id': d['id'], 'mics': [np.array(m, float) for m in d['mics']],
                                 'speaker': np.array(d['speaker'], float) if d.get('speaker') is not None else None,
                                 'emits': bool(d.get('emits'))})
        working = [d['id'] for d in self.devices if d['emits'] and d['speaker'] is not None]
        if len(working) < 2:
            raise SystemExit(f'tum_bound: {path}: fewer than two devices emit: not a TUM exchange')
        self.working = working[:2]
        rows = {}
        with open(os.path.join(path, 'truth.csv')) as f:
            for r in csv.DictReader(f):
                rows.setdefault(r['id'], []).append(
                    (np.array([float(r[c]) for c in 'xyz']), [float(r[c]) for c in ('qw', 'qx', 'qy', 'qz')]))
        self.pose = {}
        for d in self.devices:
            rs = rows.get(d['id'])
            if not rs:
                raise SystemExit(f"tum_bound: {path}/truth.csv: no row for device {d['id']}")
            spread = max(float(np.linalg.norm(p - rs[0][0])) for p, _ in rs)
            if spread > 0.01:
                raise SystemExit(f"tum_bound: {path}: device {d['id']} moves ({spread:.2f} m): only static scenes are bounded")
            self.pose[d['id']] = (rs[0][0], np.array(quat_matrix(rs[0][1])))
        self.exchanges = self._exchanges(y)

    def _exchanges(self, y):
        """Number of exchanges: emissions of the working pair, paired in time order."""
        counts = {w: 0 for w in self.working}
        emissions = os.path.join(self.path, (y.get('environment') or {}).get('truth_emissions', 'truth_emissions.csv'))
        if os.path.exists(emissions):
            with open(emissions) as f:
                for r in csv.DictReader(f):
                    if r['id'] in counts:
                        counts[r['id']] += 1
        else:
            extra = os.path.join(self.path, 'truth-extra.yaml')
            if not os.path.exists(extra):
                raise SystemExit(f'tum_bound: {self.path}: neither truth_emissions.csv nor truth-extra.yaml: no exchanges known')
            with open(extra) as f:
                for e in (yaml.safe_load(f) or {}).get('emissions') or []:
                    if e.get('emitter') in counts:
                        counts[e['emitter']] += 1
        n = min(counts.values())
        if n < 1:
            raise SystemExit(f'tum_bound: {self.path}: the working devices {self.working} never both emit')
        return n


class Model:
    """The arrivals of K exchanges as a function of the parameters (layout in __init__)."""

    def __init__(self, scene, exchanges):
        self.s = scene
        self.K = exchanges
        ids = [d['id'] for d in scene.devices]
        self.ref = scene.working[0]
        self.others = [i for i in ids if i != self.ref]
        self.dev = {d['id']: d for d in scene.devices}
        # parameters: per other device x, y, z, psi; per exchange e1, e2, clocks of the others; per path
        # (device, mic, emitter) the part of its timing error that repeats at every exchange
        self.n_geo = 4 * len(self.others)
        self.n_per_k = 2 + len(self.others)
        self.n_paths = sum(len(dv['mics']) * 2 for dv in self.dev.values())
        self.path0 = self.n_geo + self.K * self.n_per_k
        self.n = self.path0 + self.n_paths

    def truth(self):
        p = np.zeros(self.n)
        for i, d in enumerate(self.others):
            p[4 * i:4 * i + 3] = self.s.pose[d][0]
        return p

    def pose(self, p, d):
        x0, r0 = self.s.pose[d]
        if d == self.ref:
            return x0, r0
        i = self.others.index(d)
        return p[4 * i:4 * i + 3], rot_z(p[4 * i + 3]) @ r0

    def arrivals(self, p):
        """Every arrival time (s, up to the common clock of device 1) of every exchange."""
        out = []
        poses = {d: self.pose(p, d) for d in self.dev}
        spk = {w: poses[w][0] + poses[w][1] @ self.dev[w]['speaker'] for w in self.s.working}
        dist = []
        for d, dv in self.dev.items():
            x, r = poses[d]
            for m in dv['mics']:
                mic = x + r @ m
                for w in self.s.working:
                    dist.append((d, w, np.linalg.norm(mic - spk[w]) / self.s.c))
        for k in range(self.K):
            base = self.n_geo + k * self.n_per_k
            for path, (d, w, tof) in enumerate(dist):
                e = p[base + self.s.working.index(w)]
                clock = 0.0 if d == self.ref else p[base + 2 + self.others.index(d)]
                out.append(e + tof + clock + p[self.path0 + path])
        return np.array(out)

    def jacobian(self, p, h=1e-6, geo=None):
        # Geometry columns by central differences (only those in geo, default all); the emission,
        # clock and path columns are 0/1 indicators.
        dist_rows = sum(len(dv['mics']) * 2 for dv in self.dev.values())
        J = np.zeros((self.K * dist_rows, self.n))
        for j in (range(self.n_geo) if geo is None else geo):
            a, b = p.copy(), p.copy()
            a[j] += h
            b[j] -= h
            J[:, j] = (self.arrivals(a) - self.arrivals(b)) / (2 * h)
        row = 0
        for k in range(self.K):
            base = self.n_geo + k * self.n_per_k
            path = 0
            for d, dv in self.dev.items():
                for _m in dv['mics']:
                    for w in self.s.working:
                        J[row, base + self.s.working.index(w)] = 1.0
                        if d != self.ref:
                            J[row, base + 2 + self.others.index(d)] = 1.0
                        J[row, self.path0 + path] = 1.0
                        row += 1
                        path += 1
        return J


def norm_cdf(x):
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def roots(scene, args):
    """Every exact root of one exchange's noiseless arrivals per device other than device 1 (the
    others at their truth): its (x, y, z, psi offset) for which every arrival of the exchange is
    reproduced to --root-tol-samples, found by Gauss-Newton from a grid of starts. The truth is one;
    any other is a formation the arrivals can tell from the truth only by its residuals (returned per
    path, in samples), against timing errors that do not average out over a still scene's exchanges."""
    m = Model(scene, 1)
    p_true = m.truth()
    y = m.arrivals(p_true)
    nuis = list(range(m.n_geo, m.n_geo + m.n_per_k))
    out = {}
    for i, d in enumerate(m.others):
        cols = [4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3] + nuis
        found = []
        x0 = p_true[4 * i:4 * i + 3]
        for r in (0.0, 0.6, 1.2, 2.0, 3.0):
            for a in np.linspace(0, 2 * math.pi, 1 if r == 0 else 10, endpoint=False):
                for psi0 in (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi):
                    p = p_true.copy()
                    p[4 * i:4 * i + 3] = x0 + r * np.array([math.cos(a), math.sin(a), 0.0])
                    p[4 * i + 3] = psi0
                    lam = 1e-3
                    cost = float(np.sum((m.arrivals(p) - y) ** 2))
                    for _it in range(40):
                        J = m.jacobian(p, geo=cols[:4])[:, cols]
                        res = m.arrivals(p) - y
                        A = J.T @ J
                        step = -np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-30), J.T @ res)
                        q = p.copy()
                        q[cols] += step
                        c = float(np.sum((m.arrivals(q) - y) ** 2))
                        if c < cost:
                            p, cost, lam = q, c, lam * 0.3
                        else:
                            lam *= 10.0
                        if cost < 1e-30 or lam > 1e12:
                            break
                    rms = math.sqrt(cost / len(y)) * scene.fs
                    if rms > args.root_tol_samples:
                        continue
                    psi = math.atan2(math.sin(p[4 * i + 3]), math.cos(p[4 * i + 3]))
                    x = p[4 * i:4 * i + 3].copy()
                    if all(np.linalg.norm(x - f[0]) > 0.02 or abs(psi - f[1]) > 0.01 for f in found):
                        # residual per path (samples), up to the exchange's free emission times and clocks
                        found.append((x, psi, (m.arrivals(p) - y) * scene.fs))
        out[d] = found
    return out


def bound(scene, args):
    K = scene.exchanges if args.exchanges is None else min(args.exchanges, scene.exchanges)
    m = Model(scene, K)
    p = m.truth()
    J = m.jacobian(p)
    sigma_t = args.timing_std_samples / scene.fs
    F = J.T @ J / sigma_t ** 2
    sigma_b = max(args.bias_std_samples, 1e-6) / scene.fs
    for j in range(m.path0, m.n):
        F[j, j] += 1.0 / sigma_b ** 2
    up = np.array([0.0, 0.0, 1.0])
    for i, _d in enumerate(m.others):
        if args.yaw_std_rad > 0:
            F[4 * i + 3, 4 * i + 3] += 1.0 / args.yaw_std_rad ** 2
        if args.height_std_m > 0:
            F[4 * i:4 * i + 3, 4 * i:4 * i + 3] += np.outer(up, up) / args.height_std_m ** 2
    cov = np.linalg.inv(F)
    pos_idx = [4 * i + j for i in range(len(m.others)) for j in range(3)]
    C = cov[np.ix_(pos_idx, pos_idx)]
    C = 0.5 * (C + C.T)
    # Eq. 23 drawn from the bound's Gaussian: every unordered pair, device 1 fixed at its truth.
    ids = [m.ref] + m.others
    truth = np.array([scene.pose[d][0] for d in ids])
    rng = np.random.default_rng(args.seed)
    L = np.linalg.cholesky(C + 1e-15 * np.eye(len(pos_idx)))
    pairs = [(a, b) for a in range(len(ids)) for b in range(a + 1, len(ids))]
    true_d = np.array([np.linalg.norm(truth[a] - truth[b]) for a, b in pairs])
    # The roots the arrivals cannot tell apart: the estimator that knows them all picks, per device,
    # the one the priors favour (its heading offset against the magnetometer's, drawn with its error
    # --yaw-std-rad; its height against its true height, --height-std-m: a prior that knows more than
    # any estimator, so the choice is never worse than a real one's), the ideal Bayes choice; a wrong
    # one moves the device.
    # The data term: a root's residuals against the path errors of the whole scene (the repeating part
    # and the average over K exchanges of the rest).
    root_sets = roots(scene, args) if args.roots else {d: [] for d in m.others}
    sigma_path = math.sqrt(args.bias_std_samples ** 2 + args.timing_std_samples ** 2 / K)
    draws = np.zeros(args.draws)
    wrong = np.zeros(args.draws, bool)
    for n in range(args.draws):
        e = (L @ rng.standard_normal(len(pos_idx))).reshape(-1, 3)
        est = truth.copy()
        est[1:] += e
        for i, d in enumerate(m.others):
            cands = root_sets.get(d) or []
            if len(cands) < 2:
                continue
            eta = rng.normal(0.0, args.yaw_std_rad)
            noise = rng.normal(0.0, sigma_path, len(cands[0][2]))
            score = [-(psi - eta) ** 2 / (2 * args.yaw_std_rad ** 2) -
                     (((x[2] - truth[1 + i][2]) ** 2 / (2 * args.height_std_m ** 2)) if args.height_std_m > 0 else 0.0) -
                     0.5 * float(np.sum(((res - noise) / sigma_path) ** 2))
                     for x, psi, res in cands]
            x, _psi, _res = cands[int(np.argmax(score))]
            if np.linalg.norm(x - truth[1 + i]) > 1e-3:
                est[1 + i] += x - truth[1 + i]
                wrong[n] = True
        draws[n] = np.mean(np.abs(np.array([np.linalg.norm(est[a] - est[b]) for a, b in pairs]) - true_d))
    per_device = {}
    for i, d in enumerate(m.others):
        b = C[3 * i:3 * i + 3, 3 * i:3 * i + 3]
        per_device[d] = {'horizontal_rms_m': math.sqrt(b[0, 0] + b[1, 1]), 'vertical_rms_m': math.sqrt(b[2, 2]),
                         'yaw_rms_rad': math.sqrt(cov[4 * i + 3, 4 * i + 3])}
    for d, cands in root_sets.items():
        t = scene.pose[d][0]
        per_device.setdefault(d, {})['other_roots'] = [
            {'offset_m': float(np.linalg.norm(x - t)), 'yaw_offset_rad': psi, 'position_m': [float(v) for v in x]}
            for x, psi, _res in cands if np.linalg.norm(x - t) > 1e-3]
    return {'scene': os.path.basename(os.path.normpath(scene.path)), 'exchanges': K, 'reference': m.ref,
            'wrong_root_fraction': float(np.mean(wrong)),
            'devices': per_device, 'eq23_median_m': float(np.median(draws)), 'eq23_p90_m': float(np.percentile(draws, 90)),
            'draws': draws}


def measured(scene_path, args):
    est = os.path.join(args.work, os.path.basename(os.path.normpath(scene_path)) + '.bound.jsonl')
    subprocess.run([args.locus, 'replay', scene_path, '--config', args.config, '--speed', 'max', '-o', est],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = subprocess.run([args.locus, 'eval', scene_path, est, '--metric', 'tum', '--json'], capture_output=True, text=True)
    if out.returncode not in (0, 4):
        raise SystemExit(f'tum_bound: locus eval {scene_path}: exit {out.returncode}: {out.stderr.strip()}')
    s = json.loads(out.stdout)['plugins'][0]['summary']
    return s['median_error_m'], s['p90_error_m']


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--timing-std-samples', type=float, default=0.06,
                    help='timing error that changes from exchange to exchange (1 sigma, samples)')
    ap.add_argument('--bias-std-samples', type=float, default=0.04,
                    help='timing error of a path that repeats at every exchange of a still scene (1 sigma, samples)')
    ap.add_argument('--yaw-std-rad', type=float, default=0.2,
                    help='heading error of a device relative to device 1 (1 sigma, rad)')
    ap.add_argument('--height-std-m', type=float, default=0.1)
    ap.add_argument('--exchanges', type=int, default=None, help='bound with the first N exchanges (default: all)')
    ap.add_argument('--draws', type=int, default=4000)
    ap.add_argument('--root-tol-samples', type=float, default=0.2,
                    help='a root reproduces every arrival of the exchange to this rms (samples); its residuals weigh in the choice')
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--no-roots', dest='roots', action='store_false',
                    help='the local bound only (no search for the other exact roots)')
    ap.add_argument('--locus')
    ap.add_argument('--config', default='config/tum.yaml')
    ap.add_argument('--work', default='/tmp')
    ap.add_argument('--json', action='store_true')
    args = ap.parse_args()
    results, pooled = [], []
    for path in args.scenes:
        r = bound(Scene(path), args)
        pooled.append(r['draws'])
        if args.locus:
            r['measured_median_m'], r['measured_p90_m'] = measured(path, args)
        results.append(r)
    allv = np.concatenate(pooled)
    summary = {'scenes': len(results), 'eq23_median_m': float(np.median(allv)), 'eq23_p90_m': float(np.percentile(allv, 90)),
               'wrong_root_fraction': float(np.mean([r['wrong_root_fraction'] for r in results])),
               'timing_std_samples': args.timing_std_samples, 'yaw_std_rad': args.yaw_std_rad, 'height_std_m': args.height_std_m}
    if args.json:
        for r in results:
            del r['draws']
        print(json.dumps({'summary': summary, 'scenes': results}, indent=1))
        return
    print('| scene | exchanges | bound Eq. 23 median / p90 cm | wrong root | horizontal rms per device (cm) | other roots (m off, yaw offset rad) | measured median / p90 cm |')
    print('|---|---|---|---|---|---|---|')
    for r in results:
        dev = ', '.join(f"{d} {v['horizontal_rms_m'] * 100:.1f}" for d, v in r['devices'].items())
        rts = '; '.join(f"{d}: " + ', '.join(f"{o['offset_m']:.2f} ({o['yaw_offset_rad']:+.2f})" for o in v['other_roots'])
                        for d, v in r['devices'].items() if v.get('other_roots')) or '—'
        meas = f"{r['measured_median_m'] * 100:.1f} / {r['measured_p90_m'] * 100:.1f}" if 'measured_median_m' in r else '—'
        print(f"| {r['scene']} | {r['exchanges']} | {r['eq23_median_m'] * 100:.1f} / {r['eq23_p90_m'] * 100:.1f} | "
              f"{r['wrong_root_fraction'] * 100:.0f} % | {dev} | {rts} | {meas} |")
    print(f"| **pooled ({len(results)} scenes)** | | **{summary['eq23_median_m'] * 100:.1f} / {summary['eq23_p90_m'] * 100:.1f}** | "
          f"{summary['wrong_root_fraction'] * 100:.0f} % | | | |")


if __name__ == '__main__':
    main()
