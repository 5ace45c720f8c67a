#!/usr/bin/env python3
"""Writes the signal the record integration test plays into JACK: a mono float32 WAV at 44100 Hz with
LFM chirps 2->8 kHz, 40 ms, 5 ms raised-cosine fades, amplitude 0.5 (the `chirp` detector's default
template; formula of docs/scene-format.md "Signals"), starting at the frames listed in STARTS, over
white Gaussian noise at -60 dBFS (fixed seed): a microphone never delivers digital silence, and every
frame of the file is non-zero, so its first frame marks where it lands in a recording.
Usage: make_chirps.py OUT.wav  (prints the start frames, one per line)"""
import sys

import numpy as np
from scipy.io import wavfile

FS = 44100
STARTS = [4410, 26460, 48510]
LENGTH = 66150
F0, F1, D, FADE, AMP = 2000.0, 8000.0, 0.040, 0.005, 0.5
NOISE_RMS = 10 ** (-60 / 20)


def chirp():
    n = int(round(D * FS))
    t = np.arange(n) / FS
    w = np.ones(n)
    nf = FADE * FS
    k = np.arange(n)
    rise = k < nf
    w[rise] = 0.5 - 0.5 * np.cos(np.pi * k[rise] / nf)
    fall = k >= n - nf
    w[fall] = 0.5 - 0.5 * np.cos(np.pi * (n - k[fall]) / nf)
    return AMP * w * np.sin(2 * np.pi * (F0 * t + (F1 - F0) * t * t / (2 * D)))


def main():
    x = np.random.default_rng(20261122).normal(0.0, NOISE_RMS, LENGTH)
    c = chirp()
    for s in STARTS:
        x[s:s + len(c)] += c
    wavfile.write(sys.argv[1], FS, x.astype(np.float32))
    for s in STARTS:
        print(s)


if __name__ == "__main__":
    main()
