#!/usr/bin/env python3
"""Scores audio detections of a TUM-like scene (chirp exchanges) against every true arrival.

usage: check_tum_arrivals.py SCENE_DIR DETECTIONS.jsonl [--json] [--min-within1 F] [--max-off5 N]
                             [--max-missed N] [--max-false N] [--list-bad]

Why: TUM needs both arrivals of every exchange on every microphone (the device's own chirp and the
other working device's, overlapping under loose sync), so a detector is scored arrival by arrival,
not by its mean error.

Truth, per (emission, device, mic): the local sample index (fractional) at which the direct path of
the emission's signal starts in that device's recording.
  * A scene with truth-extra.yaml holding `arrivals` (the independent reference generator): its
    table `arrivals.rows` = [emission, device, mic, t_true, local_sample, dist_m], emitters from
    `emissions` [{id, emitter, ...}].
  * Else (a `locus simulate` scene): truth_emissions.csv (t_true = true start of the sound),
    truth.csv poses, scene.yaml geometry and truth clocks; the retarded time t - te = |mic(t) -
    speaker(te)| / c is iterated (as tools/scripts/check_arrivals.py does, per microphone).
Detections: `audio_detection` JSON lines (`locus replay SCENE --config X --events audio_detection -o
F`). A detection's `template` is mapped to a signal of the scene: the detector's templates are the
distinct lfm signals of the scene in scene.yaml order (the chirp detector's `from_scene: true`); a
signal emitted by several sources matches any of them.

Matching: per (device, channel, emitter), every detection is paired with the nearest arrival of that
emitter (within half a signal length); each arrival keeps its nearest detection. Classes per
arrival: within 1 sample / 1-5 samples / more than 5 samples off / missed; detections paired to no
arrival (or a second one paired to an arrival that already has a nearer one) are false. Arrivals are
grouped as `own` (the device hears itself), `cross` (a device that emits hears another emitter: the
overlapped case) and `monitor` (a device that does not emit).
Exit status: 0, or 4 when a --min/--max bar is missed. Needs python3-numpy and python3-yaml.
"""
import argparse
import csv
import json
import os
import sys

import numpy as np
import yaml


def signal_key(sig):
    return (sig.get('type'), float(sig.get('f0', 0)), float(sig.get('f1', 0)), float(sig.get('duration', 0)),
            float(sig.get('fade', 0)))


def load_scene(scene_dir):
    with open(os.path.join(scene_dir, 'scene.yaml')) as f:
        return yaml.safe_load(f)


def templates_of(scene):
    """The chirp detector's from_scene templates: distinct lfm signals, scene order -> (key, [sources])."""
    out = []
    for group in ('devices', 'emitters'):
        for d in scene.get(group) or []:
            for sig in d.get('emits') or []:
                if sig.get('type') != 'lfm':
                    continue
                k = signal_key(sig)
                for t in out:
                    if t[0] == k:
                        t[1].append(d['id'])
                        t[2].append(float(sig['duration']))
                        break
                else:
                    out.append([k, [d['id']], [float(sig['duration'])]])
    return out


def arrivals_from_extra(scene_dir):
    path = os.path.join(scene_dir, 'truth-extra.yaml')
    if not os.path.exists(path):
        return None
    with open(path) as f:
        extra = yaml.load(f, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
    if not isinstance(extra, dict) or 'arrivals' not in extra or 'emissions' not in extra:
        return None
    emitter = {int(e['id']): e['emitter'] for e in extra['emissions']}
    cols = extra['arrivals']['columns']
    ie, idev, imic, isamp, it, idist = (cols.index(k) for k in ('emission', 'device', 'mic', 'local_sample', 't_true',
                                                                 'dist_m'))
    c = float(load_scene(scene_dir).get('speed_of_sound', 343.0))
    # (emission, emitter, device, mic, local sample, true arrival time, true emission time)
    return [(int(r[ie]), emitter[int(r[ie])], str(r[idev]), int(r[imic]), float(r[isamp]), float(r[it]),
             float(r[it]) - float(r[idist]) / c) for r in extra['arrivals']['rows']]


def quat_rot(q, v):
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R @ v


def truth_poses(scene_dir, scene):
    """pose(id, t) -> (position, quaternion wxyz) from the scene's truth trajectories (linear in between)."""
    traj = {}
    with open(os.path.join(scene_dir, scene['truth'].get('trajectories', 'truth.csv'))) as f:
        for row in csv.DictReader(f):
            traj.setdefault(row['id'], []).append([float(row[k]) for k in 't x y z qw qx qy qz'.split()])
    traj = {k: np.array(v) for k, v in traj.items()}

    def pose(i, t):
        a = traj[i]
        if len(a) == 1:
            return a[0, 1:4], a[0, 4:8]
        j = int(np.searchsorted(a[:, 0], t))
        j = min(max(j, 1), len(a) - 1)
        u = (t - a[j - 1, 0]) / (a[j, 0] - a[j - 1, 0])
        p = a[j - 1, 1:4] + u * (a[j, 1:4] - a[j - 1, 1:4])
        q = a[j - 1, 4:8] + u * (a[j, 4:8] - a[j - 1, 4:8])
        return p, q / np.linalg.norm(q)
    return pose


def doppler_instant_s(sig):
    """Timing instant of a phase-timed detector (dsp::doppler_timing_instant_s, written again here):
    sum u f(u) w(u)^2 / sum f(u) w(u)^2 over the signal, w the raised-cosine fade."""
    dur, fade = float(sig['duration']), float(sig.get('fade', 0.0))
    u = (np.arange(4096) + 0.5) * dur / 4096
    w = np.ones_like(u)
    if fade > 0:
        edge = np.minimum(u, dur - u)
        w = np.where(edge < fade, 0.5 - 0.5 * np.cos(np.pi * edge / fade), 1.0)
    f = float(sig['f0']) + (float(sig['f1']) - float(sig['f0'])) * u / dur
    return float(np.sum(u * f * w * w) / np.sum(f * w * w))


def coupling_samples(scene, pose, src, te, dev, mic, t):
    """The range-Doppler coupling of one arrival (samples): (rdot / c) * the emitted signal's timing
    instant * fs, rdot from the truth poses of the speaker at te and the mic at t."""
    fs = float(scene['sample_rate'])
    c = float(scene.get('speed_of_sound', 343.0))
    geo = {d['id']: d for d in scene.get('devices') or []}
    sig = next((e for e in geo[src].get('emits') or [] if e.get('type') == 'lfm'), None) if src in geo else None
    if sig is None:
        return 0.0
    spk = np.array(geo[src].get('speaker', [0, 0, 0]), float)
    micb = np.array(geo[dev]['mics'][mic], float)

    def dist(ts, tm):
        ps, qs = pose(src, ts)
        pm, qm = pose(dev, tm)
        return np.linalg.norm(pm + quat_rot(qm, micb) - ps - quat_rot(qs, spk))
    h = 0.01
    rdot = (dist(te + h, t + h) - dist(te - h, t - h)) / (2 * h)
    return rdot / c * doppler_instant_s(sig) * fs


def arrivals_from_geometry(scene_dir, scene):
    """Every (emission, emitter, device, mic, local sample, true arrival time, true emission time)."""
    fs = float(scene['sample_rate'])
    c = float(scene.get('speed_of_sound', 343.0))
    clocks = scene['truth']['clocks']
    pose = truth_poses(scene_dir, scene)

    speakers = {}
    for d in scene.get('devices') or []:
        if 'speaker' in d:
            speakers[d['id']] = np.array(d['speaker'], float)
    for e in scene.get('emitters') or []:
        speakers[e['id']] = np.zeros(3)
    emissions = []
    with open(os.path.join(scene_dir, 'truth_emissions.csv')) as f:
        for n, r in enumerate(csv.DictReader(f)):
            emissions.append((n, r['id'], float(r['t_true'])))
    out = []
    for n, src, te in emissions:
        p, q = pose(src, te)
        ps = p + quat_rot(q, speakers[src])
        for d in scene.get('devices') or []:
            if not d.get('audio'):
                continue
            ck = clocks[d['id']]
            for m, mic in enumerate(d.get('mics') or []):
                mic = np.array(mic, float)
                t = te
                for _ in range(6):
                    pm, qm = pose(d['id'], t)
                    t = te + np.linalg.norm(pm + quat_rot(qm, mic) - ps) / c
                local = t * (1.0 + float(ck['skew_ppm']) * 1e-6) + float(ck['offset_s'])
                out.append((n, src, d['id'], m, fs * local, t, te))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('detections')
    ap.add_argument('--json', action='store_true', help='print the summary as one JSON object')
    ap.add_argument('--min-within1', type=float, help='fail (exit 4) below this fraction of arrivals within 1 sample')
    ap.add_argument('--max-off5', type=int, help='fail when more arrivals are > 5 samples off')
    ap.add_argument('--max-missed', type=int, help='fail when more arrivals are missed')
    ap.add_argument('--max-false', type=int, help='fail when there are more false detections')
    ap.add_argument('--remove-median-bias', action='store_true',
                    help='subtract the scene-wide median error of the paired detections before classifying (for '
                         'geometry-derived truth: a simulator\'s speaker and mic responses delay every arrival by '
                         'their group delay, which the geometry does not hold; the bias is printed)')
    ap.add_argument('--doppler', action='store_true',
                    help='take the range-Doppler coupling of a moving device out of each detection before classifying: '
                         '(rdot / c) * the chirp\'s timing instant, rdot from the truth poses (what TUM\'s window solve '
                         'corrects with its own estimate; docs/tum.md "Motion within an exchange")')
    ap.add_argument('--list-bad', action='store_true', help='list every arrival not within 1 sample, and false detections')
    a = ap.parse_args()

    scene = load_scene(a.scene)
    fs = float(scene['sample_rate'])
    tmpl = templates_of(scene)
    arrivals = arrivals_from_extra(a.scene)
    source = 'truth-extra.yaml'
    if arrivals is None:
        arrivals = arrivals_from_geometry(a.scene, scene)
        source = 'geometry (truth_emissions.csv, truth.csv)'
    emitters = {src for t in tmpl for src in t[1]}
    duration = {src: dur for t in tmpl for src, dur in zip(t[1], t[2])}

    dets = []
    with open(a.detections) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            e = json.loads(line)
            if e.get('type', 'audio_detection') != 'audio_detection':
                continue
            dets.append(e)

    # arrivals per (device, channel, emitter), sorted by sample
    table = {}
    pose = truth_poses(a.scene, scene) if a.doppler else None
    couplings = []
    for em, src, dev, mic, samp, t_true, te in arrivals:
        # the sample where a phase-timed detector puts the arrival (coupling included with --doppler)
        k = coupling_samples(scene, pose, src, te, dev, mic, t_true) if a.doppler and src != dev else 0.0
        couplings.append(abs(k))
        table.setdefault((dev, mic, src), []).append([samp + k, em, None, None])  # sample, emission, det err, det idx
    for v in table.values():
        v.sort()
    false = []
    for di, d in enumerate(dets):
        t = int(d.get('template', 0))
        if t >= len(tmpl):
            false.append((di, d, 'template index beyond the scene signals'))
            continue
        best = None
        for src in tmpl[t][1]:
            rows = table.get((d['device'], int(d['channel']), src), [])
            for row in rows:
                err = float(d['frame']) - row[0]
                if best is None or abs(err) < abs(best[0]):
                    best = (err, row, src)
        if best is None or abs(best[0]) > 0.5 * duration[best[2]] * fs:
            false.append((di, d, 'no arrival of that signal within half a signal length'))
            continue
        err, row, _ = best
        if row[2] is not None:
            if abs(err) < abs(row[2]):
                false.append((row[3], dets[row[3]], 'second detection of one arrival'))
                row[2], row[3] = err, di
            else:
                false.append((di, d, 'second detection of one arrival'))
        else:
            row[2], row[3] = err, di

    bias = 0.0
    if a.remove_median_bias:
        paired = [row[2] for rows in table.values() for row in rows if row[2] is not None]
        bias = float(np.median(paired)) if paired else 0.0
        for rows in table.values():
            for row in rows:
                if row[2] is not None:
                    row[2] -= bias
    working = emitters

    def group(dev, src):
        if dev == src:
            return 'own'
        return 'cross' if dev in working else 'monitor'

    classes = ('within1', 'off1to5', 'off5', 'missed')
    summary = {g: dict.fromkeys(classes + ('arrivals',), 0) for g in ('own', 'cross', 'monitor', 'all')}
    bad = []
    errs = []
    for (dev, mic, src), rows in sorted(table.items()):
        for samp, em, err, di in rows:
            g = group(dev, src)
            if err is None:
                k = 'missed'
            elif abs(err) <= 1.0:
                k = 'within1'
            elif abs(err) <= 5.0:
                k = 'off1to5'
            else:
                k = 'off5'
            if err is not None:
                errs.append(err)
            for gg in (g, 'all'):
                summary[gg][k] += 1
                summary[gg]['arrivals'] += 1
            if k != 'within1':
                bad.append((em, src, dev, mic, samp, k, err))
    n_all = summary['all']['arrivals']
    e = np.array(errs) if errs else np.zeros(1)
    within = [x for x in errs if abs(x) <= 1.0] or [0.0]
    res = {
        'scene': a.scene, 'truth': source, 'bias_removed_samples': bias, 'detections': len(dets), 'false': len(false),
        'groups': summary,
        'within1_fraction': summary['all']['within1'] / n_all if n_all else 0.0,
        'rms_within1_samples': float(np.sqrt(np.mean(np.square(within)))),
        'max_abs_error_samples': float(np.max(np.abs(e))),
    }
    # Per path (device, mic, emitter): the part of the error that repeats at every exchange (the mean
    # of the path's errors within 1 sample, about the scene-wide median) and the part that does not
    # (the scatter about that mean). A still geometry repeats its reflections: only the second part
    # averages out over exchanges (tools/scripts/tum_bound.py, --bias-std-samples).
    within_all = [x for rows in table.values() for _s, _e, x, _d in rows if x is not None and abs(x) <= 1.0]
    centre = float(np.median(within_all)) if within_all else 0.0
    means, scatter = [], []
    for rows in table.values():
        xs = np.array([x for _s, _e, x, _d in rows if x is not None and abs(x) <= 1.0])
        if len(xs) >= 3:
            means.append(xs.mean() - centre)
            scatter.extend(xs - xs.mean())
    res['path_bias_rms_samples'] = float(np.sqrt(np.mean(np.square(means)))) if means else 0.0
    res['path_scatter_std_samples'] = float(np.std(scatter)) if scatter else 0.0
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{a.scene}: {n_all} arrivals ({source}), {len(dets)} detections, {len(false)} false")
        if a.remove_median_bias:
            print(f"scene-wide median error removed: {bias:+.3f} samples")
        if a.doppler:
            print(f"range-Doppler coupling taken out of each arrival: largest {max(couplings):.2f} samples, "
                  f"{sum(1 for k in couplings if k > 0.5)} arrivals above 0.5")
        print(f"{'group':8s} {'arrivals':>8s} {'<=1':>7s} {'1-5':>5s} {'>5':>5s} {'missed':>7s}  within 1 sample")
        for g in ('own', 'cross', 'monitor', 'all'):
            s = summary[g]
            if s['arrivals'] == 0:
                continue
            print(f"{g:8s} {s['arrivals']:8d} {s['within1']:7d} {s['off1to5']:5d} {s['off5']:5d} {s['missed']:7d}  "
                  f"{100.0 * s['within1'] / s['arrivals']:.2f} %")
        print(f"rms error of the arrivals within 1 sample: {res['rms_within1_samples']:.3f} samples; "
              f"largest error of a paired detection: {res['max_abs_error_samples']:.1f} samples")
        print(f"per path (device, mic, emitter): bias rms {res['path_bias_rms_samples']:.3f} samples (repeats every "
              f"exchange), scatter {res['path_scatter_std_samples']:.3f} samples (does not)")
    if a.list_bad:
        for em, src, dev, mic, samp, k, err in bad:
            es = 'none' if err is None else f'{err:+.2f}'
            print(f"  emission {em} ({src}) at {dev} mic {mic}, sample {samp:.2f}: {k}, error {es}")
        for di, d, why in false:
            print(f"  false: {d['device']} ch {d['channel']} template {d.get('template')} frame {d['frame']:.2f}: {why}")
    failed = []
    if a.min_within1 is not None and res['within1_fraction'] < a.min_within1:
        failed.append(f"within-1-sample fraction {res['within1_fraction']:.4f} < {a.min_within1}")
    if a.max_off5 is not None and summary['all']['off5'] > a.max_off5:
        failed.append(f"{summary['all']['off5']} arrivals > 5 samples off (max {a.max_off5})")
    if a.max_missed is not None and summary['all']['missed'] > a.max_missed:
        failed.append(f"{summary['all']['missed']} arrivals missed (max {a.max_missed})")
    if a.max_false is not None and len(false) > a.max_false:
        failed.append(f"{len(false)} false detections (max {a.max_false})")
    for f in failed:
        print('FAIL: ' + f, file=sys.stderr)
    return 4 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
