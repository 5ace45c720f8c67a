#!/usr/bin/env python3
"""Writes the two-device scene of the replay integration test (stdlib only).

A (1 mic) emits a 40 ms chirp at 0.5, 1.5 and 2.5 s and hears it at once; B (2 mics) stands
DIST_M away and hears it DIST_M / C later. Both clocks start together. B also has imu.csv and
sync.csv; with --bad-imu-line N, row N of B/imu.csv is malformed (column 'az' = 'oops').
"""
import argparse, math, os, random, struct, wave

FS = 44100
C = 343.0
DIST_M = 1.715  # 5 ms
DURATION_S = 3.2
EMIT_S = [0.5, 1.5, 2.5]


def chirp(t):
    d = 0.04
    if t < 0 or t >= d:
        return 0.0
    return 0.5 * math.sin(2 * math.pi * (2000 * t + 0.5 * (6000 / d) * t * t))


def write_wav(path, channels, delays):
    rng = random.Random(len(path))
    n = int(DURATION_S * FS)
    frames = bytearray()
    for k in range(n):
        t = k / FS
        for c in range(channels):
            v = sum(chirp(t - e - delays[c]) for e in EMIT_S) + rng.gauss(0, 1e-3)
            frames += struct.pack('<h', max(-32768, min(32767, int(round(v * 32768)))))
    with wave.open(path, 'wb') as w:
        w.setnchannels(channels)
        w.setsampwidth(2)
        w.setframerate(FS)
        w.writeframes(bytes(frames))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('dir')
    ap.add_argument('--bad-imu-line', type=int, default=0)
    a = ap.parse_args()
    os.makedirs(os.path.join(a.dir, 'A'), exist_ok=True)
    os.makedirs(os.path.join(a.dir, 'B'), exist_ok=True)
    with open(os.path.join(a.dir, 'scene.yaml'), 'w') as f:
        f.write(f"""format: locus-scene/1
name: replay-integration
sample_rate: {FS}
speed_of_sound: {C}
devices:
  - id: A
    mics: [[0.0, 0.0, 0.0]]
    speaker: [0.0, 0.0, 0.0]
    emits: [{{type: lfm, f0: 2000, f1: 8000, duration: 0.04}}]
    audio: A/audio.wav
  - id: B
    mics: [[0.0, -0.07, 0.0], [0.0, 0.07, 0.0]]
    audio: B/audio.wav
    imu: B/imu.csv
    sync: B/sync.csv
  - id: quiet
    mics: [[0, 0, 0]]
""")
    write_wav(os.path.join(a.dir, 'A', 'audio.wav'), 1, [0.0])
    d = DIST_M / C
    write_wav(os.path.join(a.dir, 'B', 'audio.wav'), 2, [d, d])
    with open(os.path.join(a.dir, 'B', 'imu.csv'), 'w') as f:
        f.write('t,ax,ay,az,gx,gy,gz\n')
        for i in range(300):
            line = i + 2
            az = 'oops' if line == a.bad_imu_line else '9.81'
            f.write(f'{i * 0.01:.2f},0,0,{az},0,0,0\n')
    with open(os.path.join(a.dir, 'B', 'sync.csv'), 'w') as f:
        f.write('t,source\n')
        for e in EMIT_S:
            f.write(f'{e - 0.1:.3f},A\n')


if __name__ == '__main__':
    main()
