#!/usr/bin/env python3
"""Independent check of the DSP filters against scipy.signal.

Runs locus_filter_dump and compares: Butterworth SOS designs (frequency response on 512 points against
scipy.signal.butter(..., output='sos', fs=...); section order may differ, the cascade must not),
SosFilter outputs against scipy.signal.sosfilt with scipy's own coefficients, filtfilt against
sosfiltfilt, FIR taps against scipy.signal.firwin and FirFilter against lfilter, Goertzel power
against a direct DFT. Exits non-zero with what differs."""
import subprocess
import sys

import numpy as np
from scipy import signal

out = subprocess.run([sys.argv[1]], check=True, capture_output=True, text=True).stdout.splitlines()
fail = []
x = None
i = 0


def vec(line, tag):
    parts = line.split()
    assert parts[0] == tag, (parts[0], tag)
    n = int(parts[1])
    return np.array([float(v) for v in parts[2:2 + n]])


checked = {"iir": 0, "fir": 0, "goertzel": 0}
while i < len(out):
    p = out[i].split()
    if p[0] == "X":
        x = vec(out[i], "X").astype(np.float32).astype(np.float64)
        i += 1
    elif p[0] == "IIR":
        kind, order, f1, f2, fs = p[1], int(p[2]), float(p[3]), float(p[4]), float(p[5])
        i += 1
        sos = []
        while out[i].startswith("SOS"):
            b0, b1, b2, a1, a2 = map(float, out[i].split()[1:])
            sos.append([b0, b1, b2, 1.0, a1, a2])
            i += 1
        sos = np.array(sos)
        y = vec(out[i], "Y"); i += 1
        ff = vec(out[i], "FF"); i += 1
        wn = f1 if kind in ("lowpass", "highpass") else [f1, f2]
        ref = signal.butter(order, wn, btype=kind, output="sos", fs=fs)
        name = f"butter {kind} N={order} {wn} fs={fs}"
        if sos.shape != ref.shape:
            fail.append(f"{name}: {sos.shape[0]} sections, scipy has {ref.shape[0]}")
            continue
        w = np.linspace(0, fs / 2, 512, endpoint=False)
        _, h = signal.sosfreqz(sos, worN=w, fs=fs)
        _, hr = signal.sosfreqz(ref, worN=w, fs=fs)
        err = np.max(np.abs(h - hr))
        if err > 1e-6 * max(1.0, np.max(np.abs(hr))):
            fail.append(f"{name}: max |H - H_scipy| = {err:.3g}")
        yr = signal.sosfilt(ref, x)
        e = np.max(np.abs(y - yr)) / max(1e-9, np.max(np.abs(yr)))
        if e > 1e-5:
            fail.append(f"{name}: sosfilt relative error {e:.3g}")
        ffr = signal.sosfiltfilt(ref, x)
        e = np.max(np.abs(ff - ffr)) / max(1e-9, np.max(np.abs(ffr)))
        if e > 1e-5:
            fail.append(f"{name}: sosfiltfilt relative error {e:.3g}")
        checked["iir"] += 1
    elif p[0] == "FIR":
        kind, taps, win, beta, f1, f2, fs = p[1], int(p[2]), p[3], float(p[4]), float(p[5]), float(p[6]), float(p[7])
        i += 1
        h = vec(out[i], "H"); i += 1
        y = vec(out[i], "Y"); i += 1
        window = ("kaiser", beta) if win == "kaiser" else win
        cutoff = f1 if kind in ("lowpass", "highpass") else [f1, f2]
        pass_zero = {"lowpass": True, "highpass": False, "bandpass": False, "bandstop": True}[kind]
        hr = signal.firwin(taps, cutoff, window=window, pass_zero=pass_zero, fs=fs)
        name = f"firwin {kind} {taps} {window} {cutoff}"
        e = np.max(np.abs(h - hr))
        if e > 1e-9:
            fail.append(f"{name}: max tap error {e:.3g}")
        yr = signal.lfilter(hr, [1.0], x)
        e = np.max(np.abs(y - yr)) / max(1e-9, np.max(np.abs(yr)))
        if e > 1e-5:
            fail.append(f"{name}: FirFilter relative error {e:.3g}")
        checked["fir"] += 1
    elif p[0] == "G":
        f, pw = float(p[1]), float(p[2])
        n = np.arange(len(x))
        ref = abs(np.sum(x * np.exp(-2j * np.pi * f * n / 44100.0))) ** 2
        if abs(pw - ref) > 1e-6 * max(ref, 1.0):
            fail.append(f"goertzel {f} Hz: {pw} vs DFT {ref}")
        checked["goertzel"] += 1
        i += 1
    else:
        fail.append(f"unknown record {p[0]}")
        i += 1

print("checked:", checked)
if checked["iir"] < 15 or checked["fir"] < 7 or checked["goertzel"] < 5:
    fail.append(f"too few records checked: {checked}")
for f in fail:
    print("FAIL:", f)
sys.exit(1 if fail else 0)
