#!/usr/bin/env python3
"""Times scipy.signal.correlate on the same 9 s of audio as locus_bench_chirp, in the same run.

Usage: /usr/bin/python3 tests/bench/chirp_vs_scipy.py build/bin/locus_bench_chirp [--repeats N]

Runs the benchmark (JSON output) with LOCUS_BENCH_CHIRP_DUMP so that it writes its signal and
template as raw float32, then times scipy.signal.correlate(x, h, mode="valid") with method="fft"
(scipy's choice for these sizes) and method="direct". All times are CPU seconds of one thread
(time.thread_time / Google Benchmark's CPU time), so a loaded machine does not skew the ratios.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy import signal

FS = 44100.0


def cpu_time(fn, repeats):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    bench = sys.argv[1]
    repeats = int(sys.argv[sys.argv.index("--repeats") + 1]) if "--repeats" in sys.argv else 5
    with tempfile.TemporaryDirectory() as tmp:
        dump = os.path.join(tmp, "audio.f32")
        env = dict(os.environ, LOCUS_BENCH_CHIRP_DUMP=dump)
        out = subprocess.run([bench, "--benchmark_format=json", "--benchmark_min_time=1"],
                             env=env, check=True, capture_output=True, text=True).stdout
        x = np.fromfile(dump, dtype=np.float32)
        h = np.fromfile(dump + ".template", dtype=np.float32)
    audio_s = len(x) / FS
    results = {b["name"]: b for b in json.loads(out)["benchmarks"]}

    def locus_s(name):  # CPU seconds for one pass over the 9 s
        b = results[name]
        scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
        return b["cpu_time"] * scale

    # Check that scipy computes the same correlation as the direct Locus reference would.
    ref = signal.correlate(x[:20000].astype(np.float64), h.astype(np.float64), mode="valid")
    got = signal.correlate(x[:20000], h, mode="valid", method="fft")
    assert np.max(np.abs(ref - got)) < 1e-3 * np.max(np.abs(ref)), "scipy fft correlation mismatch"

    t_fft = cpu_time(lambda: signal.correlate(x, h, mode="valid", method="fft"), repeats)
    t_direct = cpu_time(lambda: signal.correlate(x, h, mode="valid", method="direct"), max(1, repeats // 5))

    rows = [
        ("locus chirp detector, prescreen off", locus_s("BM_ChirpDetector/prescreen:0")),
        ("locus chirp detector, prescreen on", locus_s("BM_ChirpDetector/prescreen:1")),
        ("locus correlator only (real output)", locus_s("BM_CorrelatorOnly")),
        ("locus direct time-domain correlation", locus_s("BM_DirectCorrelation")),
        ("scipy.signal.correlate method=fft", t_fft),
        ("scipy.signal.correlate method=direct", t_direct),
    ]
    det = rows[0][1]
    print(f"signal: {audio_s:.1f} s at 44.1 kHz, template {len(h)} samples (lfm 2-8 kHz, 40 ms); CPU seconds per pass")
    print(f"{'':40s} {'time (ms)':>10s} {'x_realtime':>11s} {'detector (prescreen off) faster by':>36s}")
    for name, t in rows:
        print(f"{name:40s} {t * 1e3:10.2f} {audio_s / t:11.0f} {t / det:35.1f}x")


if __name__ == "__main__":
    main()
