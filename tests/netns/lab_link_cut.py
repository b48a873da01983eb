#!/usr/bin/python3
"""Link cuts in a lab of hosts in network namespaces (issue 36): the SCM on A, the lights of the
small town's north_t on B and those of its centre on C (two light hosts), all with
config/dds/lab.xml.

Default: B's link is cut (the switch's port down) and healed, --cycles times. In each cycle B's
lights must flash on their own within 1.0 s of the cut (their DeviceStatus mode FLASH, recorded
on B by a recorder there), the SCM must log `device_lost` for them within 1.0 s, C's intersection
must run on untouched, and within 5 s of the heal B's lights must follow the SCM again (mode
NORMAL) and the SCM must have ended the flash on its own (`failsafe_recovered`), the intersection
going through start-up.

--cut-scm: A's link is cut instead: every light host's lights must flash within 1.0 s; A's SCM is
then stopped (the host is gone) and an SCM started on D from the same database; the city must
come back through start-up, its event log going on from A's.

Throughout, 0 conflicting greens: the SCM's monitor counts no violation, no light host's
monitor (mmu_<intersection> DeviceStatus) latches, and in the lamp states recorded on each light
host no two heads of one intersection show green or yellow at the same time (on the shipped
four-ways and T-junctions every two heads conflict: docs/infrastructure.md). The recordings are
read back by npm's @mcap/core and decoded by @foxglove/rosmsg2-serialization (check_mcap.mjs).

Skips (exit 77) where namespaces cannot be made (not root, no `ip`). Exit status 1 on a failure.
"""

import argparse
import contextlib
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

CITY = "config/cities/small_town.yaml"
INFRA = "config/infra/small_town.yaml"
# The small town's heads by intersection (config/infra/small_town.yaml) and the light host of each.
HEADS = {"north_t": [1, 2, 3], "centre": [4, 5, 6, 7]}
LIGHT_HOST = {"b": "north_t", "c": "centre"}
FLASH_MODE = 1   # DeviceStatus mode FLASH: the head's own fail-safe flash
FAULT = 2        # DeviceStatus health FAULT
GO = (2, 3)      # signal_<i>/state: yellow, green
NORMAL_STAGES = ("green", "yellow", "red_clearance")
CUT_S = 3.0


def fail(message):
    print(f"lab_link_cut: FAILED: {message}", flush=True)
    sys.exit(1)


def wait_for(what, condition, deadline_s):
    """Polls `condition` until it returns a true value, within a generous deadline."""
    value = netns.poll(condition, deadline_s, 0.1)
    if value is None:
        fail(f"{what}: not within {deadline_s:g} s")
    return value


class Lab:
    """The hosts, the processes on them, and scmctl towards the running SCM."""

    def __init__(self, args, lab, tmp, partition, env):
        self.args, self.lab, self.tmp, self.partition, self.env = args, lab, tmp, partition, env
        self.processes = {}
        self.logs = []
        self.scm_host = "a"

    def start(self, name, host, argv):
        log = open(self.tmp / f"{name}.log", "a")
        self.logs.append(log)
        self.processes[name] = self.lab.run(host, argv, env=self.env, stdout=log,
                                            stderr=subprocess.STDOUT)

    def start_scm(self, host):
        self.scm_host = host
        self.start(f"scm_{host}", host, [
            str(self.args.bin / "autodrive-scm"), "--config", str(self.args.source / CITY),
            "--db", str(self.tmp / "scm.db"), "--partition", self.partition])

    def scmctl(self, *command):
        run = self.lab.run(self.scm_host, [
            str(self.args.bin / "scmctl"), "--partition", self.partition, "--json",
            "--timeout", "3", *command], env=self.env, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, text=True)
        out = run.communicate(timeout=60)[0]
        try:
            return json.loads(out.splitlines()[-1]) if run.returncode == 0 else None
        except (json.JSONDecodeError, IndexError):
            return None

    def intersections(self):
        answer = self.scmctl("intersections")
        return answer["values"] if answer else None

    def running(self, names):
        """True when every intersection in `names` runs its plan (not latched, out of
        start-up)."""
        xs = self.intersections()
        return xs is not None and all(
            xs[n]["latched"] is None and xs[n]["stage"] in NORMAL_STAGES for n in names)

    def events(self, since):
        answer = self.scmctl("events", "--since", f"{since:.3f}", "--limit", "10000")
        return list(answer["values"].values()) if answer else []

    def stop(self, name, sig=signal.SIGINT):
        p = self.processes.get(name)
        if p is None or p.poll() is not None:
            return
        p.send_signal(sig)
        try:
            p.wait(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()

    def stop_all(self):
        for name in reversed(list(self.processes)):
            self.stop(name)
        for log in self.logs:
            log.close()


def light_config(source, tmp, host):
    """The small town's light host file for the heads of one intersection, as host `host`."""
    text = (source / INFRA).read_text()
    heads = HEADS[LIGHT_HOST[host]]
    replaced = text.replace("name: small_town_lights", f"name: small_town_lights_{host}") \
        .replace("map: ../maps/small_town.yaml", f"map: {source}/config/maps/small_town.yaml") \
        .replace("heads: [1, 2, 3, 4, 5, 6, 7]", f"heads: {heads}")
    if replaced.count(f"small_town_lights_{host}") != 1 or f"heads: {heads}" not in replaced \
            or str(source) not in replaced:
        fail(f"{INFRA} is not as this test expects (name, map, heads lines)")
    path = tmp / f"lights_{host}.yaml"
    path.write_text(replaced)
    return path


def read_recording(args, path, tmp):
    """[(topic, publish_ns, message)] of a light host's recording, read by npm's libraries."""
    out = tmp / (path.stem + ".values.jsonl")
    run = subprocess.run([args.node, str(args.npm_dir / "check_mcap.mjs"), str(path), "--values",
                          str(out)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         timeout=600)
    if run.returncode != 0:
        fail(f"check_mcap.mjs {path.name}: {run.stdout[-3000:]}")
    rows = [json.loads(line) for line in out.read_text().splitlines() if line]
    return sorted(((r["topic"], r["publish"], r["message"]) for r in rows), key=lambda r: r[1])


def check_recording(host, rows):
    """0 conflicting greens in a light host's recording and its monitor never latched; returns
    the statuses of its own heads: {head: [(publish_ns, mode, health)]}."""
    heads = HEADS[LIGHT_HOST[host]]
    go = {}  # head -> whether it shows go now
    conflicts = []
    statuses = {h: [] for h in heads}
    for topic, stamp, message in rows:
        if topic.endswith("/state"):
            head = int(topic.split("signal_")[1].split("/")[0])
            if head not in heads:
                continue
            go[head] = message["data"] in GO
            showing = sorted(h for h, g in go.items() if g)
            if len(showing) > 1:
                conflicts.append((stamp, showing))
        elif topic == "/autodrive/scm/devices" and message["host"] == f"infra/small_town_lights_{host}":
            device = message["device_id"]
            if device.startswith("mmu_") and message["health"] == FAULT:
                fail(f"{device} on {host} latched: {message['detail']}")
            if device.startswith("signal_"):
                head = int(device[len("signal_"):])
                statuses[head].append((stamp, message["mode"], message["health"]))
    if conflicts:
        fail(f"conflicting greens on {host}: {conflicts[:5]}")
    states = sum(1 for t, _, _ in rows if t.endswith("/state"))
    print(f"{host}: {states} lamp states, {sum(len(s) for s in statuses.values())} statuses of "
          f"its heads, 0 conflicting greens, its monitor never latched", flush=True)
    return statuses


def first_after(series, t_ns, predicate):
    for stamp, mode, health in series:
        if stamp >= t_ns and predicate(mode, health):
            return stamp
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=pathlib.Path, required=True)
    parser.add_argument("--bin", type=pathlib.Path, required=True)
    parser.add_argument("--npm-dir", type=pathlib.Path, required=True,
                        help="the installed npm checks (tests/ros2/npm.cmake)")
    parser.add_argument("--node", default="node")
    parser.add_argument("--cycles", type=int, default=10, help="cuts of B's link")
    parser.add_argument("--cut-scm", action="store_true",
                        help="cut A's link and restart the SCM on D from the same database")
    parser.add_argument("--keep", action="store_true",
                        help="keep the run's folder (logs, recordings) and print its path")
    args = parser.parse_args()
    reason = netns.skip_reason()
    if reason:
        print(f"lab_link_cut: skipped: {reason}")
        sys.exit(77)

    folder = contextlib.nullcontext(tempfile.mkdtemp(prefix="lab_link_cut.")) if args.keep \
        else tempfile.TemporaryDirectory(prefix="lab_link_cut.")
    with folder as tmp:
        if args.keep:
            print(f"files in {tmp}", flush=True)
        tmp = pathlib.Path(tmp)
        partition = f"lab_link_cut_{os.getpid()}"
        env = dict(os.environ)
        env["CYCLONEDDS_URI"] = f"file://{args.source}/config/dds/lab.xml"
        env.pop("AUTODRIVE_PROCESS_NAME", None)
        hosts = ["a", "b", "c", "d"] if args.cut_scm else ["a", "b", "c"]
        with netns.Lab(hosts) as net:
            print(f"hosts: {net.address}", flush=True)
            lab = Lab(args, net, tmp, partition, env)
            try:
                for host in LIGHT_HOST:
                    # The recorder first: it sees each head from its first state.
                    lab.start(f"record_{host}", host, [
                        str(args.bin / "autodrive-record"), "record", "-o",
                        str(tmp / f"lights_{host}.mcap"), "--topics", "/autodrive/signal_*/state",
                        "/autodrive/scm/devices", "--partition", partition])
                for host in LIGHT_HOST:
                    lab.start(f"lights_{host}", host, [
                        str(args.bin / "autodrive-infra"), "--config",
                        str(light_config(args.source, tmp, host)), "--partition", partition])
                lab.start_scm("a")
                wait_for("the city running its plans", lambda: lab.running(HEADS), 120)
                results = run_scm_cut(lab, net) if args.cut_scm else run_light_cuts(lab, net)
                status = lab.scmctl("status")
                violations = status["values"]["monitor_violations"] if status else None
                for name, p in lab.processes.items():
                    if p.poll() is not None and not name.startswith("scm_a"):
                        fail(f"{name} exited {p.returncode}")
            finally:
                lab.stop_all()
        if violations != 0:
            fail(f"the SCM's conflict monitor counted {violations} violations")
        print("SCM: 0 monitor violations", flush=True)
        statuses = {h: check_recording(h, read_recording(args, tmp / f"lights_{h}.mcap", tmp))
                    for h in LIGHT_HOST}
        check_flashes(statuses, results)
    print("lab_link_cut: OK")


def run_light_cuts(lab, net):
    """Cuts B's link `--cycles` times; returns the cuts: [{cut, heal, scm events}]."""
    cuts = []
    for cycle in range(1, lab.args.cycles + 1):
        wait_for(f"cycle {cycle}: the city running its plans", lambda: lab.running(HEADS), 60)
        since = time.time()
        cut = time.time_ns()
        net.link("b", False)
        # C's intersection runs on untouched while B is away.
        end = time.monotonic() + CUT_S
        while time.monotonic() < end:
            xs = lab.intersections()
            if xs is not None and xs["centre"]["latched"] is not None:
                fail(f"cycle {cycle}: centre latched while B was cut: {xs['centre']['latched']}")
            time.sleep(0.2)
        heal = time.time_ns()
        net.link("b", True)
        def recovered_events():
            events = lab.events(since)
            for e in events:
                if e["code"] == "failsafe_recovery_exhausted":
                    fail(f"cycle {cycle}: {e['message']}")
            return [e for e in events if e["code"] == "failsafe_recovered"]
        recovered = wait_for(f"cycle {cycle}: north_t back from its flash", recovered_events, 30)
        wait_for(f"cycle {cycle}: north_t running its plan again", lambda: lab.running(HEADS),
                 60)
        events = lab.events(since)
        lost = [e for e in events if e["code"] == "device_lost"]
        lost_devices = sorted(e["device"] for e in lost)
        expected = [f"signal_{h}" for h in HEADS["north_t"]]
        if lost_devices != expected:
            fail(f"cycle {cycle}: the SCM reported lost {lost_devices}, expected {expected}")
        lost_s = max(e["stamp"] for e in lost) - cut / 1e9
        back_s = max(e["stamp"] for e in events if e["code"] == "device_back") - heal / 1e9
        recovered_s = recovered[0]["stamp"] - heal / 1e9
        print(f"cycle {cycle}: SCM device_lost {lost_s:.3f} s after the cut, device_back "
              f"{back_s:.3f} s and failsafe_recovered {recovered_s:.3f} s after the heal",
              flush=True)
        if lost_s > 1.0:
            fail(f"cycle {cycle}: the SCM reported the lights lost {lost_s:.3f} s after the cut")
        if recovered_s > 5.0:
            fail(f"cycle {cycle}: the SCM ended the flash {recovered_s:.3f} s after the heal")
        cuts.append({"cycle": cycle, "cut": cut, "heal": heal, "hosts": ["b"],
                     "back": "after the heal", "limit_s": 5.0})
    return cuts


def run_scm_cut(lab, net):
    """Cuts A's link, restarts the SCM on D from the same database; returns the cut."""
    before = lab.events(0)
    last_id = max(e["id"] for e in before)
    cut = time.time_ns()
    net.link("a", False)
    time.sleep(CUT_S)
    # A is gone: its SCM stops (a host that lost its network for good is fenced before the
    # SCM moves), and the SCM starts on D from the same database.
    lab.stop("scm_a", signal.SIGKILL)
    restart = time.time_ns()
    lab.start_scm("d")
    wait_for("the city running its plans under the SCM on D", lambda: lab.running(HEADS), 120)
    back_s = (time.time_ns() - restart) / 1e9
    started = [e for e in lab.events(restart / 1e9 - 1) if e["code"] == "scm_started"]
    if not started or started[-1]["id"] <= last_id:
        fail(f"the SCM on D did not go on from A's event log (A's last id {last_id}, "
             f"D's start: {started})")
    print(f"SCM on D: running every plan {back_s:.2f} s after it was started; its event log "
          f"goes on from A's (A's last id {last_id}, D's scm_started id {started[-1]['id']})",
          flush=True)
    return [{"cycle": 1, "cut": cut, "heal": restart, "hosts": list(LIGHT_HOST),
             "back": "after the SCM on D started", "limit_s": 120}]


def check_flashes(statuses, cuts):
    """Each cut host's lights flashed on their own within 1.0 s of the cut, and followed the SCM
    again within the cut's limit after the heal (or after the SCM started on D)."""
    for c in cuts:
        for host in c["hosts"]:
            for head, series in statuses[host].items():
                flash = first_after(series, c["cut"], lambda mode, health: mode == FLASH_MODE)
                if flash is None:
                    fail(f"cycle {c['cycle']}: signal_{head} on {host} never flashed after the cut")
                flash_s = (flash - c["cut"]) / 1e9
                line = f"cycle {c['cycle']}: signal_{head} on {host} flashing {flash_s:.3f} s " \
                       f"after the cut"
                if flash_s > 1.0:
                    fail(line)
                back = first_after(series, c["heal"], lambda mode, health: mode != FLASH_MODE)
                if back is None:
                    fail(f"cycle {c['cycle']}: signal_{head} never followed the SCM again")
                back_s = (back - c["heal"]) / 1e9
                line += f", following the SCM {back_s:.3f} s {c['back']}"
                if back_s > c["limit_s"]:
                    fail(line)
                print(line, flush=True)


if __name__ == "__main__":
    main()
