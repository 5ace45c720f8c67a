#!/usr/bin/python3
"""integration.hil.locble: `./run hil locble` (tools/hil/hil.py locble, docs/room.md "LocBLE") on a fixed
simulated seed: a private dbus-daemon, dbusmock's bluez5 as bluetoothd, mosquitto, `locus feed` (the
scene's IMU into a fake IIO device, its advertisements through BlueZ) and one locusd board.

1. pass:      hil.py locble --seed SEED must exit 0 with every tag estimated, the live mean final error
              within TOLERANCE_M of the replay's on the same scene (replayed here: `locus replay LAYOUT
              -c config/locble.yaml`, scored by `locus eval --metric locble`), every advertisement of
              ble.csv fed through BlueZ and out of the node as a ble_advertisement event (none lost,
              none added), every IMU scan written, an estimate on the live map;
2. interrupt: Ctrl-C (SIGINT) to hil.py while the node runs: exit 130;
3. node dies: the locusd SIGKILLed mid-run: hil.py fails (exit 1) naming it.
After each: no dbus-daemon, dbusmock, mosquitto, locus feed or locusd of that run is left (their command
lines name the run's directory). The figures of the passing run are printed; no timing is asserted.
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_hil import check_clean, check_interrupt, check_node_dies, parse_args, pass_run  # noqa: E402

SEED = 1
# Live and replay run the same detectors and localizer on the same samples; what differs live is each
# advertisement's time (its read time on the node, ~0.7 ms after the scene's, more when the machine
# delays the feed) and the IMU's 16-bit quantisation. Measured: seeds 1-3 and locble-105 within 6 mm
# per tag when the feed is on time (docs/room.md); 0.5 m is well under the method's error (4-9 m): a
# live path that loses, adds or shifts data fails it.
TOLERANCE_M = 0.5
LATE_MS = 10.0  # the feed's lateness above which a missed tolerance is re-run once (below)


def check_pass(args, hil, r, tries):
    """The passing run's checks (appended to tries); True when the live error missed the tolerance."""
    tolerance_missed = False
    layout = os.path.join(hil.out, "layout")
    locus = os.path.join(args.bin, "locus")
    replay = os.path.join(args.out, "replay.jsonl")
    rp = subprocess.run([locus, "replay", layout, "-c", os.path.join(args.source, "config", "locble.yaml"),
                         "--speed", "max", "-o", replay], capture_output=True, text=True)
    ev = subprocess.run([locus, "eval", layout, replay, "--metric", "locble", "--json", "--json-output",
                         os.path.join(args.out, "replay_eval.json")], capture_output=True, text=True)
    if rp.returncode != 0 or ev.returncode not in (0, 4):
        tries.append(f"pass: the replay of {layout} failed: {rp.stderr} {ev.stderr}")
    else:
        with open(os.path.join(args.out, "replay_eval.json")) as f:
            rep = next(p for p in json.load(f)["plugins"] if p.get("metric") == "locble")["summary"]
        live = r["live"]
        print(f"replay here: {rep['targets_located']}/{rep['targets_expected']} tags, mean final error "
              f"{rep['mean_error_m']:.3f} m; live: {live['located']}/{live['expected']}, {live['mean_error_m']:.3f} m")
        if not (live["located"] == live["expected"] == r["tags"] and r["tags"] > 0):
            tries.append(f"pass: live located {live['located']}/{live['expected']} of {r['tags']} tags")
        if live["mean_error_m"] is None or not abs(live["mean_error_m"] - rep["mean_error_m"]) <= TOLERANCE_M:
            tolerance_missed = True
            tries.append(f"pass: live mean final error {live['mean_error_m']} m vs the replay's "
                         f"{rep['mean_error_m']:.3f} m (tolerance {TOLERANCE_M} m)")
    if not (r["adverts_fed"] == r["adverts_in_scene"] == r["ble_advertisement_events"] and r["adverts_failed"] == 0):
        tries.append(f"pass: advertisements: {r['adverts_in_scene']} in ble.csv, {r['adverts_fed']} fed "
                     f"({r['adverts_failed']} failed), {r['ble_advertisement_events']} out of the node")
    if not r["scanner"] or r["scanner"]["dropped"] != 0 or r["scanner"]["adverts"] != r["adverts_fed"]:
        tries.append(f"pass: the node's bluez source counted {r['scanner']} (expected {r['adverts_fed']}, 0 dropped)")
    if r["imu_scans_written"] != r["imu_rows"]:
        tries.append(f"pass: {r['imu_scans_written']} of {r['imu_rows']} IMU scans written")
    if not r["estimates_on_map"]:
        tries.append("pass: no estimate reached the live map")
    if not any("mean_error_m" in line for line in hil.lines):
        tries.append("pass: no locus eval table printed")
    return tolerance_missed


def main():
    args = parse_args()
    failures = []
    run = ("locble", "--seed", str(SEED))

    # 1. a passing run, and the same scene replayed here; once more (and said so) only when the live
    # error missed the tolerance while the machine delayed the feed by more than LATE_MS: LocBLE's
    # EnvAware windows start at a reading's time, so an advertisement late by tens of ms can move a
    # window boundary and a tag's environment change (measured: locble-105's T1 2.60 -> 3.21 m in 1 of
    # 6 runs, 3 advertisements 30-52 ms late; docs/room.md). Every other check fails at once.
    for attempt in (1, 2):
        tries, late, tolerance_missed = [], 0.0, False
        hil, r = pass_run(args, run, 180, tries)
        if r is not None:
            late = max(r["feed_lateness_ms"]["ble_max"], r["feed_lateness_ms"]["imu_max"])
            tolerance_missed = check_pass(args, hil, r, tries)
        if attempt == 1 and tolerance_missed and len(tries) == 1 and late > LATE_MS:
            print(f"retry: {tries[0]} while the feed was up to {late:.0f} ms late; running once more")
            check_clean(hil, "pass (first attempt)", failures)
            continue
        failures += tries
        break
    check_clean(hil, "pass", failures)

    # 2. Ctrl-C while the node runs; 3. the node dies mid-run
    check_interrupt(args, run, 60, 2.0, failures)
    check_node_dies(args, run, 60, "node.yaml", lambda cmd: True, "locusd exited", failures, after_s=2.0)

    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
