#!/usr/bin/env python3
"""The parking agent's own localisation against the runner's ground truth, for runs of
parking_school_pf.yaml (or a sweep of it): per run the particle filter's and SLAM's position error
(RMS, max) and heading error (max) over every decision, the filter's error where it stopped, SLAM's
map agreement with the map's grid (from the agent's log), whether the runner found it parked and its
final error against the bay; then the totals. Markdown tables.

The estimate is the agent's (run/localisation.csv: t_s, x_m, y_m, yaw_rad, slam_x_m, slam_y_m,
slam_yaw_rad, particles); the truth is the runner's (logs/ground_truth.csv, the simulator's pose of
the car at each step): matched by their simulated time.

Usage: examples/parking/localisation_figures.py RUN_OR_SWEEP_DIR
"""
import csv
import glob
import json
import math
import os
import re
import statistics
import sys


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def run_figures(run):
    truth = {}
    with open(os.path.join(run, "logs", "ground_truth.csv")) as f:
        for row in csv.DictReader(f):
            if row["vehicle"] == "nigel_1":
                truth[round(float(row["t_s"]), 2)] = (float(row["x_m"]), float(row["y_m"]),
                                                     float(row["yaw_rad"]))
    pf, slam, pf_yaw, slam_yaw, last = [], [], [], [], None
    with open(os.path.join(run, "run", "localisation.csv")) as f:
        for row in csv.DictReader(f):
            t = round(float(row["t_s"]), 2)
            if t not in truth:
                continue
            x, y, yaw = truth[t]
            e = math.hypot(float(row["x_m"]) - x, float(row["y_m"]) - y)
            pf.append(e)
            pf_yaw.append(abs(wrap(float(row["yaw_rad"]) - yaw)))
            slam.append(math.hypot(float(row["slam_x_m"]) - x, float(row["slam_y_m"]) - y))
            slam_yaw.append(abs(wrap(float(row["slam_yaw_rad"]) - yaw)))
            last = (e, pf_yaw[-1])
    agreement = ""
    for log in glob.glob(os.path.join(run, "run", "logs", "agent_nigel_1*")):
        m = re.search(r"SLAM's map: ([0-9.]+)% of the (\d+) cells", open(log, errors="replace").read())
        if m:
            agreement = (float(m.group(1)), int(m.group(2)))
    report = json.load(open(os.path.join(run, "report.json")))
    v = report["metrics"]["vehicles"]["nigel_1"]
    rms = lambda v: math.sqrt(sum(e * e for e in v) / len(v))
    return {"seed": report["seed"], "pf_rms": rms(pf), "pf_max": max(pf), "pf_yaw_max": max(pf_yaw),
            "slam_rms": rms(slam), "slam_max": max(slam), "slam_yaw_max": max(slam_yaw),
            "pf_last": last, "agreement": agreement, "parked": v["goal_reached"],
            "collisions": len(v["collisions"]),
            "final": (v.get("final_position_error_m"), v.get("final_heading_error_deg"))}


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    root = sys.argv[1]
    runs = [root] if os.path.exists(os.path.join(root, "report.json")) else \
        sorted(glob.glob(os.path.join(root, "runs", "*")))
    rows = [run_figures(r) for r in runs if os.path.exists(os.path.join(r, "run", "localisation.csv"))
            and os.path.exists(os.path.join(r, "report.json"))]  # finished runs
    if not rows:
        sys.exit(f"{root}: no run with run/localisation.csv")
    rows.sort(key=lambda r: r["seed"])
    print("| seed | parked | collisions | final error (mm, deg) | filter RMS / max (mm) | filter heading max (deg) | filter at the end (mm, deg) | SLAM RMS / max (mm) | SLAM heading max (deg) | SLAM map agrees |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        fe = r["final"]
        print(f"| {r['seed']} | {'yes' if r['parked'] else 'no'} | {r['collisions']} | "
              f"{fe[0] * 1000:.1f}, {fe[1]:.2f} | {r['pf_rms'] * 1000:.1f} / {r['pf_max'] * 1000:.1f} | "
              f"{math.degrees(r['pf_yaw_max']):.2f} | {r['pf_last'][0] * 1000:.1f}, "
              f"{math.degrees(r['pf_last'][1]):.2f} | {r['slam_rms'] * 1000:.1f} / "
              f"{r['slam_max'] * 1000:.1f} | {math.degrees(r['slam_yaw_max']):.2f} | "
              + (f"{r['agreement'][0]:.1f}% of {r['agreement'][1]}" if r["agreement"] else "") + " |")
    print()
    print(f"{len(rows)} runs: {sum(r['parked'] for r in rows)} parked within the bay's tolerances, "
          f"{sum(r['collisions'] for r in rows)} collisions")
    print(f"particle filter: RMS {statistics.mean(r['pf_rms'] for r in rows) * 1000:.1f} mm mean, "
          f"worst {max(r['pf_max'] for r in rows) * 1000:.1f} mm; "
          f"SLAM: RMS {statistics.mean(r['slam_rms'] for r in rows) * 1000:.1f} mm mean, "
          f"worst {max(r['slam_max'] for r in rows) * 1000:.1f} mm")
    agreements = [r["agreement"][0] for r in rows if r["agreement"]]
    if agreements:
        print(f"SLAM map: {statistics.mean(agreements):.1f}% of the cells seen agree with the "
              f"map's grid (mean; min {min(agreements):.1f}%)")


if __name__ == "__main__":
    main()
