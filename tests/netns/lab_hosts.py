#!/usr/bin/python3
"""One city spread over three hosts in network namespaces by its launch section (issue 36):
`launch.hosts` puts the SCM on `server` (A), the lights on `track` (B) and the simulator and its
driver on `sim_pc` (C), and each host runs `autodrive-city up CITY --host NAME`, with
config/dds/lab.xml.

Checks: `install-units` writes one systemd unit per host, each starting that host's share; each
host's launcher starts its share only, with its own status and pid files in the shared run
folder; the SCM runs its plans with the lights of another host; the SCM knows each launcher by
its host name: the lights killed on `track` are logged by the SCM as exited and restarted there;
`down --host` stops one share and leaves the others up.

Skips (exit 77) where namespaces cannot be made (not root, no `ip`). Exit status 1 on a failure.
"""

import argparse
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time

sys.dont_write_bytecode = True  # nothing written into the source tree
HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import netns  # noqa: E402

HOSTS = {"server": ("a", ["scm"]), "track": ("b", ["lights"]), "sim_pc": ("c", ["sim", "driver"])}
NORMAL_STAGES = ("green", "yellow", "red_clearance")


def fail(message):
    print(f"lab_hosts: FAILED: {message}", flush=True)
    sys.exit(1)


def wait_for(what, condition, deadline_s):
    """Polls `condition` until it returns a true value, within a generous deadline."""
    value = netns.poll(condition, deadline_s, 0.2)
    if value is None:
        fail(f"{what}: not within {deadline_s:g} s")
    return value


def city_file(source, tmp):
    """The small town with a launch section spreading it over HOSTS."""
    text = (source / "config/cities/small_town.yaml").read_text()
    text = text.replace("../maps/", f"{source}/config/maps/") \
        .replace("../cameras/", f"{source}/config/cameras/")
    if "\nlaunch:" in text:
        fail("small_town.yaml has a launch section: this test writes its own")
    hosts = "".join(f"    {h}: [{', '.join(names)}]\n" for h, (_, names) in HOSTS.items())
    text += (f"\nlaunch:\n  run_dir: {tmp / 'run'}\n"
             f"  lights: {{config: {source}/config/infra/small_town.yaml}}\n"
             "  sim: {mode: on}\n  driver: {mode: on}\n  traffic: {mode: off}\n"
             "  eye: {mode: off}\n  dashboard: {mode: off}\n"
             f"  hosts:\n{hosts}")
    path = tmp / "small_town_hosts.yaml"
    path.write_text(text)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=pathlib.Path, required=True)
    parser.add_argument("--bin", type=pathlib.Path, required=True)
    args = parser.parse_args()
    reason = netns.skip_reason()
    if reason:
        print(f"lab_hosts: skipped: {reason}")
        sys.exit(77)
    city_bin = str(args.bin / "autodrive-city")

    with tempfile.TemporaryDirectory(prefix="lab_hosts.") as tmp:
        tmp = pathlib.Path(tmp)
        city = city_file(args.source, tmp)
        partition = f"lab_hosts_{os.getpid()}"
        env = dict(os.environ)
        env["CYCLONEDDS_URI"] = f"file://{args.source}/config/dds/lab.xml"
        env.pop("AUTODRIVE_PROCESS_NAME", None)

        # One systemd unit per host, each starting that host's share.
        units = tmp / "units"
        out = subprocess.run([city_bin, "install-units", str(city), "--out", str(units),
                              "--dds-config", "/etc/autodrive/dds/lab.xml"],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if out.returncode != 0:
            fail(f"install-units: {out.stdout}")
        for host in HOSTS:
            unit = units / f"autodrive-city-small_town-{host}.service"
            if not unit.exists():
                fail(f"install-units wrote {sorted(p.name for p in units.iterdir())}, not {unit.name}")
            if f"up {city} --host {host}\n" not in unit.read_text():
                fail(f"{unit.name} does not start host {host}'s share:\n{unit.read_text()}")
        print(f"install-units: {len(HOSTS)} units, one per host", flush=True)

        def status(host):
            run = subprocess.run([city_bin, "status", str(city), "--host", host, "--json"],
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
            try:
                return json.loads(run.stdout) if run.stdout.strip() else None
            except json.JSONDecodeError:
                return None

        def share_up(host):
            s = status(host)
            return s is not None and s.get("up") and s.get("host") == host and all(
                p["phase"] == "running" for p in s["processes"]) and sorted(
                p["name"] for p in s["processes"]) == sorted(HOSTS[host][1])

        with netns.Lab([ns for ns, _ in HOSTS.values()]) as lab:
            print(f"hosts: {lab.address}", flush=True)
            launchers = {}
            logs = []
            try:
                for host, (ns, _) in HOSTS.items():
                    log = open(tmp / f"launcher_{host}.log", "w")
                    logs.append(log)
                    launchers[host] = lab.run(ns, [city_bin, "up", str(city), "--host", host,
                                                   "--partition", partition],
                                              env=env, stdout=log, stderr=subprocess.STDOUT)
                for host in HOSTS:
                    wait_for(f"host {host}'s share up", lambda h=host: share_up(h), 180)
                print("each host's launcher runs its share only: "
                      + ", ".join(f"{h}: {HOSTS[h][1]}" for h in HOSTS), flush=True)
                for host in HOSTS:
                    for name in ("status-{}.json", "launcher-{}.pid"):
                        if not (tmp / "run" / name.format(host)).exists():
                            fail(f"no {name.format(host)} in the run folder")

                def scmctl(*command):
                    run = lab.run("a", [str(args.bin / "scmctl"), "--partition", partition,
                                        "--json", "--timeout", "3", *command], env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
                    text = run.communicate(timeout=60)[0]
                    return json.loads(text.splitlines()[-1]) if run.returncode == 0 else None

                def running():
                    xs = scmctl("intersections")
                    return xs is not None and all(
                        x["latched"] is None and x["stage"] in NORMAL_STAGES
                        for x in xs["values"].values())
                wait_for("the SCM on server running its plans with track's lights", running, 120)
                print("the SCM runs every plan with the lights of another host", flush=True)

                # The lights killed on track: track's launcher starts them again, and the SCM
                # logs both, naming the host.
                since = time.time()
                lights_pid = next(p["pid"] for p in status("track")["processes"]
                                  if p["name"] == "lights")
                os.kill(lights_pid, signal.SIGKILL)

                def logged():
                    answer = scmctl("events", "--since", f"{since:.3f}", "--limit", "1000")
                    events = list(answer["values"].values()) if answer else []
                    exited = [e for e in events if e["code"] == "process_exited"
                              and e["device"] == "process/lights"]
                    back = [e for e in events if e["code"] == "process_restarted"
                            and e["device"] == "process/lights"]
                    return (exited, back) if exited and back else None
                exited, back = wait_for("the SCM logging the lights' exit and return", logged, 60)
                if "track" not in exited[0]["message"]:
                    fail(f"the SCM's process_exited does not name host track: {exited[0]}")
                print(f"SCM: {exited[0]['message']}; {back[0]['message']}", flush=True)
                wait_for("the SCM running its plans again", running, 120)

                # One share down, the others up.
                down = subprocess.run([city_bin, "down", str(city), "--host", "sim_pc"],
                                      stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                      timeout=180)
                if down.returncode != 0:
                    fail(f"down --host sim_pc: {down.stdout}")
                if launchers["sim_pc"].wait(timeout=60) != 0:
                    fail(f"sim_pc's launcher exited {launchers['sim_pc'].returncode}")
                for host in ("server", "track"):
                    if not share_up(host):
                        fail(f"host {host}'s share went down with sim_pc's: {status(host)}")
                print("down --host sim_pc stopped that share only", flush=True)
            finally:
                for p in launchers.values():
                    if p.poll() is None:
                        p.send_signal(signal.SIGINT)
                for p in launchers.values():
                    try:
                        p.wait(timeout=120)
                    except subprocess.TimeoutExpired:
                        p.kill()
                        p.wait()
                for log in logs:
                    log.close()
    print("lab_hosts: OK")


if __name__ == "__main__":
    main()
