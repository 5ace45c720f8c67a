#!/usr/bin/env python3
"""AMIL demo report: the listeners' table (true vs estimated direction and distance) and the map (PNG).

Reads only files Locus wrote: the scene (scene.yaml, truth.csv), the estimates (JSON lines from
locusd/locus replay), the scorer's JSON (locus eval --json-output) and the player's track file
(amil `track_csv`). Truth positions come from the scorer (true direction and distance of each
listener in the player's start frame); the true gesture path from truth.csv, mapped into the same
frame (docs/eval.md, `player_start@T`).

usage: amil_report.py SCENE_DIR ESTIMATES.jsonl EVAL.json TRACK.csv OUT.png
"""
import csv
import json
import math
import os
import sys

import yaml


def load_estimates(path):
    out = {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            e = json.loads(line)
            if e.get("type") != "estimate":
                continue
            out[e["target"]] = e  # the last one per listener
    return out


def quat_rot(q, v):
    w, x, y, z = q
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return [sum(r[i][j] * v[j] for j in range(3)) for i in range(3)]


def true_gesture(scene_dir, player, frame):
    """The player's true path from truth.csv in its start frame, or [] when it cannot be placed."""
    if "@" not in frame:
        return []
    t_local = float(frame.split("@", 1)[1])
    with open(os.path.join(scene_dir, "scene.yaml")) as f:
        scene = yaml.safe_load(f)
    truth = scene.get("truth") or {}
    clock = (truth.get("clocks") or {}).get(player, {})
    t0 = (t_local - clock.get("offset_s", 0.0)) / (1.0 + clock.get("skew_ppm", 0.0) * 1e-6)
    rows = []
    with open(os.path.join(scene_dir, truth.get("trajectories", "truth.csv"))) as f:
        for r in csv.DictReader(f):
            if r["id"] == player:
                rows.append([float(r[k]) for k in ("t", "x", "y", "z", "qw", "qx", "qy", "qz")])
    if not rows:
        return []
    ref = min(rows, key=lambda r: abs(r[0] - t0))
    yb = quat_rot(ref[4:8], [0.0, 1.0, 0.0])
    n = math.hypot(yb[0], yb[1])
    if n < 0.2:  # upright phone: the back of the phone (-z)
        yb = [-c for c in quat_rot(ref[4:8], [0.0, 0.0, 1.0])]
        n = math.hypot(yb[0], yb[1])
    ax_y = (yb[0] / n, yb[1] / n)
    ax_x = (ax_y[1], -ax_y[0])  # y x z
    return [((r[1] - ref[1]) * ax_x[0] + (r[2] - ref[2]) * ax_x[1], (r[1] - ref[1]) * ax_y[0] + (r[2] - ref[2]) * ax_y[1])
            for r in rows if t0 - 0.2 <= r[0]]


def main():
    if len(sys.argv) != 6:
        print(__doc__, file=sys.stderr)
        return 2
    scene_dir, est_path, eval_path, track_path, png = sys.argv[1:]
    est = load_estimates(est_path)
    with open(eval_path) as f:
        ev = json.load(f)
    group = next((p for p in ev["plugins"] if p.get("metric") == "amil"), None)
    if group is None:
        print("amil_report.py: no amil plugin group in " + eval_path, file=sys.stderr)
        return 1
    rows = [t for t in group["targets"] if t.get("true_distance_m") is not None]

    print(f"{'listener':>8} {'true dir':>9} {'est dir':>8} {'err':>6} | {'true dist':>9} {'est dist':>8} {'err':>6} | {'conf':>5}")
    print(f"{'':>8} {'(deg)':>9} {'(deg)':>8} {'(deg)':>6} | {'(m)':>9} {'(m)':>8} {'(%)':>6} |")
    for t in rows:
        e = est.get(t["target"])
        td, tdir = t["true_distance_m"], t["true_direction_deg"]
        if e is None:
            print(f"{t['target']:>8} {tdir:9.1f} {'-':>8} {'-':>6} | {td:9.2f} {'-':>8} {'-':>6} | no estimate")
            continue
        edir = e.get("direction_rad")
        edist = e.get("distance_m")
        edir_s = f"{math.degrees(edir):8.1f}" if edir is not None else f"{'-':>8}"
        derr = t.get("direction_error_deg")
        derr_s = f"{derr:6.1f}" if derr is not None else f"{'-':>6}"
        edist_s = f"{edist:8.2f}" if edist is not None else f"{'(dir)':>8}"
        pct = t.get("distance_error_pct")
        pct_s = f"{pct:6.1f}" if pct is not None else f"{'-':>6}"
        print(f"{t['target']:>8} {tdir:9.1f} {edir_s} {derr_s} | {td:9.2f} {edist_s} {pct_s} | {e.get('confidence', 0):5.2f}")
    s = group["summary"]

    def fmtv(v, spec):
        return format(v, spec) if v is not None else "-"
    print(f"located {s.get('targets_located')}/{s.get('targets_expected')}; direction error mean "
          f"{fmtv(s.get('mean_direction_error_deg'), '.2f')} deg (max {fmtv(s.get('max_direction_error_deg'), '.2f')}); "
          f"distance error median {fmtv(s.get('median_distance_error_pct'), '.1f')} %; position error mean "
          f"{fmtv(s.get('mean_error_m'), '.2f')} m")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 8.5))
    cmap = plt.get_cmap("tab20")
    for i, t in enumerate(rows):
        col = cmap(i % 20)
        th = math.radians(t["true_direction_deg"])
        tx, ty = t["true_distance_m"] * math.cos(th), t["true_distance_m"] * math.sin(th)
        ax.plot(tx, ty, "o", color=col, ms=10)
        ax.annotate(t["target"], (tx, ty), textcoords="offset points", xytext=(7, 7), fontsize=9)
        e = est.get(t["target"])
        if e is None:
            continue
        pos = e.get("position_m")
        if pos and pos[0] is not None:
            ax.plot(pos[0], pos[1], "x", color=col, ms=10, mew=2)
            ax.plot([tx, pos[0]], [ty, pos[1]], "-", color=col, lw=1)
        elif e.get("direction_rad") is not None:
            d = e["direction_rad"]
            ax.plot([0, 6 * math.cos(d)], [0, 6 * math.sin(d)], "--", color=col, lw=1)
    # Gesture: tracked (track.csv) and true (truth.csv) in the start frame.
    path, beeps = [], []
    if os.path.exists(track_path):
        with open(track_path) as f:
            for r in csv.DictReader(f):
                (path if r["kind"] == "path" else beeps).append((float(r["x_m"]), float(r["y_m"])))
    frame = next(iter(est.values()))["frame"] if est else ""
    player = next(iter(est.values()))["reference"] if est else ""
    truth_path = true_gesture(scene_dir, player, frame) if player else []
    ax.plot(0, 0, "k^", ms=10, label="player (start)")
    ax.plot([], [], "ko", label="listener: true")
    ax.plot([], [], "kx", mew=2, label="listener: estimated")
    ax.set_xlabel("x (m), player's start frame")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlim(-2.5, 2.5)
    ax.set_ylim(-0.6, 5.6)
    s_line = (f"direction error mean {fmtv(s.get('mean_direction_error_deg'), '.2f')} deg, "
              f"distance error median {fmtv(s.get('median_distance_error_pct'), '.1f')} %")
    ax.set_title(f"AMIL: one gesture locates every listener\n{s_line}", fontsize=11)
    ins = ax.inset_axes([0.03, 0.02, 0.3, 0.22])
    if truth_path:
        ins.plot([p[0] for p in truth_path], [p[1] for p in truth_path], "-", color="0.6", lw=2, label="true")
    if path:
        ins.plot([p[0] for p in path], [p[1] for p in path], "-", color="tab:red", lw=1, label="tracked (IMU)")
    if beeps:
        ins.plot([b[0] for b in beeps], [b[1] for b in beeps], "o", color="tab:blue", ms=4, label="beeps (speaker)")
    ins.set_aspect("equal")
    ins.set_title("gesture (m)", fontsize=8)
    ins.tick_params(labelsize=7)
    ins.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    print("map: " + png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
