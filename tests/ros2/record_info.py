#!/usr/bin/python3
"""`autodrive-record info` on a bag rosbag2 itself recorded, against npm's @mcap/core (issue 35).

Reads tests/ros2/upstream/rosbag2/only_topics.mcap (vendored from ros2/rosbag2, see its
UPSTREAM.md) with `autodrive-record info` and with tests/ros2/npm/check_mcap.mjs --foreign
(@mcap/core indexed and streamed with CRCs, every message decoded with its channel's schema),
and requires both to list the same topics with the same types and message counts, and the same
total. Exit status 1 on any difference.
"""

import argparse
import json
import re
import subprocess
import sys

TOPIC_LINE = re.compile(r"^\s+(/\S+)\s+(\S+/msg/\S+)\s+(\d+) msgs?\s+(\S+)\s*$")


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", required=True, help="folder of autodrive-record")
    parser.add_argument("--node", required=True)
    parser.add_argument("--npm", required=True, help="folder of check_mcap.mjs and node_modules")
    parser.add_argument("file")
    args = parser.parse_args()

    info = subprocess.run([f"{args.bin}/autodrive-record", "info", args.file],
                          capture_output=True, text=True)
    print(info.stdout, info.stderr, sep="")
    if info.returncode != 0:
        print("record_info: FAILED: autodrive-record info exited", info.returncode)
        return 1
    ours = {}
    total = None
    for line in info.stdout.splitlines():
        if m := TOPIC_LINE.match(line):
            ours[m.group(1)] = (m.group(2), int(m.group(3)))
        elif m := re.match(r"^messages:\s+(\d+)", line):
            total = int(m.group(1))

    check = subprocess.run([args.node, f"{args.npm}/check_mcap.mjs", args.file, "--foreign"],
                           capture_output=True, text=True)
    print(check.stdout, check.stderr, sep="")
    if check.returncode != 0:
        print("record_info: FAILED: check_mcap.mjs exited", check.returncode)
        return 1
    theirs_json = json.loads(check.stdout)
    theirs = {t: (v["type"], v["count"]) for t, v in theirs_json["topics"].items()}

    problems = []
    if not theirs:
        problems.append("@mcap/core found no topic")
    for topic in sorted(set(ours) | set(theirs)):
        if ours.get(topic) != theirs.get(topic):
            problems.append(f"{topic}: autodrive-record {ours.get(topic)}, @mcap/core "
                            f"{theirs.get(topic)}")
    if total != theirs_json["messages"]:
        problems.append(f"messages: autodrive-record {total}, @mcap/core {theirs_json['messages']}")
    for p in problems:
        print("record_info: FAILED:", p)
    if problems:
        return 1
    print(f"record_info: {len(ours)} topics, {total} messages: autodrive-record info and "
          "@mcap/core agree")
    return 0


if __name__ == "__main__":
    sys.exit(main())
