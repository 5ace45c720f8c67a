#!/usr/bin/python3
"""integration.hil.tum: TUM's live roles in the virtual room (tools/hil/hil.py tum, `./run hil tum`).

On simulated seed 1 (static, overlap, 4 devices), 8 s of exchanges:
1. pass:      hil.py tum must exit 0 with every device located, the live Eq. 23 median within
              TOLERANCE_M of the replay's on the same layout (hil.py replays it), every node adopting the
              same working pair, the expected one (the layout's emitters: on one machine every RTT ties,
              elect_order breaks it), both working devices emitting with none missed or refused, an
              estimate on the live map; run once more (and said so) only when that is missed while the
              room reported xruns (a machine too loaded to feed the nodes);
2. interrupt: Ctrl-C (SIGINT) to hil.py while its nodes run: exit 130;
3. node dies: a monitor's locusd SIGKILLed mid-run: hil.py fails (exit 1) naming it.
After each: no jackd, mosquitto, `locus room` or locusd of that run is left, nor JACK's shm files
(test_hil.py's checks). The figures are printed; no timing is asserted.
"""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_hil import check_clean, check_interrupt, check_node_dies, parse_args, pass_run  # noqa: E402

RUN = ("tum", "--seed", "1", "--track", "static", "--duration", "8")
# The live run differs from the replay by what the room renders (its interpolator, noise, the 16-bit IMU,
# the magnetometer's errors), the live tone schedule (device 2 0.11-0.16 s after device 1, not overlapping)
# and fewer exchanges (8 s instead of the scene's 27): measured 4.8 vs 4.9 cm on this seed in the last
# ctest run, 4.7 vs 4.9 cm over 12 s (docs/room.md); other layouts differ by more (static seed 2: 71 cm).
TOLERANCE_M = 0.05


def main():
    args = parse_args()
    failures = []
    for attempt in (1, 2):
        problems = []
        hil, r = pass_run(args, RUN, 300, problems)
        if attempt == 2 or r is None:
            break
        room_xruns = re.search(r"(\d+) xruns", r.get("room") or "")
        live, replay = r["live"], r["replay"]
        ok = live.get("targets_located") == live.get("targets_expected") and live.get("median_error_m") is not None and \
            replay.get("median_error_m") is not None and live["median_error_m"] <= replay["median_error_m"] + TOLERANCE_M
        if ok:
            break
        # One retry, said: room xruns (chopped tones), or the known live defect that the first
        # exchanges' solve settles a monitor in a mirror basin with its clocks paired right (2 of 16
        # runs, docs/tum.md "Live roles"); the same failure twice fails.
        xr = int(room_xruns.group(1)) if room_xruns else 0
        print(f"retry: bars missed (live median {live.get('median_error_m')} m vs replay "
              f"{replay.get('median_error_m')} m) with {xr} room xruns"
              f"{'' if xr else ': the known mirror-basin start of the live solve'}; running once more")
        check_clean(hil, "pass (first attempt)", failures)
    failures += problems
    if r is not None:
        live, replay = r["live"], r["replay"]
        if not (live.get("targets_located") == live.get("targets_expected") == 4):
            failures.append(f"pass: located {live.get('targets_located')}/{live.get('targets_expected')} (expected 4/4)")
        if live.get("median_error_m") is None or replay.get("median_error_m") is None or \
                not live["median_error_m"] <= replay["median_error_m"] + TOLERANCE_M:
            failures.append(f"pass: live median {live.get('median_error_m')} m vs replay {replay.get('median_error_m')} m "
                            f"(tolerance {TOLERANCE_M} m)")
        roles = set(tuple(v) if v else None for v in r["roles"].values())
        if len(roles) != 1 or r["elected"] is None or list(r["elected"]) != list(r["expected_election"]):
            failures.append(f"pass: election {r['roles']} (expected every node: {r['expected_election']})")
        emitted = r["emissions"]
        for ident in r["expected_election"]:
            e = emitted.get(ident)
            if not e or e["scheduled"] < 20 or e["missed"] or e["refused"]:
                failures.append(f"pass: emissions of {ident}: {e} (expected >= 20 scheduled for 8 s, none missed or refused)")
        if not r["sync"] or any(s["n"] < 4 for s in r["sync"]):
            failures.append(f"pass: link sync {r['sync']} (expected every directed pair over >= 4 round trips)")
        if not r["latency_ms"]:
            failures.append("pass: no estimate reached the live map")
    check_clean(hil, "pass", failures)

    check_interrupt(args, RUN, 120, 3.0, failures)
    check_node_dies(args, RUN, 120, "nodes", lambda cmd: "N3.yaml" in cmd, "locusd N3 exited", failures, after_s=4.0)

    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
