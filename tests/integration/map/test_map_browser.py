#!/usr/bin/python3
"""The live map in a real browser during a real replay (issue 18).

Simulates the AMIL field test (`locus simulate amil`), replays it through `locusd --scene ... --speed
realtime --http 127.0.0.1:0`, and opens the map in headless Chromium while the replay runs. Chromium is
driven over the DevTools protocol on a pipe (--remote-debugging-pipe: fd 3 in, fd 4 out, NUL-separated
JSON; no extra Python packages). Once locusd says the replay finished, the test reads the drawn map
back from the DOM (every drawn element carries data-* attributes with the numbers it was drawn from)
and checks it against the estimates locusd wrote to its JSON-lines output: one drawn target per
estimated target of the frame on show, at the estimate's position (or bearing, for direction-only
results), the reference device at the origin, one health row per scene device with its detections'
SNR, and the estimates having arrived over the live event stream (the page was open before they
existed). It keeps a screenshot, OUT/map.png.

Every process it starts (locusd, chromium) runs in its own process group and is killed in `finally`,
also when a check fails. Exit status: 0 pass, 1 fail, 77 skipped (chromium is not installed; CI
installs it with tools/install-deps.sh, so there it runs).

    test_map_browser.py --bin build/bin --source . --out build/map-test
"""
import argparse
import base64
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tools", "scripts"))
from campaign_common import kill_group  # noqa: E402

SKIP = 77


class Cdp:
    """DevTools protocol over chromium's --remote-debugging-pipe."""

    def __init__(self, proc, write_fd, read_fd):
        self.proc, self.w, self.r = proc, write_fd, read_fd
        self.next_id, self.buf = 0, b""

    def call(self, method, params=None, session=None, timeout=30.0):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + timeout
        while True:
            while b"\0" not in self.buf:
                if time.monotonic() > end:
                    raise TimeoutError(f"chromium did not answer {method} within {timeout} s")
                import select
                ready, _, _ = select.select([self.r], [], [], 0.5)
                if ready:
                    chunk = os.read(self.r, 1 << 20)
                    if not chunk:
                        raise RuntimeError(f"chromium closed the DevTools pipe (exit {self.proc.poll()})")
                    self.buf += chunk
            raw, self.buf = self.buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    def eval(self, session, expression):
        r = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True},
                      session)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page script failed: {r['exceptionDetails']}")
        return r["result"].get("value")


def get_json(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        return json.load(r)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", default="1")
    args = ap.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        print("SKIP: chromium is not installed (tools/install-deps.sh installs it)")
        return SKIP
    os.makedirs(args.out, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="locus-map-test-")
    locusd = browser = None
    failures = []

    def check(ok, what):
        print(("ok   " if ok else "FAIL ") + what)
        if not ok:
            failures.append(what)

    try:
        scene = os.path.join(tmp, "scene")
        subprocess.run([os.path.join(args.bin, "locus"), "simulate", "amil", scene, "--seed", args.seed],
                       check=True, stdout=subprocess.DEVNULL)
        # Chromium with the DevTools protocol on fds 3 (commands in) and 4 (replies out), started and
        # given its page before locusd, so that a slow browser start cannot miss the replay.
        to_chrome_r, to_chrome_w = os.pipe()
        from_chrome_r, from_chrome_w = os.pipe()
        profile = os.path.join(tmp, "profile")
        cmd = (f"exec {chromium} --headless --no-sandbox --disable-gpu --no-first-run --no-default-browser-check "
               f"--user-data-dir={profile} --window-size=1280,800 --remote-debugging-pipe "
               f"3<&{to_chrome_r} 4>&{from_chrome_w} about:blank")
        browser = subprocess.Popen(["bash", "-c", cmd], pass_fds=(to_chrome_r, from_chrome_w),
                                   stdout=subprocess.DEVNULL, stderr=open(os.path.join(args.out, "chromium.log"), "w"),
                                   start_new_session=True)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        cdp = Cdp(browser, to_chrome_w, from_chrome_r)
        target = cdp.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = cdp.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        cdp.call("Page.enable", session=session)
        cdp.call("Emulation.setDeviceMetricsOverride",
                 {"width": 1280, "height": 800, "deviceScaleFactor": 1, "mobile": False}, session)
        estimates_path = os.path.join(tmp, "estimates.jsonl")
        locusd = subprocess.Popen(
            [os.path.join(args.bin, "locusd"), "--config", os.path.join(args.source, "config/amil.yaml"), "--scene",
             scene, "--speed", "realtime", "--http", "127.0.0.1:0", "--http-param", "linger_s=120", "-o",
             estimates_path],
            stdout=subprocess.PIPE, stderr=open(os.path.join(args.out, "locusd.log"), "w"), text=True,
            start_new_session=True)
        line = locusd.stdout.readline().strip()
        check(line.startswith("map: http://127.0.0.1:"), f"locusd prints the map's URL ({line!r})")
        if failures:
            return 1
        url = line.split(" ", 1)[1]
        t_started = time.monotonic()

        cdp.call("Page.navigate", {"url": url}, session)

        # The page is up (state loaded, stream open) during the replay, before any estimate exists.
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and cdp.eval(session, "document.body && document.body.dataset.ready") != "1":
            time.sleep(0.1)
        check(cdp.eval(session, "document.body.dataset.ready") == "1", "the page loaded its state")
        state = get_json(url + "api/state")
        check(not state["finished"], f"the page was open while the replay ran "
                                     f"({time.monotonic() - t_started:.1f} s after start)")
        check(len(state["tracks"]) == 0, "no estimate existed yet when the page opened")

        # Wait for the replay's end as the page sees it (the status event of the stream).
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and cdp.eval(session, "document.body.dataset.finished") != "1":
            time.sleep(0.2)
        check(cdp.eval(session, "document.body.dataset.finished") == "1", "the page heard that the replay finished")
        time.sleep(0.5)  # one animation frame for the last render

        estimates = [json.loads(l) for l in open(estimates_path) if l.strip()]
        estimates = [e for e in estimates if e["type"] == "estimate"]
        check(len(estimates) > 0, f"locusd wrote {len(estimates)} estimates")
        shown_frame = cdp.eval(session, "document.getElementById('map').dataset.frame")
        latest = {}
        for e in estimates:
            if e["frame"] == shown_frame:
                latest[(e["plugin"], e["reference"], e["target"])] = e
        check(len(latest) > 0, f"the map shows the frame of the estimates ({shown_frame!r})")
        drawn = cdp.eval(session, """JSON.stringify({
            estimates: [...document.querySelectorAll('#map g.estimate')].map(g => ({
                target: g.dataset.target, plugin: g.dataset.plugin, x: +g.dataset.x, y: +g.dataset.y,
                std: g.dataset.std === '' ? null : +g.dataset.std, ellipse: !!g.querySelector('ellipse')})),
            bearings: [...document.querySelectorAll('#map g.bearing')].map(g => ({
                target: g.dataset.target, plugin: g.dataset.plugin, dir: +g.dataset.directionRad})),
            devices: [...document.querySelectorAll('#map g.device')].map(g => ({id: g.dataset.id,
                x: +g.dataset.x, y: +g.dataset.y})),
            health: [...document.querySelectorAll('#health tbody tr')].map(tr => ({id: tr.dataset.device,
                snr: tr.cells[7].textContent, link: tr.dataset.link})),
            sse: +(document.body.dataset.sseEvents || 0),
            log: document.querySelectorAll('#events li').length})""")
        drawn = json.loads(drawn)
        by_target = {d["target"]: d for d in drawn["estimates"]}
        by_bearing = {d["target"]: d for d in drawn["bearings"]}
        check(len(drawn["estimates"]) + len(drawn["bearings"]) == len(latest),
              f"one drawn target per estimated target: {len(drawn['estimates'])} positions + "
              f"{len(drawn['bearings'])} bearings for {len(latest)} targets")
        worst = 0.0
        for (_plugin, _ref, target), e in latest.items():
            if "direction_only" in e["flags"]:
                d = by_bearing.get(target)
                check(d is not None, f"{target}: drawn as a bearing")
                if d:
                    worst = max(worst, abs(d["dir"] - e["direction_rad"]))
            else:
                d = by_target.get(target)
                check(d is not None, f"{target}: drawn at its position")
                if d:
                    err = math.hypot(d["x"] - e["position_m"][0], d["y"] - e["position_m"][1])
                    worst = max(worst, err)
                    check(d["ellipse"] == (e["std_m"] is not None and e["std_m"] > 0),
                          f"{target}: its uncertainty ellipse is drawn")
        check(worst < 1e-9, f"every drawn target is where its estimate says (largest difference {worst:.2e})")
        refs = {e["reference"] for e in latest.values() if e["reference"]}
        check({d["id"] for d in drawn["devices"]} == refs and all(d["x"] == 0 and d["y"] == 0 for d in drawn["devices"]),
              f"the reference device(s) {sorted(refs)} at the origin")
        scene_devices = sorted(os.path.basename(p) for p in os.listdir(scene)
                               if os.path.isdir(os.path.join(scene, p)))
        check(sorted(h["id"] for h in drawn["health"]) == scene_devices,
              f"one health row per scene device ({len(drawn['health'])} of {len(scene_devices)})")
        check(all(h["snr"] not in ("", "–") for h in drawn["health"]), "every device shows its last detection's SNR")
        check(all(h["link"] == "in-process" for h in drawn["health"]), "link state shown (in-process replay)")
        check(drawn["sse"] >= len(estimates), f"the estimates reached the open page over the event stream "
                                              f"({drawn['sse']} live events)")
        check(drawn["log"] > 0, f"the event log shows events ({drawn['log']})")

        shot = cdp.call("Page.captureScreenshot", {"format": "png"}, session)
        png = os.path.join(args.out, "map.png")
        with open(png, "wb") as f:
            f.write(base64.b64decode(shot["data"]))
        print(f"screenshot: {png}")
        try:
            cdp.call("Browser.close", timeout=5)
        except Exception:
            pass
        # locusd ends its linger on SIGTERM, cleanly.
        os.killpg(locusd.pid, signal.SIGTERM)
        status = locusd.wait(timeout=30)
        check(status == 0, f"locusd exits 0 on SIGTERM while lingering (exit {status})")
    finally:
        kill_group(browser)
        kill_group(locusd)
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
