#!/usr/bin/python3
"""integration.hil.montage: `./run hil montage` (tools/hil/hil.py montage, tools/hil/hil_sync.py, docs/room.md
"Montage") on simulated seed 1: jackd (dummy driver), mosquitto, `locus room` and four locusd walker boards;
the first sends the start signal over MQTT once, every walker plays its Gold code every round after its
arrival (`sync_emitter`) and ranges with config/montage.yaml.

1. pass:      hil.py montage --seed SEED must exit 0 with: the start signal received by every walker; every
              walker's rounds all scheduled (none late, cut or refused) and every emission heard by the room
              (walkers x rounds onsets); at least MIN_DETECTED of the (emission, other walker) pairs detected
              within 3 samples of the room's direct arrival (the live acoustic and sync path); at least
              MIN_LOCATED walker located and an estimate on the live map. The live and replay trace errors
              are printed, NOT checked: live, 2-4 of 4 walkers are located at 3-7 m against the replay's
              2.4 m on this seed (the room's IMU has no magnetometer, so the walkers' headings share no
              reference, and fewer far pairs are detected; docs/room.md "Montage"). The issue's bar (every
              device located, the live error near the replay's) is not met for Montage, and this test
              says so rather than check a tolerance wide enough to hide it;
2. interrupt: Ctrl-C (SIGINT) to hil.py while the nodes run: exit 130;
3. node dies: a walker's locusd SIGKILLed mid-run: hil.py fails (exit 1) naming it.
After each: no jackd, mosquitto, locus room or locusd of that run is left, nor JACK's shm files.
The figures of the passing run are printed; no timing is asserted.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_hil import check_clean, check_interrupt, check_node_dies, parse_args, pass_run  # noqa: E402

SEED = 1
MIN_LOCATED = 1  # measured 2-4 of 4 in 7 runs of seed 1
# Measured on seed 1 (docs/room.md): 45 % of the pairs within 3 samples (146 of 324; montage-103 49 %);
# a sync or emission off by one 256-frame period, or lost rounds, leave none.
MIN_DETECTED = 0.35



def check_pass(r, tries):
    live, rep = r["live"], r["replay"]
    print(f"live {live.get('targets_located')}/{live.get('targets_expected')} located, mean error "
          f"{live.get('mean_error_m')} m; replay {rep.get('targets_located')}/{rep.get('targets_expected')}, "
          f"{rep.get('mean_error_m')} m")
    users = sorted(r["emissions"])
    if len(users) < 2:
        tries.append(f"pass: {len(users)} walkers emitted")
    rounds = {u: r["emissions"][u]["scheduled"] for u in users}
    for u in users:
        e = r["emissions"][u]
        if e["syncs"] != 1 or e["late"] or e["cut"] or e["refused"] or e["scheduled"] < 10:
            tries.append(f"pass: walker {u}: {e} (expected the one start signal and every round scheduled)")
        if r["sync"].get(u, {}).get("received") != 1:
            tries.append(f"pass: walker {u} received {r['sync'].get(u, {}).get('received')} start signals (expected 1)")
    heard = int(r["room"].split(" emissions,")[0].rsplit(" ", 1)[1])
    if heard != sum(rounds.values()):
        tries.append(f"pass: the room heard {heard} emissions, the walkers scheduled {sum(rounds.values())}")
    det = r["detection"]
    print(f"other users' codes within 3 samples: {det['within_3']} of {det['pair_rounds']} pair-rounds")
    if not det["within_3"] >= MIN_DETECTED * det["pair_rounds"]:
        tries.append(f"pass: {det['within_3']} of {det['pair_rounds']} pair-rounds detected within 3 samples "
                     f"(expected >= {MIN_DETECTED:.0%})")
    if not (live.get("targets_located") or 0) >= MIN_LOCATED:
        tries.append(f"pass: live located {live.get('targets_located')} walkers (expected >= {MIN_LOCATED})")
    if not r["estimate_to_map_ms"]:
        tries.append("pass: no estimate reached the live map")


def main():
    args = parse_args()
    failures = []
    run = ("montage", "--seed", str(SEED))
    tries = []
    hil, r = pass_run(args, run, 300, tries)
    if r is not None:
        check_pass(r, tries)
    failures += tries
    check_clean(hil, "pass", failures)
    check_interrupt(args, run, 90, 3.0, failures)
    check_node_dies(args, run, 90, os.path.join("nodes", "W2.yaml"), lambda cmd: True, "locusd W2 exited", failures,
                    after_s=3.0)
    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
