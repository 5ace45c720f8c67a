#!/usr/bin/env python3
"""LocBLE: the Bayesian Cramér-Rao bound of a tag's position from one L-walk (docs/locble.md, "The bound").

usage: locble_bound.py SCENE... [--locus build/bin/locus --config config/locble.yaml] [--known-model]
                       [--cluster-radius-m R]
                       [--fading-db 3.5] [--shadowing-db 1.3] [--decorrelation-m 2.5] [--channel-db 2]
                       [--common-db 3.6] [--link-db 4] [--n 2.5] [--n-sd 0.5] [--position-sd-m 11.5] [--json]

Why: the issue's bars (mean final error <= 1.8 m on locble-105 and its kind, <= 1.5 m on our simulator)
are only worth chasing if the data can carry them. For every tag this computes, from the scene's truth,
what no estimator of the readings can beat (in mean squared error): the observer's TRUE path (truth.csv
at each reading's true time, from the clock in scene.yaml), the tag's true position, every reading
ble.csv holds (its advertising channel), and the world's RSS model as `../shared/scenes/README.md`
states it and locble-105's truth-extra.yaml quantifies it:

    RSS = G0 + delta_env - 10 n_env log10(d) + shadowing(position) + channel_offset + fading

unknown G0 (the tag's true 1 m power and the receiver's offset against the advertised power,
prior sd --common-db), a static offset per link and environment class (LOS / pLOS / NLOS: prior sd
--link-db) and an exponent per class (prior --n +- --n-sd); shadowing --shadowing-db, exponentially
correlated over --decorrelation-m of the walk within one class; one offset per advertising channel
(--channel-db, shared by the readings on it); fading --fading-db per packet. The classes come from
truth-extra.yaml's ble_rows (the foreign generator) or truth_ble_env.csv (`locus simulate locble`);
--known-model treats every reading as one class (the bound if the environment never changed).
A weak prior on the position (--position-sd-m, the estimator's +-20 m search square) keeps far tags
finite. The bound is the inverse Fisher information of (x, y, G0, delta_c, n_c), linearised at the
truth; its position block gives an rms error. A 2D Gaussian error of rms r has mean 0.886 r: printed
as the mean-error equivalent, what the issue's "mean final error" compares with (a lower bound on the
rms, not strictly on the mean of a non-Gaussian error; it is what an efficient estimator would show).

--cluster-radius-m R adds, per tag, the bound when the readings of every tag truly within R m of it
are fused (each keeps its own G0, link offsets and exponents; the position is shared as if co-located):
what perfect clustering (paper Sec. 6, Fig. 15) could give, membership known.

With --locus the scenes are also replayed through --config and each tag's final error (locus eval
--metric locble) is printed beside its bound. Needs python3-numpy and python3-yaml.
"""
import argparse
import bisect
import csv
import json
import math
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import locble_campaign as LC  # noqa: E402  (its scene reading and scoring)


def load_scene(scene):
    with open(os.path.join(scene, 'scene.yaml')) as f:
        y = yaml.safe_load(f)
    address_tag = {address: tag for tag, address in LC.tag_addresses(scene).items()}
    observer = next(d for d in y['devices'] if d.get('ble'))
    clock = (y.get('truth', {}).get('clocks', {}) or {}).get(observer['id'], {}) or {}
    offset, skew = float(clock.get('offset_s', 0.0)), float(clock.get('skew_ppm', 0.0)) * 1e-6
    traj = {}
    with open(os.path.join(scene, y['truth'].get('trajectories', 'truth.csv'))) as f:
        for r in csv.DictReader(f):
            traj.setdefault(r['id'], []).append((float(r['t']), float(r['x']), float(r['y'])))
    traj = {k: np.array(sorted(v)) for k, v in traj.items()}
    readings = []
    with open(os.path.join(scene, observer['ble'])) as f:
        for r in csv.DictReader(f):
            tag = address_tag.get(r['address'].upper())
            if tag is not None:
                readings.append({'t_true': (float(r['t']) - offset) / (1.0 + skew), 'tag': tag,
                                 'channel': r.get('channel', '0')})
    env_of = environment_lookup(scene, y, readings)
    for r in readings:
        r['env'] = env_of(r)
    return y, observer['id'], traj, readings


def environment_lookup(scene, y, readings):
    """Per reading, its environment class: truth-extra.yaml ble_rows (same order as ble.csv), else
    truth_ble_env.csv (the latest row of the tag at or before the reading), else one class."""
    extra = os.path.join(scene, 'truth-extra.yaml')
    if os.path.exists(extra):
        with open(extra) as f:
            ex = yaml.safe_load(f)
        rows = (ex.get('ble_rows') or {}).get('rows')
        cols = (ex.get('ble_rows') or {}).get('columns')
        if rows and cols and len(rows) == len(readings) and 'env' in cols:
            k = cols.index('env')
            envs = [row[k] for row in rows]
            index = {id(r): i for i, r in enumerate(readings)}
            return lambda r: envs[index[id(r)]]
    name = (y.get('environment') or {}).get('truth_ble_env')
    if name and os.path.exists(os.path.join(scene, name)):
        table = {}
        with open(os.path.join(scene, name)) as f:
            for r in csv.DictReader(f):
                table.setdefault(r['tag'], []).append((float(r['t_true']), r['env']))
        for v in table.values():
            v.sort()

        def env(r):
            rows = table.get(r['tag'])
            if not rows:
                return 'X'
            i = bisect.bisect_right([t for t, _ in rows], r['t_true']) - 1
            return rows[max(i, 0)][1]
        return env
    return lambda r: 'X'


def mean_rss(theta, px, py, env_index, m):
    """The model's mean RSS (dB, relative to the advertised power) at each reading. theta = (x, y,
    G0, delta_0..delta_m-1, n_0..n_m-1); env_index: the class of each reading (0..m-1)."""
    d = np.maximum(np.hypot(theta[0] - px, theta[1] - py), 0.1)
    return theta[2] + theta[3 + env_index] - 10.0 * theta[3 + m + env_index] * np.log10(d)


def jacobian(theta, px, py, env_index, m):
    """d mean_rss / d theta, one row per reading."""
    dx, dy = theta[0] - px, theta[1] - py
    d = np.maximum(np.hypot(dx, dy), 0.1)
    n = theta[3 + m + env_index]
    g = np.zeros((len(d), 3 + 2 * m))
    g[:, 0] = -10.0 * n / math.log(10.0) * dx / d ** 2
    g[:, 1] = -10.0 * n / math.log(10.0) * dy / d ** 2
    g[:, 2] = 1.0
    rows = np.arange(len(d))
    g[rows, 3 + env_index] = 1.0
    g[rows, 3 + m + env_index] = -10.0 * np.log10(d)
    return g


def position_information(path, tag_xy, readings, a):
    """The Fisher information of one tag's (x, y) from its readings, its own nuisances (G0, delta_c,
    n_c, with their priors) marginalised (Schur complement); also its mean distance and classes.
    Linearised at the true position and the prior's exponent (a.n) in every class."""
    t = np.array([r['t_true'] for r in readings])
    px = np.interp(t, path[:, 0], path[:, 1])
    py = np.interp(t, path[:, 0], path[:, 2])
    env = ['X' if a.known_model else r['env'] for r in readings]
    classes = sorted(set(env))
    m = len(classes)
    env_index = np.array([classes.index(e) for e in env], dtype=int)
    theta = np.concatenate([[tag_xy[0], tag_xy[1], 0.0], np.zeros(m), np.full(m, a.n)])
    g = jacobian(theta, px, py, env_index, m)
    walk = np.hypot(px[:, None] - px[None, :], py[:, None] - py[None, :])
    same_env = env_index[:, None] == env_index[None, :]
    channel = np.array([r['channel'] for r in readings])
    cov = (a.fading_db ** 2 * np.eye(len(t)) + a.shadowing_db ** 2 * np.exp(-walk / a.decorrelation_m) * same_env
           + a.channel_db ** 2 * (channel[:, None] == channel[None, :]))
    prior = [0.0, 0.0] + [a.common_db ** -2] + [a.link_db ** -2] * m + [a.n_sd ** -2] * m
    info = g.T @ np.linalg.solve(cov, g) + np.diag(prior)
    pos, cross, nuisance = info[:2, :2], info[:2, 2:], info[2:, 2:]
    mean_distance = float(np.mean(np.hypot(tag_xy[0] - px, tag_xy[1] - py)))
    return pos - cross @ np.linalg.solve(nuisance, cross.T), mean_distance, classes


def rms_bound(position_info, a):
    inv = np.linalg.inv(position_info + np.eye(2) / a.position_sd_m ** 2)
    return math.sqrt(inv[0, 0] + inv[1, 1])


def final_errors(locus, config, scene):
    """Final error per tag id from a replay through config (locble_campaign's scoring)."""
    import tempfile
    with tempfile.TemporaryDirectory() as work:
        return {r['target']: r['final_error_m'] for r in LC.score(locus, scene, config, work)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--locus', default=None, help='also replay and score each scene with this binary')
    ap.add_argument('--config', default='config/locble.yaml')
    ap.add_argument('--known-model', action='store_true', help='one environment class per link')
    ap.add_argument('--fading-db', type=float, default=3.5)
    ap.add_argument('--shadowing-db', type=float, default=1.3)
    ap.add_argument('--decorrelation-m', type=float, default=2.5)
    ap.add_argument('--channel-db', type=float, default=2.0)
    ap.add_argument('--common-db', type=float, default=3.6)
    ap.add_argument('--link-db', type=float, default=4.0)
    ap.add_argument('--n', type=float, default=2.5)
    ap.add_argument('--n-sd', type=float, default=0.5)
    ap.add_argument('--position-sd-m', type=float, default=11.5)
    ap.add_argument('--cluster-radius-m', type=float, default=0.0)
    ap.add_argument('--json', action='store_true')
    return run(ap.parse_args())


def defaults(**overrides):
    """The command line's defaults as a namespace (for tests and other scripts)."""
    return argparse.Namespace(**{**dict(locus=None, config='config/locble.yaml', known_model=False, fading_db=3.5,
                                        shadowing_db=1.3, decorrelation_m=2.5, channel_db=2.0, common_db=3.6,
                                        link_db=4.0, n=2.5, n_sd=0.5, position_sd_m=11.5, cluster_radius_m=0.0,
                                        json=False, scenes=[]), **overrides})


def run_rows(a):
    """One row per tag of every scene in a.scenes (bound, and the final error when a.locus is set)."""
    rows = []
    for scene in a.scenes:
        try:
            y, observer, traj, readings = load_scene(scene)
        except (OSError, KeyError, StopIteration, ValueError, yaml.YAMLError) as e:
            sys.exit(f'locble_bound: {scene}: cannot read the scene and its truth ({type(e).__name__}: {e}); '
                     'expected scene.yaml with truth (clocks, trajectories), the observer\'s ble.csv, truth.csv')
        if observer not in traj:
            sys.exit(f'locble_bound: {scene}: truth has no trajectory for the observer {observer}')
        errors = final_errors(a.locus, a.config, scene) if a.locus else {}
        tags = sorted({r['tag'] for r in readings})
        info = {}
        for tag in tags:
            if tag not in traj:
                sys.exit(f'locble_bound: {scene}: truth has no position for tag {tag}')
            mine = [r for r in readings if r['tag'] == tag]
            info[tag] = position_information(traj[observer], traj[tag][0, 1:3], mine, a) + (len(mine),)
        for tag in tags:
            j, dist, classes, n = info[tag]
            rms = rms_bound(j, a)
            row = {'scene': os.path.basename(os.path.normpath(scene)), 'tag': tag, 'readings': n,
                   'mean_distance_m': dist, 'classes': classes, 'bound_rms_m': rms,
                   'bound_mean_m': 0.886 * rms, 'final_error_m': errors.get(tag)}
            if a.cluster_radius_m > 0:
                members = [o for o in tags if np.hypot(*(traj[o][0, 1:3] - traj[tag][0, 1:3])) <= a.cluster_radius_m]
                row['cluster_size'] = len(members)
                row['fused_bound_rms_m'] = rms_bound(sum(info[o][0] for o in members), a)
            rows.append(row)
    return rows


def run(a):
    rows = run_rows(a)
    if a.json:
        print(json.dumps(rows, indent=1))
        return
    print('scene           tag    readings  distance  classes          bound rms  (mean-equiv.)  final error')
    for r in rows:
        fe = '-' if r['final_error_m'] is None else f"{r['final_error_m']:.2f} m"
        fused = (f"   fused with {r['cluster_size']} tags within {a.cluster_radius_m:g} m: {r['fused_bound_rms_m']:.2f} m rms"
                 if 'cluster_size' in r else '')
        print(f"{r['scene']:15s} {r['tag']:6s} {r['readings']:8d}  {r['mean_distance_m']:6.1f} m  {','.join(r['classes']):15s}"
              f"  {r['bound_rms_m']:7.2f} m  ({r['bound_mean_m']:.2f} m)       {fe}{fused}")
    b = np.array([r['bound_mean_m'] for r in rows])
    near = np.array([r['mean_distance_m'] <= 5.6 for r in rows])
    print(f"{len(rows)} tags: mean of the mean-error equivalents {b.mean():.2f} m"
          + (f" (tags at <= 5.6 m: {b[near].mean():.2f} m, {near.sum()} tags)" if near.any() else ''))
    if a.cluster_radius_m > 0:
        clustered = [r for r in rows if r['cluster_size'] > 1]
        if clustered:
            print(f"tags with a cluster: {len(clustered)}; bound rms alone {np.mean([r['bound_rms_m'] for r in clustered]):.2f} m,"
                  f" fused {np.mean([r['fused_bound_rms_m'] for r in clustered]):.2f} m")
    fe = [r['final_error_m'] for r in rows if r['final_error_m'] is not None]
    if fe:
        print(f"measured: mean final error {np.mean(fe):.2f} m over {len(fe)} tags")


if __name__ == '__main__':
    main()
