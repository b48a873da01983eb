#!/usr/bin/env python3
"""An independent recomputation of a scenario run's red-light violations, collisions and route
completion from its raw logs (standard library only), compared with its report.json.

It reads only the run folder: logs/world.json (the cars' bodies and routes, the static
obstacles, the stop lines and the heads facing them), logs/ground_truth.csv and logs/lamps.csv,
and follows the definitions of docs/scenarios.md ("Metrics") with code of its own. Exit 0 when
it agrees with report.json, 1 (saying where) when it does not.

Usage: scenario_recompute.py RUN_DIR [RUN_DIR...]
"""
import csv
import json
import math
import os
import sys

CONTACT_M = 0.005      # bodies this close touch
SEPARATION_M = 0.02    # a contact ends once this far apart ...
REARM_S = 0.5          # ... for this long
ROUTE_TOLERANCE_M = 10.0 / 14.0


def rectangle(cx, cy, yaw, length, width):
    fx, fy = math.cos(yaw), math.sin(yaw)
    lx, ly = -fy, fx
    hl, hw = length / 2, width / 2
    return [(cx - hl * fx - hw * lx, cy - hl * fy - hw * ly),
            (cx + hl * fx - hw * lx, cy + hl * fy - hw * ly),
            (cx + hl * fx + hw * lx, cy + hl * fy + hw * ly),
            (cx - hl * fx + hw * lx, cy - hl * fy + hw * ly)]


def footprint(car, s):
    c = car['centre_ahead_m']
    return rectangle(s['x'] + c * math.cos(s['yaw']), s['y'] + c * math.sin(s['yaw']), s['yaw'],
                     car['length_m'], car['width_m'])


def point_segment(p, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    n2 = dx * dx + dy * dy
    t = 0.0 if n2 == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n2))
    return math.hypot(a[0] + t * dx - p[0], a[1] + t * dy - p[1])


def polygon_distance(a, b):
    """Separating-axis test for overlap (convex polygons), else the nearest edge distance."""
    def axes(poly):
        for i in range(len(poly)):
            x0, y0 = poly[i]
            x1, y1 = poly[(i + 1) % len(poly)]
            yield (-(y1 - y0), x1 - x0)

    overlap = True
    for ax in list(axes(a)) + list(axes(b)):
        pa = [p[0] * ax[0] + p[1] * ax[1] for p in a]
        pb = [p[0] * ax[0] + p[1] * ax[1] for p in b]
        if max(pa) < min(pb) or max(pb) < min(pa):
            overlap = False
            break
    if overlap:
        return 0.0
    best = math.inf
    for i in range(len(a)):
        for j in range(len(b)):
            best = min(best, point_segment(a[i], b[j], b[(j + 1) % len(b)]),
                       point_segment(b[j], a[i], a[(i + 1) % len(a)]))
    return best


def steady_red(track, t, end):
    """Whether the head showed a steady red at t: red, and not one of three or more stretches
    in a row of at most 1 s each alternating between red and dark (a flashing red, which is a
    stop sign's rule, not a red light's)."""
    stretches = []
    for k, (at, state) in enumerate(track):
        to = track[k + 1][0] if k + 1 < len(track) else max(end, at)
        if to > at:
            stretches.append((at, to, state))
    i = None
    for k, (at, to, state) in enumerate(stretches):
        if at <= t + 1e-9:
            i = k
    if i is None or stretches[i][2] != 1:
        return False

    def short(k):
        return stretches[k][1] - stretches[k][0] <= 1.0

    def flips(k, j):
        return stretches[k][2] in (0, 1) and stretches[j][2] in (0, 1) and \
            stretches[k][2] != stretches[j][2]
    if not short(i):
        return True
    lo = hi = i
    while lo > 0 and short(lo - 1) and flips(lo - 1, lo):
        lo -= 1
    while hi + 1 < len(stretches) and short(hi + 1) and flips(hi, hi + 1):
        hi += 1
    return hi - lo + 1 < 3


def recompute(run):
    logs = os.path.join(run, 'logs')
    world = json.load(open(os.path.join(logs, 'world.json')))
    truth = {}
    with open(os.path.join(logs, 'ground_truth.csv')) as f:
        for row in csv.DictReader(f):
            truth.setdefault(row['vehicle'], []).append(
                {'t': float(row['t_s']), 'x': float(row['x_m']), 'y': float(row['y_m']),
                 'yaw': float(row['yaw_rad']), 'vx': float(row['vx_mps'])})
    lamps = {}
    with open(os.path.join(logs, 'lamps.csv')) as f:
        for row in csv.DictReader(f):
            lamps.setdefault(int(row['head']), []).append((float(row['t_s']), int(row['state'])))

    out = {}
    # Red lights: the tail crosses a signalised stop line (within its ends) while a head facing
    # the lane shows a steady red (1).
    for car in world['cars']:
        samples = truth.get(car['name'], [])
        tail = car['length_m'] / 2 - car['centre_ahead_m']
        red = []
        for line in world['stop_lines']:
            if line['control'] != 'signal':
                continue
            (lx, ly), (rx, ry) = line['left'], line['right']
            mx, my = (lx + rx) / 2, (ly + ry) / 2
            half = math.hypot(lx - rx, ly - ry) / 2
            ax, ay = (lx - rx) / (2 * half), (ly - ry) / (2 * half)
            dx, dy = line['direction']

            def along(s):
                px = s['x'] - tail * math.cos(s['yaw'])
                py = s['y'] - tail * math.sin(s['yaw'])
                return (px - mx) * dx + (py - my) * dy, abs((px - mx) * ax + (py - my) * ay)

            for i in range(1, len(samples)):
                b, _ = along(samples[i - 1])
                a, lateral = along(samples[i])
                if b < 0 <= a and lateral <= half + 0.02:
                    if any(steady_red(lamps.get(h, []), samples[i]['t'], world['end_s'])
                           for h in line['heads']):
                        red.append(round(samples[i]['t'], 6))
        # Route completion: the furthest point of the route passed within the tolerance, moving
        # at most 0.5 m ahead at a time; 1 once the front is within the goal tolerance of its end.
        route = [tuple(p) for p in car['route']]
        completion = 1.0
        if route:
            cum = [0.0]
            for i in range(1, len(route)):
                cum.append(cum[-1] + math.hypot(route[i][0] - route[i - 1][0],
                                                route[i][1] - route[i - 1][1]))
            progress, goal = 0.0, False
            front = car['centre_ahead_m'] + car['length_m'] / 2
            for s in samples:
                best_d, best_s = math.inf, progress
                for i in range(len(route) - 1):
                    n = cum[i + 1] - cum[i]
                    if n <= 0 or cum[i + 1] < progress - 0.1 or cum[i] > progress + 0.5:
                        continue
                    (x0, y0), (x1, y1) = route[i], route[i + 1]
                    t = max(0.0, min(1.0, ((s['x'] - x0) * (x1 - x0) + (s['y'] - y0) * (y1 - y0)) / (n * n)))
                    d = math.hypot(x0 + t * (x1 - x0) - s['x'], y0 + t * (y1 - y0) - s['y'])
                    if d < best_d:
                        best_d, best_s = d, cum[i] + t * n
                if best_d <= ROUTE_TOLERANCE_M:
                    progress = max(progress, best_s)
                fx = s['x'] + front * math.cos(s['yaw'])
                fy = s['y'] + front * math.sin(s['yaw'])
                if math.hypot(fx - route[-1][0], fy - route[-1][1]) <= car['goal_tolerance_m']:
                    goal = True
            completion = 1.0 if goal else min(progress / cum[-1], 1.0)
        out[car['name']] = {'red': red, 'completion': completion, 'contacts': []}

    # Collisions: bodies within CONTACT_M of a static obstacle or of another car; a new contact
    # with the same thing only after SEPARATION_M apart for REARM_S.
    def track(name, other, samples, distance_at):
        touching, last, contacts = False, None, []
        for i, s in enumerate(samples):
            d = distance_at(i, s)
            if d is None:
                continue
            if d <= CONTACT_M:
                if not touching and (last is None or s['t'] - last >= REARM_S):
                    contacts.append(round(s['t'], 6))
                touching, last = True, s['t']
            elif d > SEPARATION_M:
                if touching:
                    last = s['t']
                touching = False
            elif touching:
                last = s['t']
        return contacts

    cars = world['cars']
    for ci, car in enumerate(cars):
        samples = truth.get(car['name'], [])
        for st in world['statics']:
            poly = [tuple(p) for p in st['footprint']]
            cx = sum(p[0] for p in poly) / len(poly)
            cy = sum(p[1] for p in poly) / len(poly)
            r = max(math.hypot(p[0] - cx, p[1] - cy) for p in poly) + 0.3

            until = math.inf if st['until_s'] is None else st['until_s']

            def d_static(i, s, poly=poly, cx=cx, cy=cy, r=r, since=st['from_s'], until=until):
                # An obstacle placed or removed by an event stands from_s <= t < until_s.
                if not since <= s['t'] + 1e-9 < until:
                    return math.inf
                if math.hypot(s['x'] - cx, s['y'] - cy) > r + 0.1:
                    return math.inf
                return polygon_distance(footprint(car, s), poly)
            out[car['name']]['contacts'] += track(car['name'], st['name'], samples, d_static)
        for other in cars[ci + 1:]:
            os_ = truth.get(other['name'], [])

            def d_car(i, s, other=other, os_=os_):
                if i >= len(os_):
                    return None
                return polygon_distance(footprint(car, s), footprint(other, os_[i]))
            hits = track(car['name'], other['name'], samples, d_car)
            out[car['name']]['contacts'] += hits
            out[other['name']]['contacts'] += hits
    return out


def main(runs):
    bad = 0
    for run in runs:
        report = json.load(open(os.path.join(run, 'report.json')))
        mine = recompute(run)
        for name, m in mine.items():
            v = report['metrics']['vehicles'][name]
            theirs_red = [x['t_s'] for x in v['red_light_violations']]
            theirs_hits = sorted(x['t_s'] for x in v['collisions'] if x['kind'] != 'traffic')
            checks = [
                ('red-light violations', m['red'], theirs_red),
                ('collisions (static and cars)', sorted(m['contacts']), theirs_hits),
            ]
            for what, a, b in checks:
                if len(a) != len(b) or any(abs(x - y) > 1e-6 for x, y in zip(a, b)):
                    print(f'{run}: {name}: {what}: recomputed {a}, report.json {b}')
                    bad += 1
            if abs(m['completion'] - v['route_completion']) > 1e-5:
                print(f"{run}: {name}: route completion: recomputed {m['completion']:.6f}, "
                      f"report.json {v['route_completion']}")
                bad += 1
            print(f"{run}: {name}: red {len(m['red'])}, collisions {len(m['contacts'])}, "
                  f"completion {m['completion']:.6f}: {'agrees' if not bad else 'DISAGREES'}")
    return 1 if bad else 0


if __name__ == '__main__':
    if len(sys.argv) < 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(sys.argv[1:]))
