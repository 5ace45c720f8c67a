#!/usr/bin/env python3
"""How far above the noise the first path of each SpyLoc beep is, per class (LoS / NLoS).

usage: spyloc_first_path_snr.py SCENE_DIR [--template-ms 4 ...]

Why (issue 16, brief step 3): on NLoS beeps the detector times a reflection because the diffracted
first path is under its onset threshold. Before lowering thresholds, this measures whether that path
can be found at all: the onset statistic c(τ) = |<y, o(·−τ)>|² (y the walker's audio band-passed to
17.8-20.5 kHz, o the beacon's tones over the first template-ms: the multitone detector's onset
template) at the true first-path lag (max over ±2 samples), in dB over the median of c over the
20 ms before it, against the largest c over that noise-only stretch.
Truth: truth-extra.yaml `beeps` (the foreign generator: arrival_first_local_sample, label); scenes of
`locus simulate` have no such table. Needs numpy, scipy and yaml.
"""
import argparse
import os
import sys

import numpy as np
import yaml
from scipy.io import wavfile
from scipy.signal import butter, sosfiltfilt


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('--template-ms', type=float, action='append', default=None)
    a = ap.parse_args()
    extra = os.path.join(a.scene, 'truth-extra.yaml')
    if not os.path.exists(extra):
        sys.exit(f'{extra}: not found (needs the foreign generator\'s beeps table)')
    with open(extra) as f:
        d = yaml.load(f, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
    if not isinstance(d, dict) or 'beeps' not in d:
        sys.exit(f'{extra}: no `beeps` list')
    with open(os.path.join(a.scene, 'scene.yaml')) as f:
        sc = yaml.safe_load(f)
    tones = {e['id']: e['emits'][0]['tones_hz'] for e in sc.get('emitters') or [] if e.get('emits')}
    dev = next(x for x in sc['devices'] if x.get('audio'))
    fs, x = wavfile.read(os.path.join(a.scene, dev['audio']))
    x = x.astype(float)
    if x.ndim > 1:
        x = x[:, 0]
    y = sosfiltfilt(butter(6, [17800, 20500], btype='band', fs=fs, output='sos'), x)
    pre = int(0.02 * fs)
    for ms in a.template_ms or [4.0]:
        n = int(round(ms * 1e-3 * fs))
        t = np.arange(n) / fs
        for lab in ('LOS', 'NLOS'):
            at, floor_max = [], []
            for b in d['beeps']:
                if str(b['label']).upper() != lab or b['beacon'] not in tones:
                    continue
                k0 = int(np.floor(float(b['arrival_first_local_sample'])))
                if k0 - pre - n < 0 or k0 + n + 3 > len(y):
                    continue
                o = sum(np.exp(2j * np.pi * f * t) for f in tones[b['beacon']])
                c = np.abs(np.correlate(y[k0 - pre - n:k0 + n + 3], o, 'valid')) ** 2  # c[i]: lag k0 - pre - n + i
                noise = c[:pre - n]                 # templates wholly before the first path
                ref = np.median(noise)
                i0 = pre + n
                at.append(10 * np.log10(c[i0 - 2:i0 + 3].max() / ref))
                floor_max.append(10 * np.log10(noise.max() / ref))
            at, floor_max = np.array(at), np.array(floor_max)
            if not len(at):
                continue
            print(f'template {ms:g} ms, {lab}: {len(at)} beeps; first path over the noise median: median {np.median(at):.1f} dB '
                  f'(q25 {np.percentile(at, 25):.1f}); noise-only maximum: median {np.median(floor_max):.1f} dB; '
                  f'first path above its noise-only maximum: {int((at > floor_max).sum())} of {len(at)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
