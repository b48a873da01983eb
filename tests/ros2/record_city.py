#!/usr/bin/python3
"""autodrive-record on the default city, checked with npm's MCAP and ROS 2 decoders and an
independent subscriber (issue 35).

Brings up the default city (config/cities/small_town.yaml, autodrive-city up in its own DDS
partition and run folder) and records it twice at once: one recorder stops by itself
(`--duration`), the other by SIGTERM once the first is done. Meanwhile count_probe.c (Cyclone's C
API only: topics from DCPSPublication, types idlc made from rosidl's derived IDL, every sample
taken raw) notes
the source time of every sample of every topic. Then, with the city down:
  - `autodrive-record info` reads both files (profile ros2);
  - check_mcap.mjs (@mcap/core indexed and streamed with CRCs, @foxglove/rosmsg2-serialization
    decoding every message with its channel's schema) passes on both, with SPaT at 10 +- 0.5 Hz
    and the latched MAP present; and fails on a copy with one byte flipped in a chunk;
  - over the same window of source time, each topic's recorded count is within 0.5% of the
    probe's (no camera topic unless --cameras, then the overhead camera's frames too), and every
    topic the probe saw is recorded;
  - the SCM counted no write failure while recorded (`scmctl status`);
  - `autodrive-record play` of the first file into a fresh partition, recorded there by a third
    recorder, delivers every topic's recorded count again with byte-identical payloads, each
    topic offered with the recorded reliability and durability (latched ones transient-local);
  - the city's own `--record` file (autodrive-city up --record) passes the same MCAP checks.
With --measure the probe and the SIGTERM recorder run --seconds before the timed recorder
starts, and it prints the SCM's loop percentiles over that minute and over the recorded one, and
the timed recorder's CPU (figures, not checks: docs/recording.md).
Exit status 1 on any failure.
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
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import city_run  # noqa: E402
import count_probe  # noqa: E402
from city_run import (add_arguments, city_environment, cpu_seconds, proc_stat,  # noqa: E402
                      start_city, stop)
SPAT = "/autodrive/scm/spat"
MAP = "/autodrive/scm/map"


def fail(message):
    print(f"record_city: FAILED: {message}", flush=True)
    sys.exit(1)


def wait_for(path, text, process, seconds, what):
    deadline = time.monotonic() + seconds
    while text not in path.read_text(errors="replace"):
        if process.poll() is not None or time.monotonic() > deadline:
            print(path.read_text(errors="replace")[-3000:])
            fail(what)
        time.sleep(0.2)


def check(args, env, mcap, expect, flip=False, times=None):
    command = [args.node, str(args.npm / "check_mcap.mjs"), str(mcap)]
    for topic, count in expect:
        command += ["--expect", f"{topic}:{count}"]
    if flip:
        command += ["--flip-byte", "middle"]
    if times:
        command += ["--times", str(times)]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=1800)


def build_probe(args, work):
    try:
        return count_probe.build(args.source, args.ros2_work, args.idlc, args.cc, work)
    except RuntimeError as e:
        fail(str(e))


def scm_status(args, env, partition):
    status = city_run.scm_status(args, env, partition)
    if isinstance(status, str):
        fail(status)
    return status


def compare_with_probe(probe_file, times_file, cameras):
    """Each topic's recorded count against the probe's over the same window of source time."""
    recorded = {}
    for line in times_file.read_text().splitlines():
        t = json.loads(line)
        recorded[t["topic"]] = t
    logs = [x for t in recorded.values() for x in t["log"]]
    # The window: from 2 s after the recorder's first message (it finds topics within 200 ms of
    # starting; 2 s leaves room for a loaded machine) to 0.5 s before its last, in source time;
    # the probe covered all of it.
    start, end = min(logs) + 2_000_000_000, max(logs) - 500_000_000
    probe_seen = {}
    for line in probe_file.read_text().splitlines():
        p = json.loads(line)
        name = "/" + p["topic"][3:] if p["topic"].startswith("rt/") else None
        if name is None:
            continue  # not a ROS topic (ros_discovery_info): ROS tools do not record it
        probe_seen[name] = p
        if p["since"] > start:
            fail(f"the probe subscribed to {name} only after the window began")
    failures, rows, total_rec, total_probe = [], [], 0, 0
    for name, p in sorted(probe_seen.items()):
        n_probe = sum(1 for x in p["stamps"] if start <= x <= end)
        if name not in recorded:
            # Cameras: none without --cameras; with it, the overhead camera's frames only.
            if "Image" in p["type"] and (not cameras or name.endswith("/debug_image")):
                continue
            if n_probe:
                failures.append(f"{name}: {n_probe} samples in the window, not recorded")
            continue
        n_rec = sum(1 for x in recorded[name]["publish"] if start <= x <= end)
        total_rec += n_rec
        total_probe += n_probe
        rows.append((name, n_probe, n_rec, p["lost"]))
        if abs(n_rec - n_probe) > int(0.005 * n_probe):
            failures.append(f"{name}: recorded {n_rec}, the probe {n_probe} (more than 0.5% apart)")
    print(f"--- counts over {(end - start) / 1e9:.2f} s of source time "
          f"(topic, the probe's count, recorded; the samples DDS told the probe it lost):")
    for name, n_probe, n_rec, lost in rows:
        print(f"  {name:55s} {n_probe:8d} {n_rec:8d}{f'  (probe lost {lost})' if lost else ''}"
              f"{'' if n_probe == n_rec else '  <-'}")
    print(f"  {'total':55s} {total_probe:8d} {total_rec:8d}", flush=True)
    if failures:
        fail("; ".join(failures))
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(parser)
    parser.add_argument("--seconds", type=float, default=8.0, help="how long to record")
    parser.add_argument("--cameras", action="store_true",
                        help="record the overhead camera's frames too (about 90 MB/s)")
    parser.add_argument("--rate", type=float, default=4.0, help="playback rate")
    parser.add_argument("--measure", action="store_true",
                        help="print the SCM's loop and the recorder's CPU (runs the city "
                        "--seconds without the timed recorder first)")
    parser.add_argument("--baselines", type=int, default=1,
                        help="with --measure: baseline minutes before the recorder starts, each "
                        "printed (the figures' own noise)")
    args = parser.parse_args()
    record = str(args.bin / "autodrive-record")

    with tempfile.TemporaryDirectory(prefix="record_city.", dir=args.work) as tmp:
        tmp = pathlib.Path(tmp)
        probe = build_probe(args, tmp)
        partition = f"record_city_{os.getpid()}"
        env = city_environment(tmp)
        city_log = tmp / "city.log"
        with open(city_log, "w") as log:
            city = start_city(args, env, partition, log, ["--record", str(tmp / "city.mcap")])
            try:
                wait_for(city_log, "is up.", city, 300, "the city did not come up")
                probe_out = tmp / "probe.jsonl"
                listen = (args.baselines + 1) * args.seconds + 90 if args.measure \
                    else args.seconds + 30
                probe_run = subprocess.Popen(
                    [str(probe), partition, f"{listen:g}", str(probe_out)]
                    + (["--cameras"] if args.cameras else []),
                    env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                # The probe reads every topic before the recorders start.
                ready = probe_run.stdout.readline()
                if "reading" not in ready:
                    fail(f"count_probe (exit {probe_run.poll()}): {ready}{probe_run.stdout.read()}")
                timed_log, term_log = tmp / "timed.log", tmp / "term.log"
                cameras = ["--cameras", "--exclude", "*/debug_image"] if args.cameras else []
                with open(timed_log, "w") as tl, open(term_log, "w") as ml:
                    term = subprocess.Popen(
                        [record, "--log-level", "info", "record", "--partition", partition,
                         "-o", str(tmp / "term.mcap")], env=env, stdout=ml,
                        stderr=subprocess.STDOUT)
                    for window in range(args.baselines if args.measure else 0):
                        # The baseline: the city with the probe and the other recorders, for
                        # the SCM's loop window (its last 3,000 passes, about a minute). More
                        # than one show how much the figures move from one minute to the next
                        # with nothing changed.
                        print(f"city up; {args.seconds:g} s with the probe and the SIGTERM "
                              "recorder before the timed recorder starts", flush=True)
                        time.sleep(args.seconds)  # the measurement's window, not a wait
                        if window + 1 < args.baselines:
                            city_run.print_scm(f"the SCM, baseline {window + 1}:",
                                      scm_status(args, env, partition))
                    before = scm_status(args, env, partition)
                    print(f"city up in partition {partition}; recording {args.seconds:g} s",
                          flush=True)
                    timed = subprocess.Popen(
                        [record, "--log-level", "info", "record", "--partition", partition,
                         "--duration", f"{args.seconds:g}", "-o", str(tmp / "timed.mcap")]
                        + cameras, env=env, stdout=tl, stderr=subprocess.STDOUT)
                    cpu0, wall0 = cpu_seconds(timed.pid), time.monotonic()
                    niceness = None
                    cpu1, wall1 = cpu0, wall0
                    deadline = time.monotonic() + args.seconds + 120
                    while timed.poll() is None and time.monotonic() < deadline:
                        try:
                            cpu1, wall1 = cpu_seconds(timed.pid), time.monotonic()
                            niceness = int(proc_stat(timed.pid)[16])  # once it has started
                        except (FileNotFoundError, ProcessLookupError):
                            break
                        time.sleep(0.5)  # sampling the recorder's CPU, not waiting for a result
                    during = scm_status(args, env, partition)
                    try:
                        rc = timed.wait(timeout=max(1, deadline - time.monotonic()))
                    except subprocess.TimeoutExpired:
                        stop(timed, signal.SIGKILL)
                        fail("autodrive-record --duration did not stop")
                    wait_for(term_log, f"recording {SPAT}", term, 60,
                             "the SIGTERM recorder never recorded SPaT")
                    term_rc = stop(term, signal.SIGTERM)
                probe_run.send_signal(signal.SIGINT)
                probe_text = probe_run.communicate(timeout=120)[0]
                print("--- recorder stopped by --duration:")
                print(timed_log.read_text(errors="replace")[-8000:])
                print("--- recorder stopped by SIGTERM:")
                print(term_log.read_text(errors="replace")[-1500:], flush=True)
                if rc != 0:
                    fail(f"autodrive-record --duration exited {rc}")
                if term_rc != 0:
                    fail(f"autodrive-record stopped by SIGTERM exited {term_rc}")
                if probe_run.returncode != 0:
                    fail(f"count_probe exited {probe_run.returncode}: {probe_text[-3000:]}")
            finally:
                stop(city, signal.SIGINT, group=True)

        print(f"the recorder: {100 * (cpu1 - cpu0) / max(1e-9, wall1 - wall0):.1f}% of one core "
              f"over {wall1 - wall0:.1f} s, at nice {niceness}")
        city_run.print_scm("the SCM before recording:", before)
        city_run.print_scm("the SCM while recorded:  ", during)
        if args.measure:
            for k in ("loop_work_p99_ms", "loop_late_p99_ms"):
                if before.get(k):
                    print(f"  {k}: {100 * (during[k] / before[k] - 1):+.1f}%")
        if niceness != 10:
            fail(f"the recorder ran at nice {niceness}, not 10 (it yields the CPU to the city)")
        if during.get("write_failures") != before.get("write_failures"):
            fail(f"the SCM counted {during.get('write_failures')} write failures while recorded, "
                 f"{before.get('write_failures')} before")

        spat_min = int(args.seconds * 10 * 0.5)
        # timed.mcap and term.mcap by hand; city.mcap by `autodrive-city up --record`.
        for name in ("timed.mcap", "term.mcap", "city.mcap"):
            info = subprocess.run([record, "info", str(tmp / name)], env=env, capture_output=True,
                                  text=True, timeout=600)
            print(f"--- autodrive-record info {name} (exit {info.returncode}):\n{info.stdout}"
                  f"{info.stderr}", flush=True)
            if info.returncode != 0 or "profile:  ros2" not in info.stdout:
                fail(f"autodrive-record info {name}")
            out = check(args, env, tmp / name, [(SPAT, spat_min), (MAP, 1)],
                        times=tmp / "timed.times" if name == "timed.mcap" else None)
            shown = out.stdout if name != "timed.mcap" or out.returncode else \
                json.dumps({k: v for k, v in json.loads(out.stdout).items() if k != "topics"})
            print(f"--- check_mcap.mjs {name} (exit {out.returncode}):\n{shown}{out.stderr}",
                  flush=True)
            if out.returncode != 0:
                fail(f"check_mcap.mjs {name}")
            if name == "timed.mcap":
                result = json.loads(out.stdout)
        cameras = [t for t, v in result["topics"].items() if v["type"] == "sensor_msgs/msg/Image"]
        if args.cameras and cameras != ["/autodrive/cameras/overhead/image"]:
            fail(f"camera topics recorded with --cameras --exclude '*/debug_image': {cameras}")
        if not args.cameras and cameras:
            fail(f"camera topics recorded without --cameras: {cameras}")
        spat = result["topics"][SPAT]
        if not 9.5 <= spat["rate_hz"] <= 10.5:
            fail(f"SPaT recorded at {spat['rate_hz']} Hz, expected 10 +- 0.5")
        compare_with_probe(tmp / "probe.jsonl", tmp / "timed.times", args.cameras)

        flipped = check(args, env, tmp / "term.mcap", [], flip=True)
        print(f"--- check_mcap.mjs --flip-byte middle (exit {flipped.returncode}): "
              f"{json.loads(flipped.stdout)['errors'] if flipped.stdout else flipped.stderr}")
        if flipped.returncode != 1:
            fail("check_mcap.mjs did not see a flipped byte")

        # Playback into a fresh partition, recorded there.
        replay_partition = f"{partition}_replay"
        replay_log = tmp / "replay.log"
        with open(replay_log, "w") as rl:
            replay = subprocess.Popen(
                [record, "--log-level", "info", "record", "--partition", replay_partition,
                 "-o", str(tmp / "replay.mcap")] + (["--cameras"] if args.cameras else []),
                env=env, stdout=rl, stderr=subprocess.STDOUT)
            play = subprocess.run(
                [record, "play", str(tmp / "timed.mcap"), "--partition", replay_partition,
                 "--rate", f"{args.rate:g}", "--wait-for-readers", "30"], env=env,
                capture_output=True, text=True, timeout=args.seconds / args.rate + 600)
            print(f"--- autodrive-record play (exit {play.returncode}):\n{play.stdout[-3000:]}"
                  f"{play.stderr[-2000:]}", flush=True)
            replay_rc = stop(replay, signal.SIGINT)
        print(f"--- recorder of the replay (exit {replay_rc}):\n"
              f"{replay_log.read_text(errors='replace')[-1500:]}", flush=True)
        if play.returncode != 0:
            fail("autodrive-record play")
        replayed = json.loads(check(args, env, tmp / "replay.mcap", []).stdout)
        differ = []
        for topic, want in sorted(result["topics"].items()):
            got = replayed["topics"].get(topic, {})
            # The player offers what was recorded: latched topics transient-local (durability 1).
            if got and got["offered"] != want["offered"]:
                differ.append(f"{topic}: recorded with writers offering {want['offered']}, "
                              f"played with {got['offered']}")
            if got.get("count", 0) != want["count"] or \
                    got.get("payload_sha256") != want["payload_sha256"]:
                differ.append(f"{topic}: recorded {want['count']}, replayed and recorded again "
                              f"{got.get('count', 0)}" +
                              ("" if got.get("count", 0) != want["count"] else
                               ", the payloads differ"))
        for line in differ:
            print(f"replay: {line}")
        if differ:
            fail(f"the replay differs on {len(differ)} of {len(result['topics'])} topics")
        latched = sorted(t for t, v in result["topics"].items()
                         if any("durability 1" in o for o in v["offered"]))
        if SPAT in latched or MAP not in latched:
            fail(f"the topics offered transient-local are {latched}: MAP is, SPaT is not")
        print(f"replay: all {len(result['topics'])} topics, "
              f"{sum(t['count'] for t in result['topics'].values())} messages, again with "
              f"byte-identical payloads (sha256 over each topic's payloads) and the recorded "
              f"offered QoS ({len(latched)} latched topics offered transient-local again)")
    print("record_city: OK")


if __name__ == "__main__":
    main()
