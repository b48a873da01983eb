#!/usr/bin/env python3
"""The behavioural-cloning figures of a sweep of sweep_cloning_driving_school.yaml, from the
runner's reports: per seed the collisions, lane departures (and the share of distance off the
lanes), red lights run, laps completed and lap times, the light the seed drew and the model's
inference time (from the agent's log); then the totals. Markdown tables.

Usage: examples/cloning/cloning_figures.py SWEEP_DIR
"""
import glob
import json
import os
import re
import statistics
import sys


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sweep = sys.argv[1]
    runs = sorted(glob.glob(os.path.join(sweep, "runs", "*", "report.json")),
                  key=lambda p: json.load(open(p))["seed"])
    if not runs:
        sys.exit(f"{sweep}: no runs/*/report.json")
    print("| seed | collisions | lane departures | off lane | red lights run | laps | lap times (s) | inference (ms, mean) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    totals = {"collisions": 0, "departures": 0, "laps": 0, "runs": 0, "five": 0}
    lap_times, inference = [], []
    for path in runs:
        r = json.load(open(path))
        v = r["metrics"]["vehicles"]["nigel_1"]
        laps = v.get("lap_times_s", [])
        lap_times += laps
        ms = ""
        for log in glob.glob(os.path.join(os.path.dirname(path), "run", "logs", "agent_nigel_1*")):
            m = re.search(r"frames through the network on \d+ thread\(s\): ([0-9.]+) ms mean",
                          open(log, errors="replace").read())
            if m:
                ms = m.group(1)
                inference.append(float(ms))
        print(f"| {r['seed']} | {len(v['collisions'])} | {len(v['lane_departures'])} | "
              f"{100 * v['off_lane_fraction']:.1f}% | {len(v['red_light_violations'])} | "
              f"{v.get('laps_completed', 0)} | {', '.join(f'{t:.1f}' for t in laps)} | {ms} |")
        totals["collisions"] += len(v["collisions"])
        totals["departures"] += len(v["lane_departures"])
        totals["laps"] += v.get("laps_completed", 0)
        totals["runs"] += 1
        totals["five"] += v.get("laps_completed", 0) >= 5
    print()
    print(f"{totals['runs']} runs: {totals['five']} drove 5 laps; {totals['collisions']} collisions, "
          f"{totals['departures']} lane departures, {totals['laps']} laps in all")
    if lap_times:
        print(f"lap time: mean {statistics.mean(lap_times):.1f} s, "
              f"min {min(lap_times):.1f} s, max {max(lap_times):.1f} s")
    if inference:
        print(f"inference: {statistics.mean(inference):.2f} ms a frame on one thread "
              f"({1000 / statistics.mean(inference):.0f} frames a second)")


if __name__ == "__main__":
    main()
