#!/usr/bin/env python3
"""How loud interferer bursts are where the beeps are, and which LoS beeps a detector loses to them
(issue 16: checking the simulator's babble / music bursts against the foreign scene's).

usage: spyloc_burst_check.py levels WAV...
       spyloc_burst_check.py missed [--detections SUFFIX] SCENE_DIR...

`levels`: per recording (first channel), 10 ms frames; burst frames are those where the 0.2-4 kHz
power, averaged over 0.3 s, is 6 dB over its median (babble and music carry most of their energy
there). Prints, relative to the quiet frames' median, the p50 / p90 / p99 of three bands inside and
outside the bursts: 0.2-4 kHz, 16-17.8 kHz (next to the tones: what a burst puts near them, free of
beeps) and 17.8-20.5 kHz (the tone band: beeps included).

`missed`: per LoS beep of each scene (truth as tools/scripts/check_spyloc_arrivals.py reads it;
detections from SCENE_DIR + SUFFIX, default `.jsonl`, as spyloc_campaign.py --keep leaves them), the
beep's level in its own tones (median of 10 ms frames over its first 50 ms) over the local
background (30th percentile of the 200 ms before it) and the burst level near it (16-17.8 kHz
median over +-0.1 s, over the recording's median). Prints the found rate (right identity) by both,
and lists the missed beeps. Needs python3-numpy, python3-scipy and python3-yaml.
"""
import argparse
import os
import sys

import numpy as np
import scipy.io.wavfile as wavfile
import scipy.signal as sps
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_spyloc_arrivals as arrivals  # noqa: E402

HOP_S = 0.01


def read_mono(path):
    fs, x = wavfile.read(path)
    x = x.astype(np.float64)
    if x.ndim > 1:
        x = x[:, 0]
    return fs, x


def frames(x, fs):
    hop = int(round(HOP_S * fs))
    f, _, s = sps.stft(x, fs, nperseg=hop, noverlap=0, boundary=None, padded=False)
    return f, np.abs(s) ** 2, hop


def band_db(f, p, lo, hi):
    return 10 * np.log10(p[(f >= lo) & (f < hi)].sum(0) + 1e-30)


def levels(paths):
    for path in paths:
        fs, x = read_mono(path)
        f, p, _ = frames(x, fs)
        low = band_db(f, p, 200, 4000)
        k = int(round(0.3 / HOP_S))
        smooth = 10 * np.log10(np.convolve(10 ** (low / 10), np.ones(k) / k, 'same'))
        burst = smooth > np.median(smooth) + 6
        print(f'{path}: burst frames {100 * burst.mean():.1f} %')
        for name, lo, hi in (('0.2-4 kHz', 200, 4000), ('16-17.8 kHz', 16000, 17800), ('17.8-20.5 kHz', 17800, 20500)):
            v = band_db(f, p, lo, hi)
            m = np.median(v[~burst])
            q = lambda sel, pc: np.percentile(v[sel], pc) - m if sel.any() else float('nan')  # noqa: E731
            print(f'  {name:13s} over the quiet median: quiet p90 {q(~burst, 90):5.1f} p99 {q(~burst, 99):5.1f} | '
                  f'bursts p50 {q(burst, 50):5.1f} p90 {q(burst, 90):5.1f} p99 {q(burst, 99):5.1f} dB')


def missed(scenes, suffix):
    rows = []
    for sd in scenes:
        with open(os.path.join(sd, 'scene.yaml')) as fh:
            scene = yaml.safe_load(fh)
        dev = next(d for d in scene['devices'] if d.get('audio'))
        fs, x = read_mono(os.path.join(sd, dev['audio']))
        f, p, hop = frames(x, fs)
        masks, tones = {}, {}
        for e in scene.get('emitters') or []:
            for s in e.get('emits') or []:
                if s.get('type') == 'multitone':
                    tones[e['id']] = [float(t) for t in s['tones_hz']]
                    masks[e['id']] = sum(1 << int(round((t - 18000.0) / 250.0)) for t in tones[e['id']])
        adj = band_db(f, p, 16000, 17800)
        quiet = np.median(adj)
        beeps = arrivals.beeps_from_extra(sd) or arrivals.beeps_from_geometry(sd, scene, dev['id'])
        dets = arrivals.read_events(sd + suffix, 'audio_detection', dev['id'])
        best, _ = arrivals.match_detections(beeps, dets, 0.05 * fs)
        for j, b in enumerate(beeps):
            fr = b['first'] / hop
            if not b['los'] or b['beacon'] not in tones or fr < 21 or fr + 6 > p.shape[1]:
                continue
            idx = [int(np.argmin(np.abs(f - t))) for t in tones[b['beacon']]]
            tp = 10 * np.log10(p[idx].sum(0) + 1e-30)
            level = np.median(tp[int(fr + 0.5):int(fr + 5.5)])
            background = np.percentile(tp[int(fr - 20):int(fr - 1)], 30)
            burst = np.median(adj[max(0, int(fr - 10)):int(fr + 10)]) - quiet
            d = best.get(j)
            ok = d is not None and int(d['template']) == masks[b['beacon']]
            rows.append((os.path.basename(sd.rstrip('/')), b['index'], ok, level - background, burst))
    if not rows:
        sys.exit('no LoS beeps')
    r = np.array([(x[2], x[3], x[4]) for x in rows], float)
    print(f'LoS beeps {len(r)}, found with the right identity {100 * r[:, 0].mean():.2f} %')
    for lo, hi in ((-99, 10), (10, 15), (15, 99)):
        m = (r[:, 1] >= lo) & (r[:, 1] < hi)
        if m.any():
            print(f'  beep over the background in its tones {lo:>4}..{hi:<3} dB: {m.sum():5d} beeps, found {100 * r[m, 0].mean():5.1f} %')
    for lo, hi in ((-99, 2), (2, 6), (6, 12), (12, 99)):
        m = (r[:, 2] >= lo) & (r[:, 2] < hi)
        if m.any():
            print(f'  burst next to the tones {lo:>4}..{hi:<3} dB: {m.sum():5d} beeps, found {100 * r[m, 0].mean():5.1f} %, '
                  f'beep over background median {np.median(r[m, 1]):.1f} dB')
    print('missed (scene #beep: beep over background, burst dB):')
    for x in rows:
        if not x[2]:
            print(f'  {x[0]} #{x[1]}: {x[3]:6.1f} {x[4]:6.1f}')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    sub = ap.add_subparsers(dest='cmd', required=True)
    lv = sub.add_parser('levels')
    lv.add_argument('wav', nargs='+')
    ms = sub.add_parser('missed')
    ms.add_argument('--detections', default='.jsonl', help='suffix of each scene directory holding its detections')
    ms.add_argument('scene', nargs='+')
    a = ap.parse_args()
    if a.cmd == 'levels':
        levels(a.wav)
    else:
        missed(a.scene, a.detections)


if __name__ == '__main__':
    main()
