"""What the ROS 2 tests on the running default city share (record_city.py, live_city.py): their
command line (the programs, node and the npm modules, the probe's compiler and derived IDL), the
city brought up in a DDS partition and run folder of its own, stopping processes, and a process's
CPU time from /proc."""

import json
import os
import pathlib
import re
import signal
import subprocess

CITY = "config/cities/small_town.yaml"


def add_arguments(parser):
    """The options every such test takes (CTest gives them; tests/ros2/*_tests.cmake)."""
    parser.add_argument("--source", type=pathlib.Path, required=True)
    parser.add_argument("--bin", type=pathlib.Path, required=True)
    parser.add_argument("--node", required=True)
    parser.add_argument("--npm", type=pathlib.Path, required=True, help="the npm modules' folder")
    parser.add_argument("--cc", default="cc", help="C compiler for count_probe.c")
    parser.add_argument("--idlc", default="idlc")
    parser.add_argument("--ros2-work", type=pathlib.Path, required=True,
                        help="ros2_interfaces_test's work folder (its derived_idl)")
    parser.add_argument("--work", type=pathlib.Path,
                        help="folder for the files (default: a temporary one, removed)")


def city_environment(tmp):
    """The environment of the city and the test's programs: state under `tmp`, no process name."""
    env = dict(os.environ)
    env["XDG_STATE_HOME"] = str(pathlib.Path(tmp) / "state")
    env.pop("AUTODRIVE_PROCESS_NAME", None)
    return env


def start_city(args, env, partition, log, extra=()):
    """`autodrive-city up` of the default city in `partition` (its own session: stop it with
    `stop(city, group=True)`), writing into the open file `log`."""
    return subprocess.Popen(
        [str(args.bin / "autodrive-city"), "up", str(args.source / CITY), "--partition",
         partition, "--dashboard", "127.0.0.1:0", "--duration", "3600", *extra],
        env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def stop(process, sig=signal.SIGINT, group=False):
    """Sends `sig` (to the process group with `group`), waits up to 120 s, then kills; returns
    the exit status (None when it had to be killed)."""
    if process.poll() is None:
        (os.killpg if group else os.kill)(process.pid, sig)
    try:
        return process.wait(timeout=120)
    except subprocess.TimeoutExpired:
        (os.killpg if group else os.kill)(process.pid, signal.SIGKILL)
        process.wait()
        return None


def proc_stat(pid):
    """/proc/PID/stat's fields after the command name (field 3 of proc(5) first)."""
    return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


def cpu_seconds(pid):
    """The CPU time (user + system) process `pid` has used, in seconds."""
    fields = proc_stat(pid)
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def scm_status(args, env, partition):
    """`scmctl status` of the SCM in `partition`: its values, or the error text."""
    out = subprocess.run([str(args.bin / "scmctl"), "--partition", partition, "--json", "status"],
                         env=env, capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        return f"scmctl status: {out.stdout}{out.stderr}"
    values = json.loads(out.stdout.splitlines()[0]).get("values", {})
    return values if isinstance(values, dict) else dict(values)


def scm_log_lines(city_log, words):
    """The lines of the SCM's own log (logs/scm.log in the run folder `autodrive-city up`
    printed into `city_log`) that contain any of `words`: the evidence behind a failed check."""
    text = pathlib.Path(city_log).read_text(errors="replace")
    match = re.search(r"run folder (\S+)", text)
    if match is None:
        return ["(no run folder in the city's log)"]
    log = pathlib.Path(match.group(1)) / "logs" / "scm.log"
    if not log.exists():
        return [f"(no {log})"]
    return [x for x in log.read_text(errors="replace").splitlines() if any(w in x for w in words)]


SCM_LOOP_KEYS = ("write_failures", "loop_passes", "loop_work_p50_ms", "loop_work_p99_ms",
                 "loop_late_p50_ms", "loop_late_p99_ms", "stalls")


def print_scm(label, status):
    print(f"{label} " + ", ".join(f"{k} {status.get(k)}" for k in SCM_LOOP_KEYS), flush=True)
