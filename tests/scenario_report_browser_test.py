#!/usr/bin/python3
"""The scenario runner's HTML reports in a real browser (issue 33's acceptance for the reports).

In its own temporary folder, runs three scenarios with `autodrive-scenario run` (side by side,
each on its own DDS partition): the shipped `crossing_red_light` (a driver that ignores the
lights: it fails its expectation `red_light_violations: "== 0"`) with its seed and with
`--seed 2`, and `crossing_clean` (the same crossing, waiting for green). From their report.json
it writes a sweep's summary.json by hand (two variants: the clean driver, and the red-light
runner over both seeds) and renders summary.html with `autodrive-scenario render-summary`.
Then it opens a run's report.html and the summary.html as file:// in Debian's headless Chromium
(Selenium, with the network emulated offline) and checks, on each page:

  1. no console error (no SEVERE entry of the browser's log);
  2. no request but the page's own file:// URL (the DevTools Network events of the performance
     log, and `performance.getEntriesByType('resource')` empty), no element with a source;
  3. the uPlot charts are there (at least 3 `.uplot` on report.html: the map, the car's speed
     and lamps, the time line, every head's lamps; at least 1 on summary.html) and drawn (the map's canvas holds the car's colour, the
     lamp strip the red it ran), the cursor on the speed chart moves the car on the map, and
     moving the mouse over every chart logs no error;
  4. report.html names the violation (`red_light_violations`), says FAILED and shows the failed
     expectation; summary.html marks the failed runs and links each run's report.html by a
     relative path that exists;

and writes a full-page screenshot of each at 1400 px wide into the build folder
(`scenario_screenshots/scenario_report.png`, `scenario_summary.png`).

Run by CTest (tests/CMakeLists.txt) with AUTODRIVE_SOURCE_DIR, AUTODRIVE_BINARY_DIR and
CYCLONEDDS_URI set. Exit 0 when every check holds.
"""
import base64
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.parse

from selenium import webdriver
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service

SOURCE = pathlib.Path(os.environ["AUTODRIVE_SOURCE_DIR"])
BUILD = pathlib.Path(os.environ["AUTODRIVE_BINARY_DIR"])
BIN = BUILD / "bin"
SCENARIOS = SOURCE / "config" / "scenarios"
SHOTS = BUILD / "scenario_screenshots"
METRICS = ["collisions", "red_light_violations", "route_completion", "score", "time_to_goal_s"]
# For `worst` in the summary: the larger is worse for counts, the smaller for the rest.
WORST_IS_MAX = {"collisions", "red_light_violations", "time_to_goal_s"}

failures = []


def check(condition, message):
    print(("ok   " if condition else "FAIL ") + message, flush=True)
    if not condition:
        failures.append(message)


def wait_for(predicate, timeout, what, interval=0.2):
    """Polls `predicate` until it gives a true value (returned) or `timeout` s pass (None)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    print(f"gave up waiting for {what} after {timeout} s", flush=True)
    return None


def run_scenarios(work, env):
    """The three runs, side by side: {id: (variant, seed, exit code, run folder)}."""
    runs = {
        "clean_seed1": ("driver", SCENARIOS / "crossing_clean.yaml", None),
        "red_light_seed1": ("ignore_lights", SCENARIOS / "crossing_red_light.yaml", None),
        "red_light_seed2": ("ignore_lights", SCENARIOS / "crossing_red_light.yaml", 2),
    }
    procs = {}
    for run_id, (variant, scenario, seed) in runs.items():
        out = work / "runs" / run_id
        argv = [str(BIN / "autodrive-scenario"), "run", str(scenario), "--out", str(out), "--quiet"]
        if seed is not None:
            argv += ["--seed", str(seed)]
        log = open(work / f"{run_id}.log", "w")
        procs[run_id] = (subprocess.Popen(argv, env=env, stdout=log, stderr=subprocess.STDOUT),
                         log, out)
    results = {}
    for run_id, (proc, log, out) in procs.items():
        try:
            code = proc.wait(600)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = proc.wait()
        log.close()
        print(f"{run_id}: exit {code}; " + (work / f"{run_id}.log").read_text().strip()[-400:],
              flush=True)
        variant, scenario, seed = runs[run_id]
        results[run_id] = (variant, seed, code, out)
    return results


def summary_of(results):
    """A sweep's summary.json (the schema `autodrive-scenario sweep` writes) from the runs'
    reports: `runs_failed` counts the runs that could not be made."""
    variants = {}
    for run_id, (variant, seed, code, out) in results.items():
        report = json.loads((out / "report.json").read_text())
        run = report["metrics"]["run"]
        variants.setdefault(variant, {"name": variant, "parameters": {}, "runs": []})
        variants[variant]["parameters"] = {"scenario": report["scenario"]["name"]}
        variants[variant]["runs"].append({
            "id": run_id, "seed": report["seed"], "passed": report["passed"],
            "end": report["end"]["reason"], "exit_code": code,
            "report": f"runs/{run_id}/report.json",
            "metrics": {m: run.get(m) for m in METRICS}})
    for v in variants.values():
        v["stats"] = {}
        for m in METRICS:
            values = [r["metrics"][m] for r in v["runs"] if r["metrics"][m] is not None]
            if not values:
                v["stats"][m] = {"n": 0, "mean": None, "std": None, "min": None, "max": None,
                                 "worst": None}
                continue
            mean = sum(values) / len(values)
            std = (sum((x - mean) ** 2 for x in values) / (len(values) - 1)) ** 0.5 \
                if len(values) > 1 else 0.0
            v["stats"][m] = {"n": len(values), "mean": mean, "std": std, "min": min(values),
                             "max": max(values),
                             "worst": max(values) if m in WORST_IS_MAX else min(values)}
    all_runs = [r for v in variants.values() for r in v["runs"]]
    return {"sweep": {"name": "report_browser_test", "file": "(written by the test)"},
            "runs_total": len(all_runs), "runs_done": len(all_runs),
            "runs_failed": sum(1 for r in all_runs if r["end"] == "failed"),
            "metrics": METRICS, "variants": list(variants.values())}


def open_page(driver, path):
    """Opens a file offline; returns (its URL, whether it drew itself)."""
    driver.get_log("browser")  # drop what an earlier page left
    driver.get_log("performance")
    url = path.resolve().as_uri()
    driver.get(url)
    ready = wait_for(lambda: driver.execute_script("return window.reportReady === true;"), 60,
                     f"{path.name} to draw")
    return url, ready is not None


def check_no_error_and_no_request(driver, url, name):
    console = driver.get_log("browser")
    errors = [e for e in console if e.get("level") == "SEVERE"]
    check(not errors, f"{name}: no console error ({errors[:3]})")
    requests = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        # Every request but those of the browser's own pages (its first tab's chrome://).
        if (message.get("method") == "Network.requestWillBeSent" and
                not message["params"].get("documentURL", "").startswith("chrome://")):
            requests.append(message["params"]["request"]["url"])
    others = [u for u in requests if u != url and not u.startswith("data:")]
    check(url in requests and not others,
          f"{name}: no request but its own file:// URL ({len(requests)} requests: "
          f"{sorted(set(requests))[:5]})")
    resources = driver.execute_script(
        "return performance.getEntriesByType('resource').map((e) => e.name);")
    check(resources == [], f"{name}: no resource loaded ({resources[:5]})")
    sources = driver.execute_script(
        "return Array.from(document.querySelectorAll('[src]')).map((e) => e.getAttribute('src'));")
    check(sources == [], f"{name}: no element with a source ({sources[:5]})")


def count_colour(driver, selector, rgb, tolerance=40):
    """How many pixels of the first canvas under `selector` are within `tolerance` of `rgb`."""
    return driver.execute_script("""
      const [sel, rgb, tol] = arguments;
      const c = document.querySelector(sel);
      if (!c) return -1;
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let n = 0;
      for (let i = 0; i < d.length; i += 4) {
        if (Math.abs(d[i] - rgb[0]) <= tol && Math.abs(d[i + 1] - rgb[1]) <= tol &&
            Math.abs(d[i + 2] - rgb[2]) <= tol) n++;
      }
      return n;""", selector, list(rgb), tolerance)


def hover_every_chart(driver):
    """Moves the mouse across every chart (the cursor, the legends and the map's bodies follow
    it), so that an error in those paths shows in the console."""
    for over in driver.find_elements(By.CSS_SELECTOR, ".uplot .u-over"):
        driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", over)
        size = over.size
        chain = ActionChains(driver)
        for fx in (0.2, 0.5, 0.8):
            chain.move_to_element_with_offset(over, int((fx - 0.5) * size["width"]), 0)
        chain.perform()
    driver.execute_script("window.scrollTo(0, 0);")


def map_picture(driver):
    return driver.execute_script("return document.querySelector('#map canvas').toDataURL();")


def full_page_screenshot(driver, path, width=1400):
    """The whole page at `width` CSS pixels (the viewport made as tall as the page)."""
    height = driver.execute_script("return Math.ceil(document.documentElement.scrollHeight);")
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
        "width": width, "height": min(height, 10000), "deviceScaleFactor": 1, "mobile": False})
    time.sleep(0.5)  # the charts follow the viewport's size (one animation frame)
    shot = driver.execute_cdp_cmd("Page.captureScreenshot", {"format": "png"})
    path.write_bytes(base64.b64decode(shot["data"]))
    driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})


def main():
    work = pathlib.Path(tempfile.mkdtemp(prefix="scenario_report_browser_"))
    print(f"working in {work}", flush=True)
    env = dict(os.environ)
    SHOTS.mkdir(parents=True, exist_ok=True)
    results = run_scenarios(work, env)
    codes = {run_id: r[2] for run_id, r in results.items()}
    check(codes == {"clean_seed1": 0, "red_light_seed1": 1, "red_light_seed2": 1},
          f"the clean run passes and the red-light runs fail their expectation ({codes})")
    for run_id, (_, _, _, out) in results.items():
        check((out / "report.html").is_file(), f"{run_id}: report.html written beside report.json")
    if not all((r[3] / "report.json").is_file() for r in results.values()):
        return work
    summary = summary_of(results)
    (work / "summary.json").write_text(json.dumps(summary, indent=2))
    rendered = subprocess.run([str(BIN / "autodrive-scenario"), "render-summary",
                               str(work / "summary.json"), str(work / "summary.html")],
                              env=env, capture_output=True, text=True, timeout=60)
    check(rendered.returncode == 0 and (work / "summary.html").is_file(),
          f"render-summary wrote summary.html ({rendered.returncode}: {rendered.stderr.strip()})")

    options = Options()
    options.binary_location = "/usr/bin/chromium"
    for a in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1400,900", "--hide-scrollbars",
              f"--user-data-dir={work / 'chromium'}"]:
        options.add_argument(a)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    try:
        driver.set_script_timeout(30)
        # The network off: a page that reached for anything would fail to get it (and log it).
        driver.execute_cdp_cmd("Network.enable", {})
        driver.execute_cdp_cmd("Network.emulateNetworkConditions", {
            "offline": True, "latency": 0, "downloadThroughput": -1, "uploadThroughput": -1})

        # report.html of the first red-light run.
        report_path = results["red_light_seed1"][3] / "report.html"
        url, drew = open_page(driver, report_path)
        check(drew, "report.html drew itself (window.reportReady)")
        time.sleep(0.5)
        charts = driver.execute_script("return document.querySelectorAll('.uplot').length;")
        check(charts >= 3, f"report.html has its uPlot charts ({charts} .uplot elements)")
        before = map_picture(driver)
        speed = driver.find_element(By.CSS_SELECTOR, "#car-nigel_1 .speed .u-over")
        ActionChains(driver).move_to_element_with_offset(speed, -speed.size["width"] // 4, 0) \
            .perform()
        check(map_picture(driver) != before,
              "report.html: the cursor on the speed chart moves the car's body on the map")
        hover_every_chart(driver)
        check_no_error_and_no_request(driver, url, "report.html")
        for box in ["#map", "#car-nigel_1 .speed", "#car-nigel_1 .lamps", "#timeline"]:
            n = driver.execute_script(f"return document.querySelectorAll('{box} .uplot').length;")
            check(n == 1, f"report.html: a uPlot chart in {box}")
        car = count_colour(driver, "#map canvas", (0x25, 0x63, 0xeb))
        check(car > 200, f"report.html: the map shows the car's track ({car} pixels of its colour)")
        red = count_colour(driver, "#car-nigel_1 .lamps canvas", (0xdc, 0x26, 0x26), 30)
        check(red > 200, f"report.html: the lamp strip shows the red it ran ({red} pixels)")
        text = driver.execute_script("return document.body.innerText;")
        check("red_light_violations" in text,
              "report.html names the violation (red_light_violations)")
        check("FAILED" in driver.find_element("id", "verdict").text, "report.html says FAILED")
        problems = driver.find_element("id", "problems").text
        check("red_light_violations == 0 failed" in problems,
              f"report.html shows the failed expectation ({problems!r})")
        failed_rows = driver.execute_script(
            "return Array.from(document.querySelectorAll('#expectations tr.bad'))"
            ".map((tr) => tr.cells[0].textContent);")
        check(failed_rows == ["red_light_violations"],
              f"report.html's expectations table marks it failed ({failed_rows})")
        events = driver.execute_script(
            "return Array.from(document.querySelectorAll('#events tbody tr'))"
            ".map((tr) => tr.cells[3].textContent);")
        check("red light" in events and any(e.startswith("plan ") for e in events),
              f"report.html's time line has the violation and SPaT ({len(events)} rows)")
        full_page_screenshot(driver, SHOTS / "scenario_report.png")

        # summary.html
        url, drew = open_page(driver, work / "summary.html")
        check(drew, "summary.html drew itself (window.reportReady)")
        time.sleep(0.5)
        hover_every_chart(driver)
        check_no_error_and_no_request(driver, url, "summary.html")
        charts = driver.execute_script("return document.querySelectorAll('.uplot').length;")
        check(charts >= 1, f"summary.html has its uPlot charts ({charts} .uplot elements)")
        rows = driver.execute_script(
            "return Array.from(document.querySelectorAll('#runs tbody tr')).map((tr) => "
            "[tr.cells[1].textContent, tr.cells[3].textContent, "
            "tr.querySelector('a') ? tr.querySelector('a').getAttribute('href') : null]);")
        marked = {r[0]: "FAILED" in r[1] for r in rows}
        check(marked == {"clean_seed1": False, "red_light_seed1": True, "red_light_seed2": True},
              f"summary.html marks the failed runs ({marked})")
        links_ok = all(r[2] is not None and not r[2].startswith("/") and "://" not in r[2]
                       and (work / urllib.parse.unquote(r[2])).is_file() for r in rows)
        check(len(rows) == 3 and links_ok,
              f"summary.html links each run's report.html relatively ({[r[2] for r in rows]})")
        columns = driver.execute_script(
            "return document.querySelectorAll('#variants thead th').length;")
        check(columns == 3, f"summary.html shows the two variants side by side ({columns - 1})")
        full_page_screenshot(driver, SHOTS / "scenario_summary.png")
    finally:
        driver.quit()
    print(f"screenshots in {SHOTS}", flush=True)
    return work


if __name__ == "__main__":
    folder = main()
    if failures:
        print(f"{len(failures)} check(s) failed; the runs are in {folder}", flush=True)
        sys.exit(1)
    shutil.rmtree(folder, ignore_errors=True)
    print("all checks passed", flush=True)
