#!/usr/bin/python3
"""Independent reference for the simulator (registered as ctest sim_scipy_reference).

Runs the reference-scene writer (argv[1]) into argv[2], then, from scratch with numpy/scipy and the
scene files only (scene.yaml, truth.csv, truth_emissions.csv, RX/audio.wav):
  * computes each chirp's direct-path arrival at every RX microphone from the true geometry
    (quaternion rotation of the body-frame mic/speaker offsets, r/c) and RX's clock
    (local = true*(1+skew*1e-6) + offset) as a fractional frame;
  * rebuilds the received waveform with scipy.signal.chirp evaluated at those fractional times
    (its own raised-cosine fade), and checks it against the WAV sample by sample (least-squares gain);
  * fits the arrival in the WAV by cross-correlation (scipy.signal.correlate) refined to sub-sample
    precision (scipy.optimize.minimize_scalar over the continuous-time template), and requires
    |fit - geometry| < 0.05 samples.
Exit status 0 on success, 1 on a mismatch (with the numbers printed).
"""
import csv
import os
import subprocess
import sys

import numpy as np
import yaml
from scipy import optimize, signal
from scipy.io import wavfile


def quat_rotate(q, v):
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R @ np.asarray(v, dtype=float)


def fade(t, dur, fade_s):
    w = np.ones_like(t)
    w[(t < 0) | (t >= dur)] = 0.0
    a = (t >= 0) & (t < fade_s)
    w[a] = 0.5 * (1 - np.cos(np.pi * t[a] / fade_s))
    b = (t < dur) & (dur - t < fade_s)
    w[b] = 0.5 * (1 - np.cos(np.pi * (dur - t[b]) / fade_s))
    return w


def template(t, sig):
    """The emitted lfm at times t after its start (scipy's chirp; phi=-90 turns cos into sin)."""
    x = signal.chirp(t, f0=sig["f0"], t1=sig["duration"], f1=sig["f1"], method="linear", phi=-90)
    return sig.get("amplitude", 1.0) * fade(t, sig["duration"], sig.get("fade", 0.0)) * x


def main():
    writer, out = sys.argv[1], sys.argv[2]
    subprocess.run([writer, out], check=True)
    with open(os.path.join(out, "scene.yaml")) as f:
        sc = yaml.safe_load(f)
    fs = float(sc["sample_rate"])
    c = float(sc["speed_of_sound"])
    dev = {d["id"]: d for d in sc["devices"]}
    clocks = sc["truth"]["clocks"]
    poses = {}
    with open(os.path.join(out, sc["truth"]["trajectories"])) as f:
        for row in csv.DictReader(f):
            poses.setdefault(row["id"], (np.array([float(row[k]) for k in "xyz"]),
                                         [float(row[k]) for k in ("qw", "qx", "qy", "qz")]))
    emissions = []
    with open(os.path.join(out, "truth_emissions.csv")) as f:
        for row in csv.DictReader(f):
            emissions.append((float(row["t_true"]), row["id"], int(row["signal_index"])))

    rate, audio = wavfile.read(os.path.join(out, dev["RX"]["audio"]))
    assert rate == fs and audio.dtype == np.float32, (rate, audio.dtype)
    clk = clocks["RX"]
    skew, offset = 1.0 + clk["skew_ppm"] * 1e-6, clk["offset_s"]
    failures = 0
    for te0, src, idx in emissions:
        sig = dev[src]["emits"][idx]
        src_rate = 1.0 + clocks[src]["skew_ppm"] * 1e-6 if src in clocks else 1.0
        p_src, q_src = poses[src]
        spk = p_src + quat_rotate(q_src, dev[src]["speaker"])
        p_rx, q_rx = poses["RX"]
        for ch, mic_body in enumerate(dev["RX"]["mics"]):
            mic = p_rx + quat_rotate(q_rx, mic_body)
            r = np.linalg.norm(mic - spk)
            expected = ((te0 + r / c) * skew + offset) * fs  # fractional local frame of the arrival
            k0 = int(np.floor(expected)) - 50
            n = int(sig["duration"] * fs) + 100
            k = np.arange(k0, k0 + n)
            x = audio[k0:k0 + n, ch].astype(float)
            # waveform: scipy chirp at the exact (fractional) emission times of every sample
            t_emit = (k / fs - offset) / skew - r / c - te0
            ref = template(t_emit * src_rate, sig)  # the source's DAC runs on its own clock
            gain = float(ref @ x / (ref @ ref))
            resid = np.max(np.abs(x - gain * ref)) / np.max(np.abs(x))
            # arrival: integer cross-correlation peak, then continuous sub-sample refinement
            tmpl = template(np.arange(int(sig["duration"] * fs) + 1) / fs, sig)
            xc = signal.correlate(x, tmpl, mode="valid")
            coarse = k0 + int(np.argmax(xc))

            def neg_score(tau):
                s = template((k - tau) / (fs * skew) * src_rate, sig)  # RX's grid and TX's DAC clock
                return -(s @ x) / np.sqrt(s @ s)

            res = optimize.minimize_scalar(neg_score, bounds=(coarse - 1.5, coarse + 1.5), method="bounded",
                                           options={"xatol": 1e-5})
            err = res.x - expected
            ok = abs(err) < 0.05 and resid < 1e-4 and abs(gain * r - 0.1) < 1e-3
            print(f"emission t={te0:.6f} ch{ch}: r={r:.4f} m expected frame {expected:.4f} fitted {res.x:.4f} "
                  f"err {err:+.4f} samples, waveform residual {resid:.2e}, gain*r {gain * r:.5f} "
                  f"{'ok' if ok else 'MISMATCH'}")
            failures += 0 if ok else 1
    if len(emissions) != 2:
        print("expected 2 emissions, got", len(emissions))
        failures += 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
