#!/usr/bin/python3
"""The default city as the ROS 2 graph sees it: type hashes, enclaves and nodes.

Brings up the default city (config/cities/small_town.yaml, autodrive-city up in its own DDS
partition and run folder), then runs graph_probe.c (Cyclone's C API only; the graph's type
compiled by idlc from the IDL that check_interfaces.py derived from Debian's rosidl for
upstream's rmw_dds_common .msg) and checks what it saw:

1. every reader and writer of the city carries USER_DATA `typehash=RIHS01_<hex>;` equal to the
   REP-2011 hash of its type, computed afresh by upstream Jazzy's generator from the .msg
   (scripts/generate-type-hashes' function, not the committed table);
2. every participant of the city carries `enclave=/;`;
3. every participant publishes one node on ros_discovery_info whose readers and writers are
   exactly its endpoints (0 missing, 0 extra; the graph's own writer excepted, as rmw does),
   and the nodes are exactly the documented ones: /autodrive/<process> for every process of
   the city's plan, and /autodrive/launcher.

Usage: check_graph.py --source REPO --bin BUILD/bin --work ROS2_WS [--idlc idlc] [--cc cc]
ROS2_WS is check_interfaces.py's work folder (its derived_idl/). Exit 0 when every check holds.
"""

import argparse
import importlib.machinery
import importlib.util
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile
import time

CITY = "config/cities/small_town.yaml"


def fail(text):
    print(f"check_graph: FAILED: {text}")
    sys.exit(1)


def fresh_hashes(source):
    """{dds type name: RIHS01 hash} from upstream's generator run now on the .msg files."""
    path = source / "scripts" / "generate-type-hashes"
    loader = importlib.machinery.SourceFileLoader("generate_type_hashes", str(path))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()):
        table = module.hashes()
    out = {}
    for name, value in table.items():
        package, _, type_name = name.split("/")
        out[f"{package}::msg::dds_::{type_name}_"] = value
    return out


def build_probe(args, work):
    derived = args.work / "derived_idl"
    idls = sorted((derived / "rmw_dds_common" / "msg").glob("*.idl"))
    if len(idls) != 3:
        fail(f"{derived}/rmw_dds_common/msg has {len(idls)} IDL files, not 3: run "
             "ros2_interfaces_test first (its fixture)")
    gen = work / "gen"
    gen.mkdir(parents=True)
    for idl in idls:
        subprocess.run([args.idlc, "-x", "final", "-I", str(derived), "-b", str(derived), "-o",
                        str(gen), str(idl)], check=True)
    probe = work / "graph_probe"
    sources = [str(args.source / "tests" / "ros2" / "graph_probe.c")] + \
        [str(p) for p in sorted(gen.rglob("*.c"))]
    subprocess.run([args.cc, "-std=c11", "-O1", "-o", str(probe), *sources, "-I", str(gen),
                    "-lddsc"], check=True)
    return probe


def planned_processes(args, env):
    out = subprocess.run([str(args.bin / "autodrive-city"), "check", str(args.source / CITY)],
                         env=env, capture_output=True, text=True, check=True).stdout
    return [m.group(1) for m in re.finditer(r"^  (\w+)\s+/", out, re.M)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=pathlib.Path, required=True)
    parser.add_argument("--bin", type=pathlib.Path, required=True)
    parser.add_argument("--work", type=pathlib.Path, required=True)
    parser.add_argument("--idlc", default="idlc")
    parser.add_argument("--cc", default="cc")
    parser.add_argument("--seconds", type=float, default=8.0,
                        help="how long the probe listens once the city is up")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="check_graph.") as tmp:
        tmp = pathlib.Path(tmp)
        probe = build_probe(args, tmp / "probe")
        partition = f"check_graph_{os.getpid()}"
        env = dict(os.environ)
        env["XDG_STATE_HOME"] = str(tmp / "state")
        env.pop("AUTODRIVE_PROCESS_NAME", None)
        env.pop("ROS_DISTRO", None)
        processes = planned_processes(args, env)
        expected_nodes = {f"/autodrive/{p}" for p in processes} | {"/autodrive/launcher"}
        log = open(tmp / "city.log", "w")
        city = subprocess.Popen(
            [str(args.bin / "autodrive-city"), "up", str(args.source / CITY), "--partition",
             partition, "--dashboard", "127.0.0.1:0", "--duration", "600"],
            env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            deadline = time.monotonic() + 300
            while "is up." not in (tmp / "city.log").read_text():
                if city.poll() is not None or time.monotonic() > deadline:
                    print((tmp / "city.log").read_text()[-3000:])
                    fail("the city did not come up")
                time.sleep(0.5)
            print(f"city up ({len(processes)} processes: {', '.join(processes)}); probing "
                  f"{args.seconds:g} s in partition {partition}")
            seen = subprocess.run([str(probe), partition, str(args.seconds)], env=env,
                                  capture_output=True, text=True, timeout=120)
            if seen.returncode != 0:
                fail(f"graph_probe exited {seen.returncode}: {seen.stderr}")
        finally:
            os.killpg(city.pid, signal.SIGINT)
            try:
                city.wait(timeout=120)
            except subprocess.TimeoutExpired:
                os.killpg(city.pid, signal.SIGKILL)
                city.wait()
            log.close()

    probe_guid, graph, participants, endpoints = None, {}, {}, []
    for line in seen.stdout.splitlines():
        item = json.loads(line)
        if "probe" in item:
            probe_guid = item["probe"]
        elif "graph" in item:
            graph[item["graph"]["gid"]] = item["graph"]  # the newest per participant
        elif "participant" in item:
            participants[item["participant"]["guid"]] = item["participant"]
        else:
            endpoints.append(item["endpoint"])
    in_city = [e for e in endpoints
               if e["partitions"] == [partition] and e["participant"] != probe_guid]
    city_participants = sorted({e["participant"] for e in in_city})
    errors = []

    # 1. Type hashes.
    hashes = fresh_hashes(args.source)
    types = set()
    for e in in_city:
        want = f"typehash={hashes.get(e['type'], '')};"
        types.add(e["type"])
        if e["type"] not in hashes:
            errors.append(f"{e['kind']} of {e['topic']}: type {e['type']} has no .msg")
        elif e["user_data"] != want:
            errors.append(f"{e['kind']} of {e['topic']} ({e['type']}): USER_DATA "
                          f"{e['user_data']!r}, not {want!r}")
    print(f"1. {len(in_city)} readers and writers of {len(types)} types in "
          f"{len(city_participants)} participants: "
          f"{sum(1 for e in in_city if e['user_data'] == 'typehash=' + hashes.get(e['type'], '?') + ';')}"
          f" carry their type's hash")

    # 2. Enclaves.
    for p in city_participants:
        data = participants.get(p, {}).get("user_data")
        if data != "enclave=/;":
            errors.append(f"participant {p}: USER_DATA {data!r}, not 'enclave=/;'")
    print(f"2. {len(city_participants)} participants, "
          f"{sum(1 for p in city_participants if participants.get(p, {}).get('user_data') == 'enclave=/;')}"
          " with enclave=/;")

    # 3. Nodes and their endpoints.
    names = {}
    missing = extra = 0
    for p in city_participants:
        info = graph.get(p)
        if info is None:
            errors.append(f"participant {p} ({sorted({e['topic'] for e in in_city if e['participant'] == p})[:3]}...): "
                          "no ros_discovery_info")
            continue
        if len(info["nodes"]) != 1:
            errors.append(f"participant {p}: {len(info['nodes'])} nodes, not 1")
            continue
        node = info["nodes"][0]
        full = node["namespace"].rstrip("/") + "/" + node["name"]
        names.setdefault(full, []).append(p)
        for kind, key in (("reader", "readers"), ("writer", "writers")):
            actual = {e["guid"] for e in in_city if e["participant"] == p and e["kind"] == kind
                      and e["topic"] != "ros_discovery_info"}
            listed = set(node[key])
            for g in sorted(actual - listed):
                missing += 1
                topic = next(e["topic"] for e in in_city if e["guid"] == g)
                errors.append(f"node {full}: its {kind} of {topic} is not listed")
            for g in sorted(listed - actual):
                extra += 1
                errors.append(f"node {full}: lists a {kind} {g} it does not have")
    if set(names) != expected_nodes:
        errors.append(f"nodes {sorted(names)}, documented {sorted(expected_nodes)}")
    print(f"3. {len(names)} nodes ({', '.join(sorted(names))}) in {sum(map(len, names.values()))}"
          f" participants; endpoints missing from their node: {missing}, listed but absent: {extra}")
    if errors:
        for e in errors[:40]:
            print(f"   {e}")
        fail(f"{len(errors)} differences")
    print("check_graph: every check holds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
