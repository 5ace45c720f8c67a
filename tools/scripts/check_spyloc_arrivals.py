#!/usr/bin/env python3
"""Scores `multitone` detections of a SpyLoc scene against every emitted beep.

usage: check_spyloc_arrivals.py SCENE_DIR DETECTIONS.jsonl [--json] [--device ID] [--list-bad]
                                [--min-los-found F] [--min-los-within1 F]

Why: SpyLoc ranges from one beep's first-path arrival; a beep opened late, with the wrong beacon's
identity, or timed on an echo (the 4 ms envelope lobes of a 250 Hz tone grid) is a range error of
metres. So every beep is scored: found with the right identity, and its first-path error in samples,
split by the truth's LOS / NLOS label. When the file also holds the localizer's `estimate` events
(one per ranged beep, `t_s` = the beep's first-path time on the device's clock, `los` its verdict),
the verdicts are scored too: each estimate is paired with the beep whose first arrival is nearest
(within --verdict-window-s, default 80 ms: an NLoS beep may be timed on a reflection 40 ms late;
beeps come 0.25 s apart or more) and its `los` compared with the beep's label (`verdicts`).

Truth, per beep: the local sample index (fractional) of the first path at the device's microphone.
  * Scene with truth-extra.yaml holding `beeps` (the independent reference generator): each entry's
    `beacon`, `arrival_first_local_sample`, `arrival_los_local_sample`, `label` (LOS / NLOS). The
    first path of a LOS beep is its direct path: scored against `arrival_los_local_sample`. (On a
    walking receiver that generator's `arrival_first` of LOS beeps differs from `arrival_los` by up to
    ~4 samples: `first_path_len_m` vs `dist_los_m` differ by the walker's motion during the flight,
    ~3 cm; the audio's direct path follows `arrival_los` (spyloc-104: median |err| 0.6 vs 2.3
    samples). Both errors are printed: `err` (the scored one) and `err_first_table`.) A NLOS beep's
    first path is the diffracted one: `arrival_first_local_sample`.
  * Else (a `locus simulate spyloc` scene): truth_emissions.csv (t_true = true start of the beep),
    truth.csv poses, scene.yaml geometry and truth clocks (retarded time iterated as in
    check_tum_arrivals.py); label from truth_los.csv (t_true, beacon, los). The simulator's NLOS
    first path is the attenuated direct path, so first = LOS arrival there.
Identity: a beacon's tones_hz -> bit k for tone 18000 + 250·k Hz (the detector's default tone set;
--base-hz/--spacing-hz for another); a detection's `template` must equal that mask.
Beeps the recording does not hold whole (their first path later than the device's audio length
minus the beep's duration: emitted near the end, they arrive after it or are cut by it) are matched
but not scored; their count is printed (`cut_by_end`).
Matching: every audio_detection of the device is paired with the beep whose first arrival is nearest
(within --window-s, default 30 ms); each beep keeps its nearest detection; others are `false`.
Bars (exit status 4 when missed): --min-los-found (fraction of LOS beeps found with the right
identity), --min-los-within1 (fraction of those within 1 sample of the first path) and
--min-verdicts (fraction of the estimates whose LoS/NLoS verdict is the beep's label; missed when the
file holds no estimate with a verdict).
Needs python3-numpy, python3-yaml and python3-scipy (the audio's length).
"""
import argparse
import csv
import json
import os
import sys

import numpy as np
import yaml


def quat_rot(q, v):
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R @ v


def beeps_from_extra(scene_dir):
    path = os.path.join(scene_dir, 'truth-extra.yaml')
    if not os.path.exists(path):
        return None
    with open(path) as f:
        extra = yaml.load(f, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
    if not isinstance(extra, dict) or 'beeps' not in extra:
        return None
    out = []
    for b in extra['beeps']:
        los = str(b['label']).upper() == 'LOS'
        out.append({'index': int(b['index']), 'beacon': str(b['beacon']),
                    'first': float(b['arrival_los_local_sample'] if los else b['arrival_first_local_sample']),
                    'first_table': float(b['arrival_first_local_sample']),
                    'los_sample': float(b['arrival_los_local_sample']),
                    'los': los})
    return out


def read_scene(scene_dir):
    """scene.yaml as a dict, with its sample rate, speed of sound and room size (None when absent)."""
    with open(os.path.join(scene_dir, 'scene.yaml')) as f:
        scene = yaml.safe_load(f)
    room = (scene.get('environment') or {}).get('room')
    return scene, float(scene['sample_rate']), float(scene.get('speed_of_sound', 343.0)), \
        (np.array(room, float) if room else None)


def load_trajectories(scene_dir, scene):
    """The truth's trajectories: id -> array of rows (t, x, y, z, qw, qx, qy, qz)."""
    traj = {}
    with open(os.path.join(scene_dir, scene['truth'].get('trajectories', 'truth.csv'))) as f:
        for row in csv.DictReader(f):
            traj.setdefault(row['id'], []).append([float(row[k]) for k in 't x y z qw qx qy qz'.split()])
    return {k: np.array(v) for k, v in traj.items()}


def pose_at(traj, i, t):
    """Position and attitude of `i` at true time t (linear, normalised quaternion lerp)."""
    a = traj[i]
    if len(a) == 1:
        return a[0, 1:4], a[0, 4:8]
    j = min(max(int(np.searchsorted(a[:, 0], t)), 1), len(a) - 1)
    u = (t - a[j - 1, 0]) / (a[j, 0] - a[j - 1, 0])
    p = a[j - 1, 1:4] + u * (a[j, 1:4] - a[j - 1, 1:4])
    q = a[j - 1, 4:8] + u * (a[j, 4:8] - a[j - 1, 4:8])
    return p, q / np.linalg.norm(q)


def beeps_from_geometry(scene_dir, scene, device):
    fs = float(scene['sample_rate'])
    c = float(scene.get('speed_of_sound', 343.0))
    ck = scene['truth']['clocks'].get(device, {'offset_s': 0.0, 'skew_ppm': 0.0})
    traj = load_trajectories(scene_dir, scene)

    def pose(i, t):
        return pose_at(traj, i, t)

    dev = next(d for d in scene['devices'] if d['id'] == device)
    mic = np.array(dev['mics'][0], float)
    los = {}
    lpath = os.path.join(scene_dir, 'truth_los.csv')
    if os.path.exists(lpath):
        with open(lpath) as f:
            for r in csv.DictReader(f):
                los[(r['beacon'], round(float(r['t_true']), 4))] = r['los'].strip() == '1'
    out = []
    with open(os.path.join(scene_dir, 'truth_emissions.csv')) as f:
        for n, r in enumerate(csv.DictReader(f)):
            src, te = r['id'], float(r['t_true'])
            ps, _ = pose(src, te)
            t = te
            for _ in range(6):
                pm, qm = pose(device, t)
                t = te + np.linalg.norm(pm + quat_rot(qm, mic) - ps) / c
            local = t * (1.0 + float(ck['skew_ppm']) * 1e-6) + float(ck['offset_s'])
            out.append({'index': n, 'beacon': src, 'first': fs * local, 'first_table': fs * local, 'los_sample': fs * local,
                        'los': los.get((src, round(te, 4)), True)})
    return out


def read_events(path, event_type, device=None):
    """The events of one type (and device, when given) from a JSON-lines file (exits naming the bad line)."""
    out = []
    with open(path) as f:
        for ln, line in enumerate(f, 1):
            line = line.strip()
            if not line:
                continue
            try:
                ev = json.loads(line)
            except json.JSONDecodeError as e:
                sys.exit(f'{path}:{ln}: not JSON ({e})')
            if ev.get('type') == event_type and (device is None or ev.get('device') == device):
                out.append(ev)
    return out


def wav_frames(path):
    """Frames in a WAV file (scipy's reader, memory-mapped: the samples are not read)."""
    from scipy.io import wavfile
    try:
        return wavfile.read(path, mmap=True)[1].shape[0]
    except (OSError, ValueError) as e:
        sys.exit(f'{path}: not a readable WAV file ({e})')


def match_detections(beeps, dets, window):
    """Pairs each detection with the beep whose first arrival is nearest (within `window` samples);
    each beep keeps its nearest detection. Returns ({beep index: detection}, unpaired count)."""
    firsts = np.array([b['first'] for b in beeps])
    best = {}
    false = 0
    for d in dets:
        fr = float(d['frame'])
        j = int(np.argmin(np.abs(firsts - fr)))
        if abs(firsts[j] - fr) > window:
            false += 1
            continue
        if j in best:
            false += 1
            if abs(float(best[j]['frame']) - firsts[j]) <= abs(fr - firsts[j]):
                continue
        best[j] = d
    return best, false


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('detections')
    ap.add_argument('--device', default=None, help='walker device id (default: the first device with audio)')
    ap.add_argument('--base-hz', type=float, default=18000.0)
    ap.add_argument('--spacing-hz', type=float, default=250.0)
    ap.add_argument('--window-s', type=float, default=0.03)
    ap.add_argument('--json', action='store_true')
    ap.add_argument('--list-bad', action='store_true')
    ap.add_argument('--min-los-found', type=float, default=None)
    ap.add_argument('--min-los-within1', type=float, default=None)
    ap.add_argument('--min-verdicts', type=float, default=None)
    ap.add_argument('--verdict-window-s', type=float, default=0.08)
    a = ap.parse_args()

    with open(os.path.join(a.scene, 'scene.yaml')) as f:
        scene = yaml.safe_load(f)
    fs = float(scene['sample_rate'])
    device = a.device or next(d['id'] for d in scene['devices'] if d.get('audio'))
    masks = {}
    for e in (scene.get('emitters') or []) + (scene.get('devices') or []):
        for s in e.get('emits') or []:
            if s.get('type') != 'multitone':
                continue
            m = 0
            for f_hz in s['tones_hz']:
                k = (float(f_hz) - a.base_hz) / a.spacing_hz
                if abs(k - round(k)) > 1e-6 or k < 0:
                    sys.exit(f'{a.scene}/scene.yaml: emitter {e["id"]}: tone {f_hz} Hz is not on the grid '
                             f'{a.base_hz} + {a.spacing_hz}·k Hz')
                m |= 1 << int(round(k))
            masks[e['id']] = m
    beeps = beeps_from_extra(a.scene)
    if beeps is None:
        beeps = beeps_from_geometry(a.scene, scene, device)
    dev = next(d for d in scene['devices'] if d['id'] == device)
    frames = wav_frames(os.path.join(a.scene, dev['audio']))
    durations = {}
    for e in (scene.get('emitters') or []) + (scene.get('devices') or []):
        for s in e.get('emits') or []:
            if s.get('type') == 'multitone':
                durations[e['id']] = float(s.get('duration', 0.0))
    dets = read_events(a.detections, 'audio_detection', device)
    best, false = match_detections(beeps, dets, a.window_s * fs)
    rows = []
    for j, b in enumerate(beeps):
        d = best.get(j)
        r = {'index': b['index'], 'beacon': b['beacon'], 'los': b['los'], 'first': b['first'], 'found': d is not None}
        if d is not None:
            r['template'] = int(d['template'])
            r['identity_ok'] = int(d['template']) == masks.get(b['beacon'], -1)
            r['err'] = float(d['frame']) - b['first']
            r['err_first_table'] = float(d['frame']) - b['first_table']
        r['cut'] = b['first'] + durations.get(b['beacon'], 0.0) * fs > frames
        rows.append(r)
    cut = [r for r in rows if r['cut']]
    rows = [r for r in rows if not r['cut']]

    # The localizer's LoS/NLoS verdict per ranged beep (estimate events of the walker).
    ests = [e for e in read_events(a.detections, 'estimate') if e.get('target') == device and e.get('los') is not None]
    firsts = np.array([b['first'] for b in beeps])
    vrows = []
    for e in ests:
        fr = float(e['t_s']) * fs
        j = int(np.argmin(np.abs(firsts - fr)))
        if abs(firsts[j] - fr) <= a.verdict_window_s * fs:
            vrows.append((beeps[j]['los'], bool(e['los'])))

    def verdicts(sel):
        n = len(sel)
        ok = sum(1 for truth, said in sel if truth == said)
        return {'estimates': n, 'right': ok, 'accuracy': ok / n if n else float('nan')}

    def summary(sel):
        n = len(sel)
        ok = [r for r in sel if r['found'] and r['identity_ok']]
        e = np.array([abs(r['err']) for r in ok]) if ok else np.array([])
        return {'beeps': n, 'found': sum(r['found'] for r in sel), 'identity_ok': len(ok),
                'found_ok_frac': len(ok) / n if n else float('nan'),
                'within1': int((e <= 1).sum()), 'within5': int((e <= 5).sum()), 'within200': int((e <= 200).sum()),
                'within1_frac': float((e <= 1).mean()) if len(e) else float('nan'),
                'within1_first_table': int(sum(abs(r['err_first_table']) <= 1 for r in ok)),
                'median_abs_err': float(np.median(e)) if len(e) else float('nan'),
                'p90_abs_err': float(np.percentile(e, 90)) if len(e) else float('nan')}

    res = {'scene': a.scene, 'device': device, 'detections': len(dets), 'false': false, 'cut_by_end': len(cut),
           'all': summary(rows), 'los': summary([r for r in rows if r['los']]),
           'nlos': summary([r for r in rows if not r['los']]),
           'verdicts': {'all': verdicts(vrows), 'los': verdicts([v for v in vrows if v[0]]),
                        'nlos': verdicts([v for v in vrows if not v[0]]), 'unpaired': len(ests) - len(vrows)}}
    if a.json:
        print(json.dumps(res, indent=1))
    else:
        print(f"{a.scene}: {len(dets)} detections, {false} false"
              f"{f'; {len(cut)} beeps not whole in the recording (not scored)' if cut else ''}")
        for k in ('all', 'los', 'nlos'):
            s = res[k]
            print(f"  {k:4s}: {s['beeps']} beeps, found {s['found']}, right identity {s['identity_ok']} "
                  f"({100 * s['found_ok_frac']:.1f} %); of those within 1 sample {s['within1']} "
                  f"({100 * s['within1_frac']:.1f} %) [vs arrival_first table: {s['within1_first_table']}], within 5 {s['within5']}, within 200 {s['within200']}; "
                  f"|err| median {s['median_abs_err']:.2f} p90 {s['p90_abs_err']:.2f} samples")
        v = res['verdicts']
        if v['all']['estimates']:
            print(f"  verdicts: {v['all']['right']}/{v['all']['estimates']} right ({100 * v['all']['accuracy']:.1f} %): "
                  f"LoS {v['los']['right']}/{v['los']['estimates']}, NLoS {v['nlos']['right']}/{v['nlos']['estimates']}"
                  f"{', ' + str(v['unpaired']) + ' estimates unpaired' if v['unpaired'] else ''}")
    if a.list_bad:
        for r in rows:
            if not r['found'] or not r['identity_ok'] or abs(r['err']) > 1:
                print('  bad:', r)
    bad = False
    if a.min_los_found is not None and not res['los']['found_ok_frac'] >= a.min_los_found:
        print(f"BAR MISSED: LOS found with right identity {res['los']['found_ok_frac']:.3f} < {a.min_los_found}")
        bad = True
    if a.min_los_within1 is not None and not res['los']['within1_frac'] >= a.min_los_within1:
        print(f"BAR MISSED: LOS within 1 sample {res['los']['within1_frac']:.3f} < {a.min_los_within1}")
        bad = True
    if a.min_verdicts is not None and not res['verdicts']['all']['accuracy'] >= a.min_verdicts:
        print(f"BAR MISSED: LoS/NLoS verdicts right {res['verdicts']['all']['accuracy']:.3f} < {a.min_verdicts} "
              f"({res['verdicts']['all']['estimates']} estimates with a verdict)")
        bad = True
    return 4 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
