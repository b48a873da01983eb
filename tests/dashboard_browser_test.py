#!/usr/bin/python3
"""The dashboard in a real browser, on the running default city (issue 13's acceptance).

Brings the small town up with `autodrive-city up` (its own DDS partition, run folder and a free
port), opens the dashboard in Debian's headless Chromium through Selenium, and checks from
outside the dashboard, with DDS clients it does not share (`scmctl watch lamps`, `scmctl watch
fleet`, `scmctl --json intersections`):

  1. the page loads with no console error and shows every light head of the map;
  2. each head's colour on the page follows its `signal_<i>/state` within 200 ms (every change
     seen over a minute, at least 8 of them): the time `scmctl` received the report against the
     time the page changed the head (a MutationObserver), on the same host clock;
  3. the lab cars move on the page as the SCM's fleet (the Eye's poses) moves them: the page's
     position against the fleet message of the nearest stamp; each car's body as drawn (its
     rectangle's corners, from the SVG) within 1 cm of the simulator's ground truth footprint at
     the time of the observation drawn (`scmctl watch ground_truth`), over 100 samples or more;
  4. an action without the token is refused (by the server: HTTP 401, nothing reaches the SCM);
     with the token, clicking "flash" on the centre intersection puts it into flash (scmctl
     --json intersections) and the page shows the change;
  5. screenshots go into the build folder (dashboard_screenshots/).

Run by CTest (tests/CMakeLists.txt) with AUTODRIVE_SOURCE_DIR, AUTODRIVE_BINARY_DIR and
CYCLONEDDS_URI set. Exit 0 when every check holds.
"""
import json
import math
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

SOURCE = pathlib.Path(os.environ["AUTODRIVE_SOURCE_DIR"])
BUILD = pathlib.Path(os.environ["AUTODRIVE_BINARY_DIR"])
BIN = BUILD / "bin"
CITY = SOURCE / "config" / "cities" / "small_town.yaml"
SHOTS = BUILD / "dashboard_screenshots"

failures = []


def check(condition, message):
    print(("ok   " if condition else "FAIL ") + message, flush=True)
    if not condition:
        failures.append(message)


def wait_for(predicate, timeout, what, interval=0.1):
    """Polls `predicate` until it gives a true value (returned) or `timeout` s pass (None)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    print(f"gave up waiting for {what} after {timeout} s", flush=True)
    return None


class Lines:
    """A child process whose stdout lines are collected, each with the time it was read."""

    def __init__(self, argv, env):
        self.proc = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True)
        self.lines = []
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self):
        for line in self.proc.stdout:
            with self.lock:
                self.lines.append(line.rstrip("\n"))

    def json(self):
        with self.lock:
            out = []
            for line in self.lines:
                try:
                    out.append(json.loads(line))
                except json.JSONDecodeError:
                    pass
            return out

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def run(argv, env, timeout=60):
    return subprocess.run(argv, env=env, capture_output=True, text=True, timeout=timeout)


def post(url, body, token=None):
    request = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST",
                                     headers={"Content-Type": "application/json"})
    if token is not None:
        request.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(request, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"{}")


NIGEL_LENGTH, NIGEL_WIDTH = 0.318, 0.175
NIGEL_CENTRE_AHEAD = 0.07077  # the body's centre ahead of the rear axle's middle (the pose)


def truth_at(track, stamp):
    """The ground truth pose (x, y, yaw) of a car at `stamp`, interpolated between the two
    messages around it (None when they are more than 0.1 s apart or missing)."""
    before = [m for m in track if m["stamp"] <= stamp]
    after = [m for m in track if m["stamp"] >= stamp]
    if not before or not after:
        return None
    a = max(before, key=lambda m: m["stamp"])
    b = min(after, key=lambda m: m["stamp"])
    if b["stamp"] - a["stamp"] > 0.1:
        return None
    f = 0.0 if b["stamp"] == a["stamp"] else (stamp - a["stamp"]) / (b["stamp"] - a["stamp"])
    dyaw = math.atan2(math.sin(b["yaw"] - a["yaw"]), math.cos(b["yaw"] - a["yaw"]))
    return (a["x"] + f * (b["x"] - a["x"]), a["y"] + f * (b["y"] - a["y"]), a["yaw"] + f * dyaw)


def footprint(x, y, yaw):
    """A Nigel's body corners for a pose of its rear axle's middle."""
    c, s = math.cos(yaw), math.sin(yaw)
    cx, cy = x + NIGEL_CENTRE_AHEAD * c, y + NIGEL_CENTRE_AHEAD * s
    return [(cx + u * c - v * s, cy + u * s + v * c)
            for u in (-NIGEL_LENGTH / 2, NIGEL_LENGTH / 2)
            for v in (-NIGEL_WIDTH / 2, NIGEL_WIDTH / 2)]


def footprints_match(bodies, truth, tolerance=0.01, wanted=100):
    """Each drawn body's corners within `tolerance` m of the ground truth footprint's at the
    stamp of the observation drawn, for at least `wanted` (car, time) samples."""
    tracks = {}
    for m in truth:
        tracks.setdefault(m["vehicle"], []).append(m)
    errors = []
    for b in bodies:
        pose = truth_at(tracks.get(b["id"], []), b["stamp"])
        if pose is None:
            continue
        gt = footprint(*pose)
        errors.append(max(min(math.dist(p, q) for q in gt) for p in b["corners"]))
    errors.sort()
    if not errors:
        print(f"no drawn body matched a ground truth message ({len(bodies)} drawn, "
              f"{len(truth)} ground truth messages)", flush=True)
        return False
    print(f"{len(errors)} drawn bodies against ground truth: median "
          f"{errors[len(errors) // 2] * 1000:.1f} mm, worst {errors[-1] * 1000:.1f} mm "
          f"(corner to corner)", flush=True)
    return len(errors) >= wanted and errors[-1] <= tolerance


def main():
    work = pathlib.Path(tempfile.mkdtemp(prefix="dashboard_browser_"))
    partition = f"dashboard_{os.getpid()}"
    env = dict(os.environ)
    env["XDG_STATE_HOME"] = str(work / "state")  # the run folder: <it>/autodrive/small_town
    run_dir = work / "state" / "autodrive" / "small_town"
    SHOTS.mkdir(parents=True, exist_ok=True)
    scmctl = [str(BIN / "scmctl"), "--partition", partition]

    def centre_mode():
        """The centre's mode, as the SCM's `intersections` answer types it (scmctl --json)."""
        answer = json.loads(run(scmctl + ["--json", "intersections"], env).stdout)
        return answer["values"]["centre"]["mode"]

    launcher = subprocess.Popen(
        [str(BIN / "autodrive-city"), "up", str(CITY), "--partition", partition,
         "--dashboard", "127.0.0.1:0"],
        env=env, stdout=open(work / "launcher.log", "w"), stderr=subprocess.STDOUT)
    driver = None
    watchers = []
    try:
        url_file = run_dir / "dashboard.url"
        if not wait_for(lambda: url_file.exists() or launcher.poll() is not None, 300,
                        "the city to come up") or launcher.poll() is not None:
            print((work / "launcher.log").read_text())
            check(False, "the city came up with its dashboard")
            return
        url = url_file.read_text().strip()
        token_line = [l for l in (run_dir / "dashboard.tokens").read_text().splitlines()
                      if l and not l.startswith("#")][0]
        operator, token = token_line.split()
        print(f"dashboard at {url}; operator {operator}", flush=True)

        lamps = Lines(scmctl + ["watch", "lamps", "--json"], env)
        fleet = Lines(scmctl + ["watch", "fleet", "--json"], env)
        truth = Lines(scmctl + ["watch", "ground_truth", "--json"], env)
        watchers += [lamps, fleet, truth]

        options = Options()
        options.binary_location = "/usr/bin/chromium"
        for a in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                  "--window-size=1600,1000", f"--user-data-dir={work / 'chromium'}"]:
            options.add_argument(a)
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
        driver.set_script_timeout(30)
        driver.get(url)
        check(wait_for(lambda: driver.execute_script(
            "return !!(window.dashboard && window.dashboard.stateReceived)"), 60,
            "the page's first state") is not None, "the page received the city's state")

        # 1. Every head of the map is on the page.
        state = json.loads(urllib.request.urlopen(url + "api/state", timeout=30).read())
        heads = [h["id"] for h in state["map"]["heads"]]
        shown = [h for h in heads if driver.find_elements(By.ID, f"head-{h}")]
        check(len(heads) > 0 and shown == heads,
              f"every light head of the map is on the page ({len(shown)} of {len(heads)})")
        # Every light is in the devices table with its health (from its periodic status).
        def listed():
            return driver.execute_script(
                "return Array.from(document.querySelectorAll('#devices tbody tr[data-id]'))"
                ".map((tr) => [tr.getAttribute('data-id'), tr.cells[1].textContent.trim()]);")
        wanted = {f"signal_{h}" for h in heads}
        wait_for(lambda: wanted <= {d for d, _ in listed()}, 30, "every light in the devices")
        devices = dict(listed())
        check(wanted <= set(devices) and all(devices[d] for d in wanted),
              f"every light is in the devices table with its health "
              f"({len(wanted & set(devices))} of {len(wanted)}: "
              f"{sorted({devices.get(d, '?') for d in wanted})})")
        # ... and heard: "live" while the SCM hears it (not an age that grows while it is quiet).
        def heard():
            return dict(driver.execute_script(
                "return Array.from(document.querySelectorAll('#devices tbody tr[data-id]'))"
                ".map((tr) => [tr.getAttribute('data-id'), tr.lastElementChild.textContent]);"))
        wait_for(lambda: all(heard().get(d) == "live" for d in wanted), 30, "every light live")
        cells = heard()
        check(all(cells.get(d) == "live" for d in wanted),
              f"every light is live in the devices table "
              f"({sorted({cells.get(d, '?') for d in wanted})})")
        # The lamp column names each light's colour, with a dot of it.
        def lamp_cells():
            return driver.execute_script(
                "return Array.from(document.querySelectorAll('#devices tbody tr[data-id^=\"signal_\"]'))"
                ".map((tr) => [tr.getAttribute('data-id'), tr.cells[3].textContent.trim(),"
                " !!tr.cells[3].querySelector('i.dot')]);")
        colours = {"off", "red", "yellow", "green", "flashing red", "flashing yellow"}
        cells = lamp_cells()
        check(len(cells) == len(wanted) and all(t in colours and dot for _, t, dot in cells),
              f"the devices table's lamp column shows each light's colour "
              f"({sorted({t for _, t, _ in cells})})")
        # The page's lamp changes, as they happen, by the host's clock.
        driver.execute_script("""
          window.__lampLog = [];
          const log = (el) => window.__lampLog.push(
              {t: Date.now(), head: +el.id.slice(5), lamp: +el.getAttribute('data-lamp')});
          const obs = new MutationObserver((ms) => ms.forEach((m) => log(m.target)));
          document.querySelectorAll('circle[id^="head-"]').forEach((el) => {
            log(el);
            obs.observe(el, {attributes: true, attributeFilter: ['data-lamp']});
          });""")
        observe_from = time.time()
        wait_for(lambda: len(lamps.json()) >= len(heads), 60, "the first report of each head")

        # 3. Cars: the page's positions over 20 s against the fleet of the nearest stamp.
        samples = []
        for _ in range(20):
            cars = driver.execute_script("""
              return Array.from(document.querySelectorAll('g[id^="car-"]')).map((g) => (
                  {id: g.id.slice(4), x: +g.getAttribute('data-x'), y: +g.getAttribute('data-y'),
                   t: Date.now() / 1000}));""")
            samples.append(cars)
            time.sleep(1.0)
        driver.save_screenshot(str(SHOTS / "1_city.png"))
        moved = set()
        for car in {c["id"] for s in samples for c in s}:
            track = [c for s in samples for c in s if c["id"] == car]
            if len(track) >= 2 and ((track[-1]["x"] - track[0]["x"]) ** 2 +
                                    (track[-1]["y"] - track[0]["y"]) ** 2) ** 0.5 > 0.10:
                moved.add(car)
        check(len(moved) >= 2, f"lab cars move on the page ({sorted(moved)} moved > 10 cm in 20 s)")
        fleet_msgs = fleet.json()
        worst = 0.0
        compared = 0
        for s in samples[5:]:
            for c in s:
                best = None
                for m in fleet_msgs:
                    for v in m.get("vehicles", []):
                        if v.get("vehicle") == c["id"]:
                            d = abs(m["stamp"] - c["t"])
                            if best is None or d < best[0]:
                                best = (d, ((v["x"] - c["x"]) ** 2 + (v["y"] - c["y"]) ** 2) ** 0.5)
                if best is not None and best[0] < 0.5:
                    worst = max(worst, best[1])
                    compared += 1
        check(compared >= 20 and worst < 0.15,
              f"the page's cars are where the SCM's fleet puts them ({compared} positions, "
              f"worst {worst * 1000:.0f} mm from the fleet message nearest in time)")

        # 3b. Each lab car's drawn body against the simulator's ground truth at the time of the
        # observation drawn: the rectangle's corners, taken from the SVG as drawn, in map metres.
        bodies = []
        for _ in range(60):
            bodies += driver.execute_script("""
              const layer = document.getElementById('cars');
              const back = layer.getCTM().inverse();
              return Array.from(document.querySelectorAll('g[id^="car-"]'))
                .filter((g) => g.style.display !== 'none' && g.hasAttribute('data-stamp'))
                .map((g) => {
                  const m = back.multiply(g.querySelector('.body rect').getCTM());
                  const corners = [[-0.5, -0.275], [0.5, -0.275], [0.5, 0.275], [-0.5, 0.275]]
                    .map(([x, y]) => { const p = new DOMPoint(x, y).matrixTransform(m);
                                       return window.dashboard.mapOfPx(p.x, p.y); });
                  return {id: g.id.slice(4), stamp: +g.getAttribute('data-stamp'), corners};
                });""")
            time.sleep(0.25)
        check(footprints_match(bodies, truth.json()),
              "each lab car's drawn body lies on its ground truth footprint")

        # 2. Lamps: every change over a minute (from the 20 s above on).
        wait_for(lambda: time.time() - observe_from > 60, 90, "a minute of lamp changes", 1.0)
        page = driver.execute_script("return window.__lampLog;")
        dds = lamps.json()
        last = {}
        latencies = []
        missing = []
        for r in dds:
            changed = last.get(r["head"]) is not None and last[r["head"]] != r["lamp"]
            last[r["head"]] = r["lamp"]
            if not changed or r["rx"] < observe_from + 1.0 or r["rx"] > time.time() - 2.0:
                continue
            rx_ms = r["rx"] * 1000.0
            hits = [p["t"] for p in page if p["head"] == r["head"] and p["lamp"] == r["lamp"]
                    and p["t"] >= rx_ms - 100.0]
            if hits:
                latencies.append(min(hits) - rx_ms)
            else:
                missing.append(r)
        latencies.sort()
        text = (f"{len(latencies)} changes, worst {latencies[-1]:.0f} ms, median "
                f"{latencies[len(latencies) // 2]:.0f} ms" if latencies else "no changes")
        check(not missing, f"the page showed every lamp change scmctl saw ({len(missing)} missing)")
        check(len(latencies) >= 8 and latencies[-1] <= 200.0,
              f"each head's colour follows its signal_<i>/state within 200 ms ({text})")

        # 4. Actions. Without the token: refused by the server, and nothing changed.
        status, answer = post(url + "api/action",
                              {"command": "mode", "args": {"intersection": "centre",
                                                           "mode": "flash"}})
        check(status == 401 and answer.get("result") == "unauthorized",
              f"an action without a token is refused (HTTP {status}, {answer})")
        status, answer = post(url + "api/action",
                              {"command": "mode", "args": {"intersection": "centre",
                                                           "mode": "flash"}}, token + "x")
        check(status == 401, f"an action with a wrong token is refused (HTTP {status})")
        check(centre_mode() != "flash", "the refused actions did not reach the SCM")
        # The page with no token: the click is refused too.
        driver.find_element(By.CSS_SELECTOR,
                            '#x-centre button[data-action="mode-flash"]').click()
        result = wait_for(lambda: driver.find_element(By.ID, "action-result")
                          .get_attribute("data-result"), 10, "the page's answer")
        check(result == "unauthorized", f"the page refuses flash without its token ({result})")
        console_before_token = [e for e in driver.get_log("browser")]
        # With the token.
        box = driver.find_element(By.ID, "token")
        box.clear()
        box.send_keys(token)
        driver.find_element(By.CSS_SELECTOR,
                            '#x-centre button[data-action="mode-flash"]').click()
        result = wait_for(lambda: driver.find_element(By.ID, "action-result")
                          .get_attribute("data-result") == "ok" and "ok", 30, "flash's answer")
        check(result == "ok", "clicking flash with the token is accepted")
        mode = centre_mode()
        check(mode == "flash", f"scmctl intersections: the centre's mode is {mode}")
        page_mode = wait_for(lambda: driver.find_element(By.ID, "x-centre")
                             .get_attribute("data-mode") == "flash", 15, "the page's flash")
        check(page_mode is not None, "the page shows the centre in flash")
        time.sleep(2.0)  # the lamps flashing, for the picture
        driver.save_screenshot(str(SHOTS / "2_centre_flash.png"))
        events = json.loads(run(scmctl + ["--json", "events", "--limit", "20"], env).stdout)
        # The actor of an operator's command is "NAME (CLIENT)": the dashboard's client id is
        # dashboard/<name>@<address>.
        check(any(f"dashboard/{operator}@" in e.get("actor", "")
                  for e in events["values"].values() if isinstance(e, dict)),
              "the SCM logged the action with who did it (dashboard/<name>@<address>)")
        driver.find_element(By.CSS_SELECTOR,
                            '#x-centre button[data-action="mode-auto"]').click()
        wait_for(lambda: driver.find_element(By.ID, "x-centre").get_attribute("data-mode")
                 != "flash", 30, "the centre back from flash")

        # 1. No console error at any time (the refusals above are HTTP answers, not errors).
        console = console_before_token + driver.get_log("browser")
        errors = [e for e in console if e.get("level") == "SEVERE"]
        check(not errors, f"no console error ({errors[:3]})")
        driver.save_screenshot(str(SHOTS / "3_after.png"))
    finally:
        if driver is not None:
            driver.quit()
        for w in watchers:
            w.stop()
        if launcher.poll() is None:
            launcher.send_signal(signal.SIGINT)
            try:
                launcher.wait(120)
            except subprocess.TimeoutExpired:
                launcher.kill()
        check(launcher.returncode == 0, f"the city stopped cleanly (launcher exit "
                                        f"{launcher.returncode})")
    print(f"screenshots in {SHOTS}", flush=True)


if __name__ == "__main__":
    main()
    if failures:
        print(f"{len(failures)} check(s) failed", flush=True)
        sys.exit(1)
    print("all checks passed", flush=True)
