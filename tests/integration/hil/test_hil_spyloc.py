#!/usr/bin/python3
"""integration.hil.spyloc: `./run hil spyloc` (tools/hil/hil.py spyloc, tools/hil/hil_sync.py, docs/room.md
"SpyLoc") on a fixed simulated seed, shortened: jackd (dummy driver), mosquitto, `locus room` and four
locusd boards (three beacons, each sending its own radio sync over MQTT and beeping sync_delay_s after
its arrival through the `sync_emitter` plugin; the walker ranging with config/spyloc.yaml).

1. pass:      hil.py spyloc --seed SEED --duration DURATION must exit 0 with the walker located, the live
              mean error within TOLERANCE_M of the replay's on the same layout (hil.py replays and scores
              it: `locus replay LAYOUT -c config/spyloc.yaml`, `locus eval --metric spyloc`), every sync a
              beacon sent received by the walker and by that beacon, every sync's beep scheduled (none
              late, none cut), an estimate on the live map;
2. interrupt: Ctrl-C (SIGINT) to hil.py while the nodes run: exit 130;
3. node dies: a beacon's locusd SIGKILLed mid-run: hil.py fails (exit 1) naming it.
After each: no jackd, mosquitto, locus room or locusd of that run is left, nor JACK's shm files.
The figures of the passing run are printed; no timing is asserted.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_hil import check_clean, check_interrupt, check_node_dies, parse_args, pass_run  # noqa: E402

SEED = 1
DURATION_S = 15  # the first 15 s of the walk: 45 beeps, the walker's first fix and a few turns
# Live differs from the replay by the room (its own rendering of the beeps, noise and first-order
# reflections instead of the simulator's recording), the MQTT sync's arrival (measured: the walker's
# arrival within ~1 ms of the beacon's own, < 0.4 m of range) and the room's 34-sample converter delay
# (+0.26 m on every range). Measured on this seed (docs/room.md): live mean error 0.15-0.2 m above the
# replay's; 0.5 m is under the method's p90 and fails a live path that loses or shifts syncs or beeps
# (a sync late by one 256-frame period is 2 m).
TOLERANCE_M = 0.5


def check_pass(r, tries):
    live, rep = r["live"], r["replay"]
    print(f"live {live.get('targets_located')}/{live.get('targets_expected')} located, mean error "
          f"{live.get('mean_error_m')} m; replay {rep.get('mean_error_m')} m")
    if not (live.get("targets_located") == live.get("targets_expected") and live.get("targets_expected", 0) > 0):
        tries.append(f"pass: live located {live.get('targets_located')}/{live.get('targets_expected')}")
    if live.get("mean_error_m") is None or not abs(live["mean_error_m"] - rep["mean_error_m"]) <= TOLERANCE_M:
        tries.append(f"pass: live mean error {live.get('mean_error_m')} m vs the replay's {rep['mean_error_m']:.3f} m "
                     f"(tolerance {TOLERANCE_M} m)")
    beacons = [k for k, v in r["emissions"].items()]
    if len(beacons) < 3:
        tries.append(f"pass: {len(beacons)} beacons emitted (expected 3)")
    walker = [k for k in r["sync"] if k not in beacons]
    for b in beacons:
        sent, e = r["sync"][b]["sent"], r["emissions"][b]
        if sent == 0 or r["sync"][b]["received"] != sent:
            tries.append(f"pass: beacon {b} sent {sent} syncs and received {r['sync'][b]['received']} of them")
        if e["scheduled"] != sent or e["late"] or e["cut"] or e["refused"]:
            tries.append(f"pass: beacon {b}: {sent} syncs, emissions {e}")
    sent_all = sum(r["sync"][b]["sent"] for b in beacons)
    for w in walker:
        if r["sync"][w]["received"] != sent_all:
            tries.append(f"pass: walker {w} received {r['sync'][w]['received']} of {sent_all} syncs")
    if not r["estimate_to_map_ms"]:
        tries.append("pass: no estimate reached the live map")


def main():
    args = parse_args()
    failures = []
    # --calibrate-room-delay: the room's 34-sample converter delay (+0.26 m on every range) told to the
    # walker, as a deployment calibrates its beacons. Uncalibrated, that bias alone made the live error
    # 0.64-1.08 m over four runs against the replay's 0.24 m (the tolerance below then fails at random);
    # calibrated, 0.23 / 0.25 m (2026-11-28).
    run = ("spyloc", "--seed", str(SEED), "--duration", str(DURATION_S), "--calibrate-room-delay")
    # One retry, only when the first attempt failed while the machine, not the live path, was at fault:
    # the room had xruns (a chopped beep), or MQTT handed the syncs to the walker > 2 ms (median) after
    # the beacons (c x that is > 0.7 m of range: a loaded broker, not what this test is about). Said.
    for attempt in (1, 2):
        tries = []
        hil, r = pass_run(args, run, 240, tries)
        if r is not None:
            check_pass(r, tries)
        if not tries or attempt == 2 or r is None:
            break
        import re
        import statistics
        xr = re.search(r"(\d+) xruns", r.get("room") or "")
        lag = r.get("walker_minus_emitter_arrival_ms") or []
        lag_ms = statistics.median(lag) if lag else 0.0
        if not ((xr and int(xr.group(1)) > 0) or lag_ms > 2.0):
            break
        print(f"retry: {tries[0]} while the room had {xr.group(1) if xr else 0} xruns and the walker's syncs "
              f"arrived {lag_ms:.2f} ms (median) after the beacons'; running once more")
        check_clean(hil, "pass (first attempt)", failures)
    failures += tries
    check_clean(hil, "pass", failures)
    check_interrupt(args, run, 90, 3.0, failures)
    check_node_dies(args, run, 90, os.path.join("nodes", "B1.yaml"), lambda cmd: True, "locusd B1 exited", failures, after_s=3.0)
    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
