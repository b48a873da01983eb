#!/usr/bin/env python3
"""SUMO's own GLOSA on the city's network and fixed-time plan, for comparison with ours.

Exports the city for SUMO alone with its fixed-time plan at every signalised intersection and
`--vehicles` cars circulating (`autodrive-traffic export --plan PLAN --vehicles N --seed S`, a
placement per seed), runs SUMO on it once per seed without and once with
SUMO's `glosa` device on every car (its range and slowest speed scaled to full size from ours:
8 m -> 112 m, 0.06 m/s -> 0.84 m/s), and prints, per arm, SUMO's own trip statistics
(tripinfo, unfinished trips included: the cars circulate): stops per car (waitingCount),
waiting time and time loss, mean and spread over the seeds. Nobody here wrote the GLOSA it measures: the figures say what a third party's GLOSA gets
from the same geometry and plan. Needs Debian's `sumo`.

Usage: examples/glosa/sumo_glosa.py [--city config/cities/driving_school.yaml] [--plan day]
       [--vehicles 4] [--seeds 20] [--duration 600] [--bin build/bin] [--out DIR]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

SCALE = 14.0  # SUMO metres per lab metre (maps/sumo.h)


def trips(path):
    """Each finished trip's waitingCount, waitingTime and timeLoss."""
    out = []
    for t in ET.parse(path).getroot().iter("tripinfo"):
        out.append((int(t.get("waitingCount")), float(t.get("waitingTime")),
                    float(t.get("timeLoss"))))
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(os.path.dirname(here))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--city", default=os.path.join(root, "config/cities/driving_school.yaml"))
    ap.add_argument("--plan", default="day", help="the city's fixed-time plan (default day)")
    ap.add_argument("--vehicles", type=int, default=4, help="SUMO cars (default 4)")
    ap.add_argument("--seeds", type=int, default=20, help="SUMO seeds 1..N (default 20)")
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    ap.add_argument("--range-m", type=float, default=8.0, help="GLOSA range, lab metres")
    ap.add_argument("--min-speed-mps", type=float, default=0.06, help="lab m/s")
    ap.add_argument("--bin", default=os.path.join(root, "build/bin"))
    ap.add_argument("--out", help="folder for the export and SUMO's outputs (default: temporary)")
    args = ap.parse_args()
    out = args.out or tempfile.mkdtemp(prefix="sumo_glosa_")
    os.makedirs(out, exist_ok=True)
    arms = {"without glosa": 0.0, "with SUMO's glosa": 1.0}
    results = {arm: [] for arm in arms}
    for seed in range(1, args.seeds + 1):
        folder = os.path.join(out, f"export_{seed}")
        export = subprocess.run(
            [os.path.join(args.bin, "autodrive-traffic"), "export", "--city", args.city, "--out",
             folder, "--duration", str(args.duration), "--plan", args.plan, "--vehicles",
             str(args.vehicles), "--seed", str(seed)], capture_output=True, text=True)
        if export.returncode != 0:
            sys.exit(f"sumo_glosa: the export failed: {export.stderr.strip() or export.stdout}")
        cfg = next(os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".sumocfg"))
        for arm, probability in arms.items():
            trip_file = os.path.join(out, f"trips_{int(probability)}_{seed}.xml")
            run = subprocess.run(
                ["sumo", "-c", cfg, "--seed", str(seed), "--end", str(args.duration),
                 "--device.glosa.probability", str(probability),
                 "--device.glosa.range", str(args.range_m * SCALE),
                 "--device.glosa.min-speed", str(args.min_speed_mps * SCALE),
                 "--tripinfo-output", trip_file, "--tripinfo-output.write-unfinished",
                 "--no-step-log", "--no-warnings",
                 "--duration-log.disable"],
                capture_output=True, text=True)
            if run.returncode != 0:
                sys.exit(f"sumo_glosa: sumo failed (seed {seed}, {arm}): {run.stderr.strip()}")
            t = trips(trip_file)
            if t:
                results[arm].append((statistics.mean(x[0] for x in t),
                                     statistics.mean(x[1] for x in t),
                                     statistics.mean(x[2] for x in t), len(t)))
        print(f"seed {seed}/{args.seeds} done", file=sys.stderr, flush=True)

    def line(values):
        return (f"{statistics.mean(values):.2f} (sd {statistics.stdev(values):.2f})"
                if len(values) > 1 else f"{values[0]:.2f}")

    print(f"SUMO alone, {os.path.basename(args.city)}, plan {args.plan}, {args.vehicles} cars, "
          f"{args.seeds} seeds of {args.duration:.0f} s; glosa range {args.range_m * SCALE:.0f} m, min speed "
          f"{args.min_speed_mps * SCALE:.2f} m/s (full scale)")
    print("| arm | cars per run | stops per car | waiting time per car (s) | time loss per car (s) |")
    print("| --- | --- | --- | --- | --- |")
    for arm, rows in results.items():
        if not rows:
            print(f"| {arm} | 0 | - | - | - |")
            continue
        print(f"| {arm} | {line([r[3] for r in rows])} | {line([r[0] for r in rows])} | "
              f"{line([r[1] for r in rows])} | {line([r[2] for r in rows])} |")
    print(f"outputs in {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
