#!/usr/bin/env python3
"""How often an ideal receiver could time a SpyLoc LoS beep's first path within one sample, given the
scene's own noise and its early echoes: the bound behind issue 16's "first path within 1 sample for
90 % of LoS beeps".

usage: spyloc_bound.py SCENE_DIR... [--window-ms W] [--pre-ms P] [--noise-ms N] [--image-order K] [--json]
                       [--phase known|free] [--per-beep] [--min-bound F] [--max-bound F]

Why: the multitone beep (tones 18-20.25 kHz, 60 ms, 5 ms raised-cosine fades) is timed to a fraction
of a sample by its carrier phase, but the phase repeats every carrier period (~2.3 samples at 19 kHz):
which period is the first path's is decided by the envelope alone, and the floor and ceiling images
arrive 1-3 ms after the direct path, inside its 5 ms fade-in. A one-period slip is a 2.3-sample error.
This script asks how often a receiver that knows everything except the noise and the echoes could
still choose the right period.

Model, per LoS beep (everything from the scene's truth, nothing from a detector):
  * the samples from --pre-ms before the true first arrival to --window-ms after it (the onset: what
    the beep's later part adds is shared with its own reverberation, which this model does not hold);
  * the direct path: the scene's template s(t - tau0) with a free real amplitude (--phase known, the
    optimistic default: no transducer phase) or a free complex one (--phase free);
  * every image source of the room (shoebox, reflection order <= --image-order, default 2) whose
    delay falls in the window, as a nuisance path: free complex amplitude and free delay (4 columns:
    the template, its quadrature, and their delay derivatives). The image delays come from the truth's
    geometry; their amplitudes are not needed (free);
  * white noise with the in-band power measured in the audio just before the beep (17.5-20.75 kHz,
    --noise-ms before the window), scaled to the full band: the same noise the detector faces.
The direct amplitude a0 is the least-squares fit of that model to the recorded window.
The two competing hypotheses are tau0 +- T, T the template's nearest autocorrelation side peak (one
carrier period). The likelihood-ratio test between tau0 and tau0+T has error probability Q(d/2),
d = a0 * |P_perp (s(tau0) - s(tau0+T))| / sigma, P_perp the projection away from the nuisance columns.
P(slip) = Q(d+/2) + Q(d-/2); the bound's "within 1 sample" is the mean of 1 - P(slip) over LoS beeps.

It is a bound in the optimistic direction: the true arrival and image delays are given, only the
listed images interfere (no late reverberation, no diffraction from partitions), the noise is white.
A detector cannot do better on average than what it prints; whether it can reach it is another matter.

--min-bound / --max-bound: exit status 4 when the pooled bound is outside (tests/foreign, scenario).
Scenes: a foreign scene (truth-extra.yaml with `beeps`) or a `locus simulate spyloc` scene
(truth_emissions.csv, truth_los.csv); the same beep tables as check_spyloc_arrivals.py, which this
script imports. Needs python3-numpy, python3-scipy, python3-yaml.
"""
import argparse
import json
import math
import os
import sys

import numpy as np
from scipy.io import wavfile
from scipy.signal import butter, sosfiltfilt
from scipy.special import erfc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_spyloc_arrivals as arrivals  # noqa: E402  (the beep tables and the truth poses)


def qfunc(x):
    return 0.5 * erfc(x / math.sqrt(2.0))


class Template:
    """A scene's multitone emission (docs/scene-format.md): a·w(t)·Σ sin(2π f_k t), w a raised-cosine
    fade in and out. quad=True gives the quadrature (cos) version, for a free carrier phase."""

    def __init__(self, spec, fs, scale=1.0):
        self.f = np.array(spec['tones_hz'], float)
        self.scale = scale  # received time scale 1 - rdot/c (the walker's Doppler)
        self.dur = float(spec['duration'])
        self.fade = float(spec.get('fade', 0.0) or 0.0)
        self.a = float(spec.get('amplitude', 1.0))
        self.fs = fs

    def window(self, t):
        w = ((t >= 0) & (t <= self.dur)).astype(float)
        if self.fade > 0:
            up = (t >= 0) & (t < self.fade)
            w[up] = 0.5 - 0.5 * np.cos(np.pi * t[up] / self.fade)
            down = (t > self.dur - self.fade) & (t <= self.dur)
            w[down] = 0.5 - 0.5 * np.cos(np.pi * (self.dur - t[down]) / self.fade)
        return w

    def at(self, n, delay, quad=False):
        """Samples n (array) of the template started at fractional sample `delay`."""
        t = (n - delay) / self.fs * self.scale
        ph = 2 * np.pi * np.outer(t, self.f)
        tones = np.cos(ph) if quad else np.sin(ph)
        return self.a * self.window(t) * tones.sum(axis=1)

    def d_delay(self, n, delay, quad=False, h=1e-3):
        return (self.at(n, delay + h, quad) - self.at(n, delay - h, quad)) / (2 * h)

    def side_peak(self):
        """The template's nearest autocorrelation side peak, in samples (one carrier period)."""
        n = np.arange(int(self.dur * self.fs) + 8)
        s0 = self.at(n, 0.0)
        lags = np.arange(0.5, 6.0, 0.005)
        r = np.array([np.dot(s0, self.at(n, lag)) for lag in lags])
        k = int(np.argmax(r))
        return float(lags[k])


def image_delays_m(src, rcv, room, order):
    """Path lengths of the shoebox image sources of `src` (reflection order 1..order) seen at `rcv`."""
    out = []
    rng = range(-order, order + 1)
    for nx in rng:
        for ny in rng:
            for nz in rng:
                for px in (0, 1):
                    for py in (0, 1):
                        for pz in (0, 1):
                            refl = abs(2 * nx - px) + abs(2 * ny - py) + abs(2 * nz - pz)
                            if refl == 0 or refl > order:
                                continue
                            img = np.array([(1 - 2 * px) * src[0] + 2 * nx * room[0],
                                            (1 - 2 * py) * src[1] + 2 * ny * room[1],
                                            (1 - 2 * pz) * src[2] + 2 * nz * room[2]])
                            out.append(float(np.linalg.norm(img - rcv)))
    return sorted(out)


def scene_bound(scene_dir, args):
    scene, fs, c, room = arrivals.read_scene(scene_dir)
    if room is None:
        sys.exit(f'{scene_dir}/scene.yaml: environment.room: expected the room size [x, y, z] (m)')
    if not isinstance(scene.get('truth'), dict) or 'clocks' not in scene['truth']:
        sys.exit(f'{scene_dir}/scene.yaml: truth.clocks: expected the ground truth (the bound needs the true arrivals)')
    dev = scene['devices'][0]
    device = dev['id']
    mic_body = np.array(dev['mics'][0], float)
    ck = scene['truth']['clocks'].get(device, {'offset_s': 0.0, 'skew_ppm': 0.0})
    traj = arrivals.load_trajectories(scene_dir, scene)
    beeps = arrivals.beeps_from_extra(scene_dir) or arrivals.beeps_from_geometry(scene_dir, scene, device)
    emitters = {e['id']: e for e in scene.get('emitters', [])}
    _, raw = wavfile.read(os.path.join(scene_dir, dev['audio']), mmap=True)
    # integer PCM to full scale 1 (scipy gives 24-bit data left-justified in int32); floats as they are
    scale = float(np.iinfo(raw.dtype).max) + 1.0 if np.issubdtype(raw.dtype, np.integer) else 1.0
    audio = np.asarray(raw[:, 0] if raw.ndim > 1 else raw, float)
    sos = butter(4, [17500.0, 20750.0], btype='bandpass', fs=fs, output='sos')
    band_fraction = (20750.0 - 17500.0) / (fs / 2.0)
    side = {}  # per beacon: its template's carrier period (samples)
    rows = []
    pre = int(round(args.pre_ms * 1e-3 * fs))
    win = int(round(args.window_ms * 1e-3 * fs))
    noise_len = int(round(args.noise_ms * 1e-3 * fs))
    for b in beeps:
        if not b['los']:
            continue
        src_id = b['beacon']
        e = emitters.get(src_id)
        if e is None:
            continue
        spec = next((x for x in e['emits'] if x.get('type') == 'multitone'), None)
        if spec is None:
            continue
        if src_id not in side:
            side[src_id] = Template(spec, fs).side_peak()
        T = side[src_id]
        tau0 = b['first']
        n0 = int(math.floor(tau0)) - pre
        n1 = int(math.floor(tau0)) + win
        if n0 - noise_len - 200 < 0 or n1 + 200 > len(audio):
            continue
        # the geometry at the arrival: receiver from the truth (true time from the local clock)
        t_true = (tau0 / fs - float(ck['offset_s'])) / (1.0 + float(ck['skew_ppm']) * 1e-6)
        def mic_at(t):
            p, q = arrivals.pose_at(traj, device, t)
            return p + arrivals.quat_rot(q, mic_body)

        rcv = mic_at(t_true)
        if 'anchor' in e and e['anchor'] and 'position' in e['anchor']:
            src = np.array(e['anchor']['position'], float)
        else:
            src, _ = arrivals.pose_at(traj, src_id, t_true - 0.02)
        d0 = float(np.linalg.norm(rcv - src))
        # the walker's radial speed: the received beep is time-scaled by 1 - rdot/c
        rdot = (np.linalg.norm(mic_at(t_true + 0.02) - src) - np.linalg.norm(mic_at(t_true - 0.02) - src)) / 0.04
        tpl = Template(spec, fs, 1.0 - rdot / c)
        n = np.arange(n0, n1, dtype=float)
        cols = []
        phase_free = args.phase == 'free'
        cols.append(tpl.at(n, tau0))
        if phase_free:
            cols.append(tpl.at(n, tau0, quad=True))
        n_direct = len(cols)
        for L in image_delays_m(src, rcv, room, args.image_order):
            dly = tau0 + (L - d0) / c * fs
            if dly >= n1 - 2:
                continue
            cols += [tpl.at(n, dly), tpl.at(n, dly, True), tpl.d_delay(n, dly), tpl.d_delay(n, dly, True)]
        A = np.array(cols).T
        # drop columns that carry nothing in the window (an image that starts at its very end)
        keep = np.linalg.norm(A, axis=0) > 1e-9
        keep[:n_direct] = True
        A = A[:, keep]
        y = audio[n0:n1] / scale
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        a0 = float(np.hypot(*coef[:2])) if phase_free else abs(float(coef[0]))
        seg = audio[n0 - noise_len - 200:n0] / scale
        nb = sosfiltfilt(sos, seg)[200:]
        sigma_w = math.sqrt(float(np.mean(nb ** 2)) / band_fraction)
        # the nuisance columns: every image, and the direct path's own amplitude (and phase)
        Q, _ = np.linalg.qr(A)
        ds = []
        for sgn in (+1, -1):
            delta = tpl.at(n, tau0) - tpl.at(n, tau0 + sgn * T)
            r = delta - Q @ (Q.T @ delta)
            ds.append(a0 * float(np.linalg.norm(r)) / sigma_w)
        p_slip = min(1.0, qfunc(ds[0] / 2) + qfunc(ds[1] / 2))
        snr_db = 10 * math.log10(max(a0 ** 2 * float(np.sum(tpl.at(n, tau0) ** 2)) / sigma_w ** 2, 1e-12))
        rows.append({'beep': b['index'], 'beacon': src_id, 'distance_m': round(d0, 2), 'images_in_window':
                     int((A.shape[1] - n_direct) // 4), 'onset_snr_db': round(snr_db, 1), 'period_samples': round(T, 3), 'rdot_mps': round(float(rdot), 2),
                     'd_plus': round(ds[0], 2), 'd_minus': round(ds[1], 2), 'p_within1': round(1.0 - p_slip, 4)})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--window-ms', type=float, default=10.0, help='window after the first arrival (default 10 ms)')
    ap.add_argument('--pre-ms', type=float, default=2.0, help='window before it (default 2 ms)')
    ap.add_argument('--noise-ms', type=float, default=30.0, help='noise measured over this before the window')
    ap.add_argument('--image-order', type=int, default=2)
    ap.add_argument('--phase', choices=['known', 'free'], default='known')
    ap.add_argument('--per-beep', action='store_true')
    ap.add_argument('--json', action='store_true')
    ap.add_argument('--min-bound', type=float)
    ap.add_argument('--max-bound', type=float)
    args = ap.parse_args()
    for sd in args.scenes:
        if not os.path.isfile(os.path.join(sd, 'scene.yaml')):
            sys.exit(f'{sd}: not a scene directory (no scene.yaml)')
    pooled = []
    out = {}
    for sd in args.scenes:
        rows = scene_bound(sd, args)
        pooled += rows
        p = [r['p_within1'] for r in rows]
        out[sd] = {'los_beeps': len(rows), 'bound_within1': round(float(np.mean(p)), 4) if p else None}
        if args.per_beep:
            for r in rows:
                print(sd, json.dumps(r))
        if not args.json:
            print(f'{sd}: {len(rows)} LoS beeps, bound within 1 sample {100 * np.mean(p):.1f} %'
                  f' (onset SNR median {np.median([r["onset_snr_db"] for r in rows]):.1f} dB)' if p else f'{sd}: no LoS beep')
    p = [r['p_within1'] for r in pooled]
    out['pooled'] = {'los_beeps': len(pooled), 'bound_within1': round(float(np.mean(p)), 4) if p else None}
    if args.json:
        print(json.dumps(out))
    elif len(args.scenes) > 1 and p:
        print(f'pooled: {len(pooled)} LoS beeps, bound within 1 sample {100 * np.mean(p):.1f} %')
    if not p:
        sys.exit('no LoS beep to bound')
    b = float(np.mean(p))
    if (args.min_bound is not None and b < args.min_bound) or (args.max_bound is not None and b > args.max_bound):
        print(f'bound {b:.3f} outside [{args.min_bound}, {args.max_bound}]', file=sys.stderr)
        sys.exit(4)


if __name__ == '__main__':
    main()
