#!/usr/bin/python3
"""Measured statistics of an AMIL-like scene, to compare `locus simulate amil` with a foreign scene
(../shared/scenes/amil-101) on the items that make AMIL hard (docs/simulator.md, "Calibration").

Everything is measured from the written files the same way for both scenes (scene.yaml, the player's
imu.csv and audio.wav, the listeners' audio.wav, truth.csv and the truth clocks); no generator-specific
truth file is needed. The player is the device with an IMU and a speaker; listeners are the other
devices with audio.

  IMU     rate; row-stamp jitter (std of the residual of a straight-line fit of t against the row
          index); quantisation step per sensor (smallest difference between distinct values);
          white-noise density at rest (Welch PSD of rest stretches, mean over the upper third of the
          band, one-sided, sigma_sample = density * sqrt(rate)); bias at rest (mean reading minus the
          gravity projection of the true attitude, accel; mean reading, gyro); bias change between the
          first and the last rest stretch (random walk evidence).
  motion  strokes = where the truth speed (smoothed over 50 ms) exceeds 1 cm/s; pauses between
          strokes; per stroke: yaw change, largest yaw excursion, largest lateral deviation from the
          chord (mm).
  audio   listeners: 18-22 kHz noise PSD (dBFS/Hz; median and 95th percentile of 46 ms frames),
          broadband noise RMS (dBFS, median frame), beep in-band peak scaled to 1 m (dBFS) and the
          in-band SNR of a unit-distance beep; player: self-recording peak (dBFS) and clipped samples,
          and the speaker x mic tilt over the chirp (dB from 18.75 to 21.25 kHz, from the envelope of
          the self-recorded beep whose instantaneous frequency is known).

usage: scene_stats.py SCENE [SCENE...] [--json OUT]   (prints one markdown column per scene)
Needs numpy, scipy, pyyaml (Debian: python3-numpy python3-scipy python3-yaml).
"""
import argparse, csv, json, math, sys

import numpy as np
import yaml
from scipy.io import wavfile
from scipy.signal import butter, sosfiltfilt, welch, hilbert

from campaign_common import quat_matrix


def load_truth(scene):
    tr = {}
    for r in csv.DictReader(open(f"{scene}/truth.csv")):
        tr.setdefault(r['id'], []).append([float(r[k]) for k in 't x y z qw qx qy qz'.split()])
    return {k: np.array(v) for k, v in tr.items()}


def quat_R(q):
    return np.array(quat_matrix(q))


def yaw_of(q):
    w, x, y, z = q.T
    return np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def read_wav(path):
    fs, x = wavfile.read(path)
    if x.dtype == np.int16:
        x = x.astype(float) / 32768.0
    elif x.dtype == np.int32:
        x = x.astype(float) / 2147483648.0
    else:
        x = x.astype(float)
    if x.ndim > 1:
        x = x[:, 0]
    return fs, x


def strokes_of(T):
    t, p = T[:, 0], T[:, 1:4]
    dt = np.median(np.diff(t))
    v = np.r_[0.0, np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)]
    n = max(1, int(round(0.05 / dt)))
    vs = np.convolve(v, np.ones(n) / n, mode='same')
    mov = vs > 0.01
    edges = np.flatnonzero(np.diff(mov.astype(int)))
    if mov[0]:
        edges = edges[1:]
    if len(edges) % 2:
        edges = edges[:-1]
    return [(t[a + 1], t[b + 1]) for a, b in edges.reshape(-1, 2)], vs


def stats(scene):
    S = yaml.safe_load(open(f"{scene}/scene.yaml"))
    clocks = S['truth']['clocks']
    tr = load_truth(scene)
    devs = S['devices']
    player = next(d for d in devs if d.get('imu') and d.get('speaker') is not None)
    listeners = [d for d in devs if d is not player and d.get('audio')]
    pid = player['id']
    out = {'scene': scene}
    g = 9.80665
    try:
        X = yaml.safe_load(open(f"{scene}/truth-extra.yaml"))
        g = float(X.get('gravity', g))
    except OSError:
        pass

    # ---------------------------------------------------------------- motion (truth)
    T = tr[pid]
    strokes, vs = strokes_of(T)
    t = T[:, 0]
    yaw = yaw_of(T[:, 4:8])
    pauses = [strokes[k + 1][0] - strokes[k][1] for k in range(len(strokes) - 1)]
    yaw_change, yaw_exc, lat = [], [], []
    for a, b in strokes:
        i = (t >= a) & (t <= b)
        Y = np.degrees(yaw[i])
        yaw_change.append(abs(Y[-1] - Y[0]))
        yaw_exc.append(np.abs(Y - Y[0]).max())
        P = T[i, 1:3]
        c = P[-1] - P[0]
        L = np.linalg.norm(c)
        nrm = np.array([-c[1], c[0]]) / L
        lat.append(np.abs((P - P[0]) @ nrm).max() * 1e3)
    rest = ~np.isin(np.arange(len(t)), [])  # placeholder, refined below
    out['motion'] = {'strokes': len(strokes), 'stroke_s': [b - a for a, b in strokes], 'pauses_s': pauses,
                     'yaw_change_deg': yaw_change, 'yaw_excursion_deg': yaw_exc, 'lateral_dev_mm': lat}

    # ---------------------------------------------------------------- IMU
    ck = clocks[pid]
    skew, off = float(ck.get('skew_ppm', 0.0)), float(ck.get('offset_s', 0.0))
    imu = np.loadtxt(f"{scene}/{player['imu']}", delimiter=',', skiprows=1)
    ts = imu[:, 0]
    k = np.arange(len(ts))
    fit = np.polyfit(k, ts, 1)
    rate = 1.0 / fit[0]
    res = ts - np.polyval(fit, k)
    steps = []
    for c in range(1, 7):
        u = np.unique(imu[:, c])
        steps.append(float(np.diff(u).min()) if len(u) > 1 else float('nan'))
    # rest stretches: truth speed < 1 cm/s for >= 0.6 s, trimmed by 0.1 s, mapped to local time
    t_true_imu = (ts - off) / (1.0 + skew * 1e-6)
    still = np.interp(t_true_imu, t, vs) < 0.01
    stretches, start = [], None
    for i, s in enumerate(np.r_[still, False]):
        if s and start is None:
            start = i
        if not s and start is not None:
            if (i - start) / rate >= 0.6:
                m = int(0.1 * rate)
                stretches.append((start + m, i - m))
            start = None
    noise_a, noise_g, means_a, means_g, lens = [], [], [], [], []
    for a, b in stretches:
        seg = imu[a:b, 1:7]
        nper = min(256, len(seg))
        f, P = welch(seg, fs=rate, nperseg=nper, axis=0, detrend='linear')
        band = f >= rate / 3.0
        dens = np.sqrt(P[band].mean(axis=0) / 2.0)
        noise_a.append(dens[:3])
        noise_g.append(dens[3:])
        # gravity projection of the true attitude at the middle of the stretch
        tm = t_true_imu[(a + b) // 2]
        j = np.searchsorted(t, tm).clip(0, len(t) - 1)
        R = quat_R(T[j, 4:8])
        exp_a = R.T @ np.array([0.0, 0.0, g])
        means_a.append(seg[:, :3].mean(axis=0) - exp_a)
        means_g.append(seg[:, 3:].mean(axis=0))
        lens.append(b - a)
    w = np.array(lens, float)
    na = np.average(np.array(noise_a), axis=0, weights=w)
    ng = np.average(np.array(noise_g), axis=0, weights=w)
    ba, bg = np.array(means_a), np.array(means_g)
    out['imu'] = {
        'rate_hz': rate, 'stamp_jitter_ms': res.std() * 1e3, 'stamp_resid_lag1_corr': float(np.corrcoef(res[:-1], res[1:])[0, 1]),
        'accel_step': steps[:3], 'gyro_step': steps[3:],
        'rest_s': float(w.sum() / rate), 'rest_stretches': len(stretches),
        'accel_noise_density': na.tolist(), 'gyro_noise_density': ng.tolist(),
        'accel_bias_rest': np.average(ba, axis=0, weights=w).tolist(),
        'gyro_bias_rest': np.average(bg, axis=0, weights=w).tolist(),
        'accel_bias_change_first_last': (ba[-1] - ba[0]).tolist() if len(ba) > 1 else None,
        'gyro_bias_change_first_last': (bg[-1] - bg[0]).tolist() if len(bg) > 1 else None,
        'first_last_rest_gap_s': float((stretches[-1][0] - stretches[0][0]) / rate) if len(stretches) > 1 else None,
    }

    # ---------------------------------------------------------------- audio
    band_sos = None
    L = []
    for d in listeners:
        fs, x = read_wav(f"{scene}/{d['audio']}")
        if band_sos is None:
            band_sos = butter(6, [18000, min(22000, 0.49 * fs)], btype='bandpass', fs=fs, output='sos')
        nf = 2048
        frames = len(x) // nf
        X = x[:frames * nf].reshape(frames, nf) * np.hanning(nf)
        F = np.fft.rfftfreq(nf, 1 / fs)
        Pf = np.abs(np.fft.rfft(X, axis=1)) ** 2 / (fs * (np.hanning(nf) ** 2).sum()) * 2.0  # one-sided PSD
        inb = (F >= 18000) & (F < 22000)
        band_psd = Pf[:, inb].mean(axis=1)
        bb = x[:frames * nf].reshape(frames, nf).std(axis=1)
        y = sosfiltfilt(band_sos, x)
        env = np.abs(hilbert(y))
        # the five (or more) loudest beeps, >= 0.4 s apart
        peaks, e = [], env.copy()
        gap = int(0.4 * fs)
        for _ in range(5):
            i = int(np.argmax(e))
            peaks.append(env[i])
            e[max(0, i - gap):i + gap] = 0.0
        Td = tr[d['id']]
        dist = np.linalg.norm(Td[0, 1:3] - T[0, 1:3])
        noise_rms_inband = math.sqrt(np.median(band_psd) * 4000.0)
        L.append({'id': d['id'], 'dist_m': float(dist),
                  'inband_psd_med_dbfs_hz': 10 * math.log10(np.median(band_psd)),
                  'inband_psd_p95_dbfs_hz': 10 * math.log10(np.percentile(band_psd, 95)),
                  'broadband_rms_med_dbfs': 20 * math.log10(np.median(bb)),
                  'beep_peak_at_1m_dbfs': 20 * math.log10(np.median(peaks) * dist),
                  'snr_inband_at_1m_db': 20 * math.log10(np.median(peaks) * dist / noise_rms_inband)})
    out['listeners'] = L
    fs, xp = read_wav(f"{scene}/{player['audio']}")
    # self-recorded chirp tilt: matched filter against the emitted LFM, envelope at known frequencies
    spec = player['emits'][0]
    f0, f1, dur = float(spec['f0']), float(spec['f1']), float(spec['duration'])
    n = int(round(dur * fs))
    tt = np.arange(n) / fs
    ref = np.sin(2 * np.pi * (f0 * tt + 0.5 * (f1 - f0) / dur * tt * tt))
    yp = sosfiltfilt(band_sos, xp)
    corr = np.abs(np.correlate(yp, ref, mode='valid'))
    starts, c2 = [], corr.copy()
    for _ in range(5):
        i = int(np.argmax(c2))
        starts.append(i)
        c2[max(0, i - int(0.4 * fs)):i + int(0.4 * fs)] = 0.0
    tilts = []
    for s in starts:
        e = np.abs(hilbert(yp[max(0, s - 500):s + n + 500]))
        base = s - max(0, s - 500)
        def at(f):
            j = base + int((f - f0) / (f1 - f0) * n)
            return 20 * math.log10(e[j - 40:j + 40].mean())
        tilts.append(at(f0 + 0.1875 * (f1 - f0)) - at(f0 + 0.8125 * (f1 - f0)))
    out['player_audio'] = {'self_peak_dbfs': 20 * math.log10(np.abs(xp).max()),
                           'clipped_samples': int((np.abs(xp) >= 32767 / 32768).sum()),
                           'self_tilt_db': float(np.median(tilts))}
    return out


def fmt_list(v, f="{:.2f}"):
    return ", ".join(f.format(x) for x in v)


def table(results):
    rows = []
    def row(name, fn):
        rows.append("| " + name + " | " + " | ".join(fn(r) for r in results) + " |")
    rows.append("| measured | " + " | ".join(r['scene'].rstrip('/').split('/')[-1] for r in results) + " |")
    rows.append("|---|" + "---|" * len(results))
    row("IMU rate (Hz)", lambda r: f"{r['imu']['rate_hz']:.1f}")
    row("row-stamp jitter (ms, std)", lambda r: f"{r['imu']['stamp_jitter_ms']:.3f}")
    row("quantisation step accel (m/s²)", lambda r: f"{np.nanmedian(r['imu']['accel_step']):.5f}")
    row("quantisation step gyro (rad/s)", lambda r: f"{np.nanmedian(r['imu']['gyro_step']):.6f}")
    row("accel noise density at rest x,y,z (m/s²/√Hz)", lambda r: fmt_list([x * 1e3 for x in r['imu']['accel_noise_density']], "{:.2f}") + " e-3")
    row("gyro noise density at rest x,y,z (rad/s/√Hz)", lambda r: fmt_list([x * 1e4 for x in r['imu']['gyro_noise_density']], "{:.2f}") + " e-4")
    row("accel bias at rest x,y,z (m/s²)", lambda r: fmt_list(r['imu']['accel_bias_rest'], "{:+.3f}"))
    row("gyro bias at rest x,y,z (rad/s)", lambda r: fmt_list(r['imu']['gyro_bias_rest'], "{:+.4f}"))
    row("accel bias change first→last rest (m/s²)", lambda r: fmt_list(r['imu']['accel_bias_change_first_last'] or [], "{:+.4f}") + f" over {r['imu']['first_last_rest_gap_s'] or 0:.1f} s")
    row("pauses between strokes (s)", lambda r: fmt_list(r['motion']['pauses_s']))
    row("stroke durations (s)", lambda r: fmt_list(r['motion']['stroke_s']))
    row("yaw change per stroke (°)", lambda r: fmt_list(r['motion']['yaw_change_deg']))
    row("largest yaw excursion per stroke (°)", lambda r: fmt_list(r['motion']['yaw_excursion_deg']))
    row("largest lateral deviation from the chord (mm)", lambda r: fmt_list(r['motion']['lateral_dev_mm'], "{:.1f}"))
    med = lambda r, k: float(np.median([l[k] for l in r['listeners']]))
    row("listener 18-22 kHz noise PSD, median frame (dBFS/Hz, median listener)", lambda r: f"{med(r, 'inband_psd_med_dbfs_hz'):.1f}")
    row("listener 18-22 kHz noise PSD, 95th pct frame (dBFS/Hz)", lambda r: f"{med(r, 'inband_psd_p95_dbfs_hz'):.1f}")
    row("listener broadband noise RMS (dBFS)", lambda r: f"{med(r, 'broadband_rms_med_dbfs'):.1f}")
    row("beep 18-22 kHz peak scaled to 1 m (dBFS)", lambda r: f"{med(r, 'beep_peak_at_1m_dbfs'):.1f}")
    row("in-band SNR of a beep at 1 m (dB)", lambda r: f"{med(r, 'snr_inband_at_1m_db'):.1f}")
    row("self-recording peak (dBFS) / clipped samples", lambda r: f"{r['player_audio']['self_peak_dbfs']:.1f} / {r['player_audio']['clipped_samples']}")
    row("self-recorded chirp tilt 18.75→21.25 kHz (dB)", lambda r: f"{r['player_audio']['self_tilt_db']:.1f}")
    return "\n".join(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--json')
    a = ap.parse_args()
    res = [stats(s) for s in a.scenes]
    print(table(res))
    if a.json:
        json.dump(res, open(a.json, 'w'), indent=1, default=float)


if __name__ == '__main__':
    main()
