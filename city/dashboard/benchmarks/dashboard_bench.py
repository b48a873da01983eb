#!/usr/bin/python3
"""autodrive-bench-dashboard: the dashboard under a big city, measured in a real browser.

Brings up, with `autodrive-city up` and real processes, an N x N grid city (default 32 x 32:
1,024 fixed-time intersections, 4,096 simulated light heads on four `autodrive-infra` hosts),
the SCM, SUMO's background traffic (`autodrive-traffic`, default 1,000 cars, wall clock) and
the dashboard; opens the page in Debian's headless Chromium (Selenium) and, after a warm-up,
measures over --seconds:

  - the dashboard's CPU (utime + stime of its process, % of one core);
  - bytes per second per browser (the dashboard's /api/metrics: bytes queued to browsers);
  - the update latency from the DDS sample to the page, measured in the browser: for each
    message, Date.now() when the page handled it minus the sample's DDS source time
    (p50, p99, max per stream: lamps, SPaT, traffic), with --browsers pages open at once.

Goals (issue 13): <= 10% of one core, <= 100 ms p99. Prints figures; asserts nothing.
"""
import argparse
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

BIN = pathlib.Path(os.path.realpath(__file__)).parent
SOURCE = pathlib.Path(os.environ.get("AUTODRIVE_SOURCE_DIR", BIN.parent.parent))


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def udp_drops(pid):
    """Datagrams dropped so far on the UDP sockets of process `pid` (receive buffer full)."""
    inodes = set()
    for fd in pathlib.Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    drops = 0
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = pathlib.Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if fields[9] in inodes:
                drops += int(fields[-1])
    return drops


def percentile(values, p):
    if not values:
        return float("nan")
    values = sorted(values)
    return values[min(len(values) - 1, int(p * (len(values) - 1) + 0.5))]


def write_city(work, n, cars, partition):
    subprocess.run([str(BIN / "autodrive-map"), "grid", str(n), str(n), "--control", "signal",
                    "-o", str(work / "grid.yaml")], check=True, stdout=subprocess.DEVNULL)
    # The signalised intersections, as `autodrive-map info` lists them.
    info = subprocess.run([str(BIN / "autodrive-map"), "info", str(work / "grid.yaml")],
                          check=True, capture_output=True, text=True).stdout
    names = [line.split()[0] for line in info.splitlines() if " signal at (" in line]
    # The lights report once a second each (4,096 reports a second in all): the SCM's device
    # time-out must be longer than that.
    city = ["name: grid", "map: grid.yaml", "operators: {allowed: [bench]}",
            "devices: {timeout_s: 3.0}", "intersections:"]
    for name in names:
        city += [f"  - name: {name}",
                 "    groups: [{id: 1, name: e, approaches: [east]}, {id: 2, name: n, "
                 "approaches: [north]}, {id: 3, name: w, approaches: [west]}, {id: 4, name: s, "
                 "approaches: [south]}]",
                 "    plans: [{name: day, phases: [{groups: [1], green_s: 8.0}, {groups: [2], "
                 "green_s: 8.0}, {groups: [3], green_s: 8.0}, {groups: [4], green_s: 8.0}]}]"]
    # The lights: four hosts of a quarter of the heads each (one autodrive-infra process
    # cannot host all 4,096: Cyclone refuses its waitset), status once a second per head.
    heads = 4 * len(names)
    hosts = 4
    agents = []
    for k in range(hosts):
        ids = list(range(1 + k * heads // hosts, 1 + (k + 1) * heads // hosts))
        (work / f"grid_lights_{k}.yaml").write_text(
            f"name: grid_lights_{k}\ncity: grid\nmap: grid.yaml\nstatus_period_s: 1.0\n"
            f"default_backend: simulated\nheads: [{', '.join(map(str, ids))}]\n")
        agents.append(f"    - {{name: lights_{k}, command: [{BIN / 'autodrive-infra'}, --config, "
                      f"{work / f'grid_lights_{k}.yaml'}, --partition, {partition}], "
                      f"restart: always}}")
    city += [f"traffic: {{seed: 1, vehicles: {cars}}}" if cars > 0 else "",
             "launch:",
             f"  run_dir: {work / 'run'}",
             "  lights: {mode: off}",
             f"  traffic: {{mode: {'on' if cars > 0 else 'off'}, ready_timeout_s: 900}}",
             "  dashboard: {mode: on, listen: \"127.0.0.1:0\"}",
             "  agents:"] + agents
    (work / "grid_city.yaml").write_text("\n".join(city) + "\n")
    return work / "grid_city.yaml", len(names)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--grid", type=int, default=32, help="intersections per side")
    parser.add_argument("--cars", type=int, default=1000, help="SUMO cars (0: no SUMO)")
    parser.add_argument("--seconds", type=float, default=60.0, help="measured seconds")
    parser.add_argument("--warmup", type=float, default=20.0, help="seconds before measuring")
    parser.add_argument("--browsers", type=int, default=1, help="pages open at once")
    parser.add_argument("--discovery", type=float, default=300.0,
                        help="seconds to wait for the dashboard to hear every head")
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    args = parser.parse_args()

    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    work = pathlib.Path(tempfile.mkdtemp(prefix="bench_dashboard_"))
    partition = f"bench_dashboard_{os.getpid()}"
    city, intersections = write_city(work, args.grid, args.cars, partition)
    print(f"grid {args.grid}x{args.grid}: {intersections} intersections, {args.cars} SUMO cars; "
          f"work folder {work}", flush=True)
    env = dict(os.environ)
    env.setdefault("CYCLONEDDS_URI", f"file://{SOURCE}/config/dds/localhost.xml")
    launcher = subprocess.Popen([str(BIN / "autodrive-city"), "up", str(city), "--partition",
                                 partition], env=env, stdout=open(work / "launcher.log", "w"),
                                stderr=subprocess.STDOUT)
    drivers = []
    try:
        status = work / "run" / "status.json"
        deadline = time.monotonic() + 1200
        while time.monotonic() < deadline and launcher.poll() is None:
            try:
                s = json.loads(status.read_text())
                if all(p["phase"] == "running" for p in s["processes"]):
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(1.0)
        else:
            print((work / "launcher.log").read_text())
            sys.exit("the city did not come up")
        url = (work / "run" / "dashboard.url").read_text().strip()
        pid = next(p["pid"] for p in json.loads(status.read_text())["processes"]
                   if p["name"] == "dashboard")
        print(f"city up; dashboard {url} (pid {pid})", flush=True)

        options = Options()
        options.binary_location = "/usr/bin/chromium"
        for a in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                  "--window-size=1600,1000"]:
            options.add_argument(a)
        for i in range(args.browsers):
            options.arguments[:] = [a for a in options.arguments if "user-data-dir" not in a]
            options.add_argument(f"--user-data-dir={work / f'chromium{i}'}")
            d = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
            d.set_script_timeout(60)
            d.get(url)
            drivers.append(d)
        # Discovery of a big city's thousands of endpoints takes a while, and each head's last
        # lamp reaches the dashboard as history when its reader is matched (with an old
        # source time: not an update). Measure once the dashboard has heard every head.
        def metrics():
            return json.loads(urllib.request.urlopen(url + "api/metrics", timeout=30).read())

        heads = 4 * intersections
        start = time.monotonic()
        heard = metrics()["lamps_known"]
        while heard < heads and time.monotonic() - start < args.discovery:
            time.sleep(2.0)
            heard = metrics()["lamps_known"]
        print(f"the dashboard heard {heard} of {heads} heads {time.monotonic() - start:.0f} s "
              "after the page opened" + ("" if heard == heads else
                                         " (measuring all the same: --discovery)"), flush=True)
        for d in drivers:
            end = time.monotonic() + 120
            while time.monotonic() < end and not d.execute_script(
                    "return !!(window.dashboard && window.dashboard.stateReceived)"):
                time.sleep(0.5)
        time.sleep(args.warmup)

        # A plain stream reader beside the browsers: the latency to the socket, without a page.
        raw = {}
        raw_stop = threading.Event()

        def read_raw():
            with urllib.request.urlopen(url + "api/stream", timeout=60) as stream:
                event = None
                for line in stream:
                    if raw_stop.is_set():
                        return
                    line = line.decode()
                    if line.startswith("event: "):
                        event = line[7:].strip()
                    elif line.startswith("data: ") and event in ("lamps", "spat", "traffic",
                                                                  "fleet"):
                        rx = json.loads(line[6:]).get("rx")
                        if rx:
                            raw.setdefault(event, []).append(time.time() * 1000.0 - rx)

        raw_thread = threading.Thread(target=read_raw, daemon=True)
        raw_thread.start()

        for d in drivers:
            d.execute_script("for (const k in window.dashboard.latencies) "
                             "window.dashboard.latencies[k].length = 0;")
        # Every process of the city, and the browsers, for the host's load beside the figures.
        procs = {p["name"]: p["pid"] for p in json.loads(status.read_text())["processes"]}

        def chromium_pids():
            out = subprocess.run(["pgrep", "-f", f"user-data-dir={work}"], capture_output=True,
                                 text=True).stdout
            return [int(x) for x in out.split()]

        def host_cpu():
            cpu = {}
            for name, p in procs.items():
                try:
                    cpu[name] = cpu_seconds(p)
                except OSError:
                    pass
            total = 0.0
            for p in chromium_pids():
                try:
                    total += cpu_seconds(p)
                except OSError:
                    pass
            cpu["chromium"] = total
            return cpu

        h0, d0 = host_cpu(), udp_drops(pid)
        m0, c0, t0 = metrics(), cpu_seconds(pid), time.monotonic()
        lat = {}
        # The page keeps the last 1,000 per stream: collect every few seconds.
        while time.monotonic() - t0 < args.seconds:
            time.sleep(min(5.0, args.seconds - (time.monotonic() - t0)))
            for d in drivers:
                got = d.execute_script("""
                  const out = {};
                  for (const k of ['lamps', 'spat', 'traffic', 'fleet']) {
                    out[k] = (window.dashboard.latencies[k] || []).slice();
                    if (window.dashboard.latencies[k]) window.dashboard.latencies[k].length = 0;
                  }
                  return out;""")
                for k, v in got.items():
                    lat.setdefault(k, []).extend(v)
        m1, c1, t1 = metrics(), cpu_seconds(pid), time.monotonic()
        h1, d1 = host_cpu(), udp_drops(pid)
        raw_stop.set()
        handler_ms = drivers[0].execute_script("return window.dashboard.handlerMs || {};")
        dt = t1 - t0
        cpu = 100.0 * (c1 - c0) / dt
        per_browser = (m1["bytes_out"] - m0["bytes_out"]) / dt / max(1, m1["subscribers"])
        every = [x for v in lat.values() for x in v]
        print(f"measured {dt:.0f} s with {len(drivers)} browser(s), {m1['dropped']} dropped")
        # A city in fail-safe flash is not the city to measure: say so.
        state = json.loads(urllib.request.urlopen(url + "api/state", timeout=60).read())
        latched = [x for x in state.get("intersections", []) if x.get("latched")]
        print(f"intersections latched in fail-safe flash: {len(latched)} of {intersections}" +
              (f" (first: {latched[0].get('name')}: {latched[0].get('latched')})" if latched
               else ""))
        print(f"dashboard CPU: {cpu:.1f}% of one core (goal <= 10%)")
        load = {k: 100.0 * (h1[k] - h0[k]) / dt for k in h1 if k in h0}
        print(f"host ({os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}), % of one "
              "core: " + ", ".join(f"{k} {v:.0f}" for k, v in
                                   sorted(load.items(), key=lambda kv: -kv[1])) +
              f"; all {sum(load.values()):.0f}")
        print(f"dashboard's DDS sockets: {(d1 - d0) / dt:.0f} datagrams/s dropped (receive "
              "buffer full: the host cannot give it the CPU to keep up)" if d1 > d0 else
              "dashboard's DDS sockets: no datagram dropped")
        print(f"stream: {per_browser / 1000:.1f} kB/s per browser, "
              f"{(m1['messages'] - m0['messages']) / dt:.0f} messages/s")
        for k in ["lamps", "spat", "traffic", "fleet"]:
            v = lat.get(k, [])
            if v:
                print(f"latency DDS sample -> page, {k:7s}: n={len(v):6d} p50 {percentile(v, 0.5):6.1f} "
                      f"ms  p99 {percentile(v, 0.99):6.1f} ms  max {max(v):6.1f} ms")
        busy = sum(h[1] for h in handler_ms.values())
        print(f"page: {busy / 1000.0:.1f} s in message handlers since it opened; per message: " +
              ", ".join(f"{k} {h[1] / max(1, h[0]):.1f} ms (max {h[2]:.0f})"
                        for k, h in sorted(handler_ms.items()) if h[0]))
        raw_all = [x for v in raw.values() for x in v]
        print(f"latency DDS sample -> socket (a plain stream reader, no page): n={len(raw_all)} "
              f"p50 {percentile(raw_all, 0.5):.1f} ms  p99 {percentile(raw_all, 0.99):.1f} ms")
        print(f"latency DDS sample -> page, all    : n={len(every):6d} p50 "
              f"{percentile(every, 0.5):6.1f} ms  p99 {percentile(every, 0.99):6.1f} ms "
              f"(goal p99 <= 100 ms)", flush=True)
    finally:
        for d in drivers:
            d.quit()
        if launcher.poll() is None:
            launcher.send_signal(signal.SIGINT)
            try:
                launcher.wait(180)
            except subprocess.TimeoutExpired:
                launcher.kill()
        if not args.keep:
            subprocess.run(["rm", "-rf", str(work)])


if __name__ == "__main__":
    main()
