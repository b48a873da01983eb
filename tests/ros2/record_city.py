#!/usr/bin/python3
"""autodrive-record on the default city, checked with npm's MCAP and ROS 2 decoders (issue 35).

Brings up the default city (config/cities/small_town.yaml, autodrive-city up in its own DDS
partition and run folder) and records it twice at once: one recorder stops by itself
(`--duration`), the other by SIGTERM once the first is done. Then, with the city down:
  - `autodrive-record info` reads both files (profile ros2);
  - check_mcap.mjs (@mcap/core indexed and streamed with CRCs, @foxglove/rosmsg2-serialization
    decoding every message with its channel's schema) passes on both, with SPaT at about 10 Hz
    and the latched MAP present; and fails on a copy with one byte flipped in a chunk;
  - `autodrive-record play --rate 4` of the first file into a fresh partition, recorded there by
    a third recorder, delivers every SPaT message and the MAP again, byte for byte;
  - the city's own `--record` file (autodrive-city up --record) passes the same checks.
Prints the recorders' counters and check_mcap.mjs's JSON. Exit status 1 on any failure.
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

CITY = "config/cities/small_town.yaml"
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


def stop(process, sig=signal.SIGINT, group=False):
    if process.poll() is None:
        (os.killpg if group else os.kill)(process.pid, sig)
    try:
        return process.wait(timeout=120)
    except subprocess.TimeoutExpired:
        (os.killpg if group else os.kill)(process.pid, signal.SIGKILL)
        process.wait()
        return None


def check(args, env, mcap, expect, flip=False):
    command = [args.node, str(args.npm / "check_mcap.mjs"), str(mcap)]
    for topic, count in expect:
        command += ["--expect", f"{topic}:{count}"]
    if flip:
        command += ["--flip-byte", "middle"]
    out = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=pathlib.Path, required=True)
    parser.add_argument("--bin", type=pathlib.Path, required=True)
    parser.add_argument("--node", required=True)
    parser.add_argument("--npm", type=pathlib.Path, required=True, help="the npm modules' folder")
    parser.add_argument("--seconds", type=float, default=6.0, help="how long to record")
    args = parser.parse_args()
    record = str(args.bin / "autodrive-record")

    with tempfile.TemporaryDirectory(prefix="record_city.") as tmp:
        tmp = pathlib.Path(tmp)
        partition = f"record_city_{os.getpid()}"
        env = dict(os.environ)
        env["XDG_STATE_HOME"] = str(tmp / "state")
        env.pop("AUTODRIVE_PROCESS_NAME", None)
        city_log = tmp / "city.log"
        with open(city_log, "w") as log:
            city = subprocess.Popen(
                [str(args.bin / "autodrive-city"), "up", str(args.source / CITY), "--partition",
                 partition, "--dashboard", "127.0.0.1:0", "--duration", "900",
                 "--record", str(tmp / "city.mcap")],
                env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
            try:
                wait_for(city_log, "is up.", city, 300, "the city did not come up")
                print(f"city up in partition {partition}; recording {args.seconds:g} s", flush=True)
                timed_log, term_log = tmp / "timed.log", tmp / "term.log"
                with open(timed_log, "w") as tl, open(term_log, "w") as ml:
                    term = subprocess.Popen(
                        [record, "--log-level", "info", "record", "--partition", partition,
                         "-o", str(tmp / "term.mcap")], env=env, stdout=ml,
                        stderr=subprocess.STDOUT)
                    timed = subprocess.Popen(
                        [record, "--log-level", "info", "record", "--partition", partition,
                         "--duration", f"{args.seconds:g}", "-o", str(tmp / "timed.mcap")],
                        env=env, stdout=tl, stderr=subprocess.STDOUT)
                    try:
                        rc = timed.wait(timeout=args.seconds + 120)
                    except subprocess.TimeoutExpired:
                        stop(timed, signal.SIGKILL)
                        fail("autodrive-record --duration did not stop")
                    wait_for(term_log, f"recording {SPAT}", term, 60,
                             "the SIGTERM recorder never recorded SPaT")
                    term_rc = stop(term, signal.SIGTERM)
                print("--- recorder stopped by --duration:")
                print(timed_log.read_text(errors="replace")[-6000:])
                print("--- recorder stopped by SIGTERM:")
                print(term_log.read_text(errors="replace")[-1500:], flush=True)
                if rc != 0:
                    fail(f"autodrive-record --duration exited {rc}")
                if term_rc != 0:
                    fail(f"autodrive-record stopped by SIGTERM exited {term_rc}")
            finally:
                stop(city, signal.SIGINT, group=True)

        spat_min = int(args.seconds * 10 * 0.5)
        # timed.mcap and term.mcap by hand; city.mcap by `autodrive-city up --record`.
        for name in ("timed.mcap", "term.mcap", "city.mcap"):
            info = subprocess.run([record, "info", str(tmp / name)], env=env, capture_output=True,
                                  text=True, timeout=120)
            print(f"--- autodrive-record info {name} (exit {info.returncode}):\n{info.stdout}"
                  f"{info.stderr}", flush=True)
            if info.returncode != 0 or "profile:  ros2" not in info.stdout:
                fail(f"autodrive-record info {name}")
            out = check(args, env, tmp / name, [(SPAT, spat_min), (MAP, 1)])
            print(f"--- check_mcap.mjs {name} (exit {out.returncode}):\n{out.stdout}{out.stderr}",
                  flush=True)
            if out.returncode != 0:
                fail(f"check_mcap.mjs {name}")
        result = json.loads(check(args, env, tmp / "timed.mcap", []).stdout)
        cameras = [t for t, v in result["topics"].items() if v["type"] == "sensor_msgs/msg/Image"]
        if cameras:
            fail(f"camera topics recorded without --cameras: {cameras}")
        spat = result["topics"][SPAT]
        if not 9.5 <= spat["rate_hz"] <= 10.5:
            fail(f"SPaT recorded at {spat['rate_hz']} Hz, expected 10 +- 0.5")

        flipped = check(args, env, tmp / "timed.mcap", [], flip=True)
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
                 "-o", str(tmp / "replay.mcap")], env=env, stdout=rl,
                stderr=subprocess.STDOUT)
            play = subprocess.run(
                [record, "play", str(tmp / "timed.mcap"), "--partition", replay_partition,
                 "--rate", "4", "--wait-for-readers", "30"], env=env, capture_output=True,
                text=True, timeout=300)
            print(f"--- autodrive-record play (exit {play.returncode}):\n{play.stdout[-3000:]}"
                  f"{play.stderr[-2000:]}", flush=True)
            replay_rc = stop(replay, signal.SIGINT)
        print(f"--- recorder of the replay (exit {replay_rc}):\n"
              f"{replay_log.read_text(errors='replace')[-1500:]}", flush=True)
        if play.returncode != 0:
            fail("autodrive-record play")
        replayed = json.loads(check(args, env, tmp / "replay.mcap", []).stdout)
        for topic in (SPAT, MAP):
            want = result["topics"][topic]["count"]
            got = replayed["topics"].get(topic, {}).get("count", 0)
            print(f"replay: {topic}: recorded {want}, replayed and recorded again {got}")
            if got != want:
                fail(f"replay of {topic}: {got} messages, recorded {want}")
            if replayed["topics"][topic]["payload_sha256"] != result["topics"][topic]["payload_sha256"]:
                fail(f"replay of {topic}: the payloads differ from the recorded ones")
        print("replay: SPaT and MAP payloads byte-identical (sha256 over each topic's payloads)")
    print("record_city: OK")


if __name__ == "__main__":
    main()
