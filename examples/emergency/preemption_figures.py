#!/usr/bin/env python3
"""The pre-emption figures of a sweep of sweep_v2i_emergency.yaml, from the runs' own records.

For each seed it pairs the run with requests (variant `emergency`) with the run without
(`no_request`): the same SUMO demand, noise and plan, so what differs is what the requests did.
Per seed:
  - the vehicle's time to its goal and its time loss, with and without (report.json);
  - the SUMO cars' mean time loss and waiting time, with and without (SUMO's tripinfo, as the
    runner reads it): the cross streets' extra delay;
  - per intersection asked, how long after its request the lamps were back on the plan: the end of
    the last stretch (0.2 s or longer) during which one of that intersection's heads showed
    something else than in the run without requests (logs/lamps.csv of both); the run's end when
    they never were.
Prints one row per seed and the means, as Markdown tables; a `+` marks an intersection still off
its plan when the run ended.

Usage: examples/emergency/preemption_figures.py SWEEP_DIR [--city config/cities/small_town.yaml]
"""
import argparse
import csv
import json
import os
import statistics
import sys


def lamps(path):
    """{head: [(t, state), ...]} from a run's lamps.csv (changes, in time order)."""
    out = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            out.setdefault(int(row["head"]), []).append((float(row["t_s"]), int(row["state"])))
    return out


def state_at(changes, t):
    s = None
    for when, state in changes:
        if when > t:
            break
        s = state
    return s


def last_difference(a, b, heads, start, end, shortest=0.2):
    """The end of the last stretch in [start, end] at least `shortest` long during which a head of
    `heads` shows differently in a and b (shorter ones are the same change a step or two apart)."""
    times = sorted({t for h in heads for t, _ in a.get(h, []) + b.get(h, []) if start <= t <= end})
    times.append(end)
    last = None
    since = None  # start of the stretch of difference under way
    for i, t in enumerate(times[:-1]):
        differs = any(state_at(a.get(h, []), t + 1e-6) != state_at(b.get(h, []), t + 1e-6)
                      for h in heads)
        if differs and since is None:
            since = t
        if not differs and since is not None:
            if t - since >= shortest:
                last = t
            since = None
    if since is not None and end - since >= shortest:
        last = end
    return last


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sweep", help="the sweep's folder (autodrive-scenario sweep --out)")
    args = ap.parse_args()
    summary = json.load(open(os.path.join(args.sweep, "summary.json")))
    runs = {}
    for variant in summary["variants"]:
        for r in variant["runs"]:
            r = dict(r)
            r["report"] = os.path.join(args.sweep, r["report"])  # relative to the sweep
            runs[(variant["name"], r["seed"])] = r
    seeds = sorted({s for (_, s) in runs})
    rows = []
    for seed in seeds:
        with_, without = runs.get(("emergency", seed)), runs.get(("no_request", seed))
        if not with_ or not without:
            continue
        rw = json.load(open(with_["report"]))
        ro = json.load(open(without["report"]))
        mw, mo = rw["metrics"]["run"], ro["metrics"]["run"]
        world = json.load(open(os.path.join(os.path.dirname(with_["report"]), "logs", "world.json")))
        heads_of = {}
        for g in world["groups"]:
            heads_of.setdefault(g["intersection"], set()).update(g["heads"])
        la = lamps(os.path.join(os.path.dirname(with_["report"]), "logs", "lamps.csv"))
        lb = lamps(os.path.join(os.path.dirname(without["report"]), "logs", "lamps.csv"))
        end = min(rw["end"]["t_s"], ro["end"]["t_s"])
        # The intersection of each request (logs/requests.jsonl: the requests as sent).
        where = {}
        with open(os.path.join(os.path.dirname(with_["report"]), "logs", "requests.jsonl")) as f:
            for line in f:
                m = json.loads(line)
                if m.get("kind") == "request":
                    where.setdefault((m["vehicle"], m["request_id"]), m["intersection"])
        back = []
        for q in rw["metrics"]["v2i"].get("requests", []):
            x = where.get((q["vehicle"], q["request_id"]))
            heads = heads_of.get(x) if x is not None else set().union(*heads_of.values())
            last = last_difference(la, lb, heads, q["t_s"], end)
            # (seconds, whether it was still off its plan at the run's end)
            back.append((0.0, False) if last is None else (last - q["t_s"], last >= end))
        rows.append({
            "seed": seed,
            "ev_time_to_goal": (mw.get("time_to_goal_s"), mo.get("time_to_goal_s")),
            "ev_time_loss": (mw.get("time_loss_s"), mo.get("time_loss_s")),
            "ev_stopped": (mw.get("stopped_time_s"), mo.get("stopped_time_s")),
            "bg_time_loss": (mw.get("background_time_loss_mean_s"),
                             mo.get("background_time_loss_mean_s")),
            "bg_waiting": (mw.get("background_waiting_time_mean_s"),
                           mo.get("background_waiting_time_mean_s")),
            "back_to_plan": back,
            "requests": mw.get("requests"),
        })
    if not rows:
        sys.exit("preemption_figures: no seed has both an emergency and a no_request run")

    def f(v):
        return "-" if v is None else f"{v:.1f}"

    print("| seed | EV to goal, with / without (s) | EV stopped (s) | SUMO cars' time loss (s) "
          "| SUMO cars' waiting (s) | back on plan after each request (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['seed']} | {f(r['ev_time_to_goal'][0])} / {f(r['ev_time_to_goal'][1])} | "
              f"{f(r['ev_stopped'][0])} / {f(r['ev_stopped'][1])} | "
              f"{f(r['bg_time_loss'][0])} / {f(r['bg_time_loss'][1])} | "
              f"{f(r['bg_waiting'][0])} / {f(r['bg_waiting'][1])} | "
              f"{', '.join(f(b) + ('+' if censored else '') for b, censored in r['back_to_plan'])} |")

    def mean_of(key, i):
        v = [r[key][i] for r in rows if r[key][i] is not None]
        return statistics.mean(v) if v else None

    def diff(key):
        d = [r[key][0] - r[key][1] for r in rows if None not in r[key]]
        return (statistics.mean(d), statistics.stdev(d) if len(d) > 1 else 0.0, len(d))

    print()
    print(f"over {len(rows)} seeds (mean, with minus without: mean, sd):")
    for key, what in [("ev_time_to_goal", "EV time to goal (s)"), ("ev_time_loss", "EV time loss (s)"),
                      ("ev_stopped", "EV stopped time (s)"),
                      ("bg_time_loss", "SUMO cars' mean time loss (s)"),
                      ("bg_waiting", "SUMO cars' mean waiting time (s)")]:
        m, sd, n = diff(key)
        print(f"- {what}: with {f(mean_of(key, 0))}, without {f(mean_of(key, 1))}; "
              f"difference {m:+.1f} (sd {sd:.1f}, {n} seeds)")
    back = [b for r in rows for b, censored in r["back_to_plan"] if not censored]
    never = sum(1 for r in rows for _, censored in r["back_to_plan"] if censored)
    print(f"- back on plan after a request: {len(back)} requests, mean "
          f"{statistics.mean(back) if back else float('nan'):.1f} s, max "
          f"{max(back) if back else float('nan'):.1f} s; {never} still off their plan at the "
          "run's end (+ in the table)")


if __name__ == "__main__":
    main()
