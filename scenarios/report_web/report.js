// report.html: one run of a scenario, drawn from the page's data (scenarios/internal/report_data.h:
// report.json with the run's logs made ready to chart) with uPlot 1.6.32.
//
// - The header, the expectations, the run's and every car's metrics: HTML tables.
// - The map: a uPlot chart in x/y mode (`mode: 2`), metres on both axes at one scale (the
//   ranges are widened so that a metre is as long across as up, also after a zoom). Its series
//   draw the lanes' and movements' centre lines, the stop lines, the static obstacles (filled),
//   the routes (dashed) and each car's track through uPlot's path builders; the road surfaces
//   are drawn under them (hook `drawClear`) and the infraction marks, the heads' numbers and
//   the cars' bodies over them (hook `draw`), on uPlot's own canvas.
// - Per car: speed over time, and under it the lamps of the heads facing the stop lines on its
//   route as bands (steady colour, or stripes when flashing) — two uPlot charts on one time axis.
// - The time line: a uPlot chart whose rows are the scenario's events, SPaT, the SCM's events,
//   V2I requests and answers and each car's infractions, and a table of the same.
// All time charts share the cursor and the zoom (drag; double-click to undo); the cursor's time
// puts the cars' bodies on the map where they were then.
"use strict";

(() => {
  const {el, num, card} = AD;
  const D = AD.data();
  const R = D.report || {};
  const M = R.metrics || {};
  const cars = D.cars || [];
  const colour = {};
  cars.forEach((c, i) => colour[c.name] = AD.CAR_COLOURS[i % AD.CAR_COLOURS.length]);
  let endS = D.end_s || 0;
  for (const c of cars) if (c.track.t.length) endS = Math.max(endS, c.track.t[c.track.t.length - 1]);
  const page = document.getElementById("page");
  const failed = new Set((R.expect || []).filter((e) => !e.held).map((e) => e.metric));
  const pending = [];  // charts made once their boxes are in the page (their width known)

  // ---- Header ----
  const scenario = R.scenario || {};
  const end = R.end || {};
  const passed = R.passed === true;
  const inv = R.invocation || {};
  document.title = `${scenario.name || "scenario"} — ${passed ? "passed" : "FAILED"}`;
  const facts = [
    ["seed", R.seed],
    ["city", R.city],
    ["end", `${end.reason || "?"} at ${num(end.t_s, 2)} s`],
    ["cars", cars.map((c) => c.name).join(", ") || "none"],
    ["autodrive", (R.versions || {}).autodrive],
  ];
  if (inv.wall_s != null) {
    facts.push(["run took", `${num(inv.wall_s, 1)} s wall (${num(inv.real_time_factor, 2)}× real time)`]);
  }
  const problems = [];
  if (end.failure) problems.push(el("li", {}, end.failure));
  for (const e of R.expect || []) {
    if (!e.held) {
      problems.push(el("li", {}, el("code", {}, e.metric), ` ${e.expect} failed: the run gave `,
                       el("b", {}, e.value == null ? "nothing (not measured)" : num(e.value))));
    }
  }
  page.append(el("header", {class: "top"},
    el("div", {class: "title"},
      el("h1", {}, scenario.name || "scenario"),
      el("span", {class: "verdict " + (passed ? "pass" : "fail"), id: "verdict"},
         passed ? "PASSED" : "FAILED")),
    scenario.description ? el("p", {class: "description"}, scenario.description) : null,
    el("dl", {class: "facts"}, facts.map(([k, v]) => [el("dt", {}, k), el("dd", {}, v == null ? "—" : String(v))])),
    scenario.file ? el("p", {class: "file mono"}, scenario.file) : null,
    problems.length ? el("ul", {class: "problems", id: "problems"}, problems) : null));

  // ---- Expectations and run metrics ----
  const expectRows = (R.expect || []).map((e) => el("tr", {class: e.held ? "" : "bad"},
    el("td", {class: "mono"}, e.metric),
    el("td", {class: "mono"}, e.expect),
    el("td", {class: "num"}, e.value == null ? "—" : num(e.value)),
    el("td", {class: "held"}, e.held ? "✓ held" : "✗ failed")));
  const expectations = card("Expectations",
    expectRows.length
      ? el("table", {class: "grid", id: "expectations"},
           el("thead", {}, el("tr", {}, el("th", {}, "metric"), el("th", {}, "threshold"),
                               el("th", {class: "num"}, "value"), el("th", {}, "held"))),
           el("tbody", {}, expectRows))
      : el("p", {class: "note"}, "The scenario sets no expectation."));

  const runOrder = ["collisions", "red_light_violations", "stop_sign_violations", "lane_departures",
                    "infractions", "infractions_per_km", "route_completion", "goals_reached",
                    "time_to_goal_s", "score", "distance_m", "stops", "stopped_time_s",
                    "time_loss_s", "max_accel_mps2", "max_jerk_mps3", "energy_j_per_kg",
                    "spat_messages", "spat_windows_below_10hz", "spat_min_end_error_p95_s",
                    "map_messages", "requests", "requests_granted", "request_to_green_max_s",
                    "background_trips", "background_waiting_time_mean_s",
                    "background_time_loss_mean_s"];
  const run = M.run || {};
  const runKeys = runOrder.filter((k) => k in run)
    .concat(Object.keys(run).filter((k) => !runOrder.includes(k) && k !== "collision_list"));
  const runTable = el("table", {class: "kv", id: "run-metrics"}, el("tbody", {}, runKeys.map((k) => {
    const v = run[k];
    const bad = failed.has(k) || (/violations|collisions|departures|^infractions$/.test(k) && v > 0);
    return el("tr", {class: bad ? "bad" : ""}, el("th", {class: "mono"}, k),
              el("td", {class: "num"}, Array.isArray(v) ? String(v.length) : num(v)),
              el("td", {class: "unit"}, AD.unit(k)));
  })));
  const runCard = card("Run", runTable);

  // ---- Per-vehicle metrics ----
  const vehicles = M.vehicles || {};
  const names = Object.keys(vehicles);
  const carOrder = ["route_completion", "goal_reached", "time_to_goal_s", "route_length_m",
                    "distance_m", "collisions", "red_light_violations", "stop_sign_violations",
                    "lane_departures", "off_lane_fraction", "infractions", "infractions_per_km",
                    "penalty", "score", "delay_s", "time_loss_s", "stops", "stopped_time_s",
                    "max_accel_mps2", "max_jerk_mps3", "max_lateral_accel_mps2",
                    "energy_j_per_kg"];
  const keys = [];
  for (const k of carOrder) if (names.some((n) => k in vehicles[n])) keys.push(k);
  for (const n of names) for (const k of Object.keys(vehicles[n])) if (!keys.includes(k)) keys.push(k);
  const cell = (k, v) => {
    if (Array.isArray(v)) {
      const first = v.length ? v[0].t_s : null;
      const title = v.map((x) => Object.entries(x).map(([a, b]) => `${a}=${b}`).join(" ")).join("\n");
      return el("td", {class: "num" + (v.length ? " bad" : ""), title: title || null},
                String(v.length), v.length ? el("span", {class: "sub"}, ` first at ${num(first, 2)} s`) : null);
    }
    if (typeof v === "boolean") return el("td", {class: "num" + (v ? "" : " warn")}, v ? "yes" : "no");
    return el("td", {class: "num"}, num(v));
  };
  const vehiclesCard = card("Vehicles",
    names.length
      ? el("table", {class: "grid vehicles", id: "vehicle-metrics"},
           el("thead", {}, el("tr", {}, el("th", {}, "metric"), el("th", {class: "unit"}, "unit"),
                               names.map((n) => el("th", {class: "num"},
                                 el("span", {class: "chip", style: {background: colour[n] || AD.MUTED}}), n)))),
           el("tbody", {}, keys.map((k) => el("tr", {class: failed.has(k) ? "bad-row" : ""},
             el("th", {class: "mono"}, k), el("td", {class: "unit"}, AD.unit(k)),
             names.map((n) => cell(k, vehicles[n][k]))))))
      : el("p", {class: "note"}, "No vehicle metrics in report.json."));

  // ---- Map, speed and lamps ----
  const mapBox = el("div", {class: "chart", id: "map"});
  const markKinds = ["collision", "red_light", "stop_sign", "lane_departure", "goal"];
  const mapCard = card("Map and tracks", mapBox,
    el("div", {class: "legend"},
       markKinds.map((k) => el("span", {}, AD.markIcon(k), AD.MARKS[k].name)),
       el("span", {}, el("span", {class: "swatch obstacle"}), "unmapped obstacle"),
       el("span", {}, el("span", {class: "swatch wall"}), "map walls and boxes")),
    el("p", {class: "hint"}, "Metres, one scale on both axes. Drag to zoom, double-click to fit. " +
       "The bodies show where the cars were at the time under the cursor of a time chart (at the end otherwise)."));
  const speedCard = card("Speed and lamps",
    el("div", {class: "legend"}, [1, 2, 3, 4, 5, 0].map((a) => el("span", {}, AD.lampChip(a), AD.LAMP_NAME[a]))));
  pending.push(() => mapChart(mapBox));
  for (const c of cars) {
    const speedBox = el("div", {class: "chart speed"});
    const lampBox = el("div", {class: "chart lamps"});
    const vmax = Math.max(0, ...c.track.v);
    speedCard.append(el("div", {class: "car-block", id: "car-" + c.name},
      el("h3", {}, el("span", {class: "chip", style: {background: colour[c.name]}}), c.name,
         el("span", {class: "sub"}, ` top speed ${num(vmax, 3)} m/s · ${c.stop_lines.length} stop line(s) on its way`)),
      speedBox, lampBox));
    pending.push(() => speedChart(c, speedBox));
    pending.push(() => lampChart(c, lampBox));
  }
  if (!cars.length) speedCard.append(el("p", {class: "note"}, "No car."));

  // ---- Time line ----
  const T = D.timeline || {rows: [], marks: []};
  // The time line's and the lamps' row names: one axis width for both, so that their times align.
  const rowAxis = Math.min(280, Math.ceil(Math.max(40, ...T.rows.map(AD.textWidth),
    ...Object.keys(D.heads || {}).map((h) => AD.textWidth("h" + h)))) + 18);
  const timelineBox = el("div", {class: "chart", id: "timeline"});
  const kinds = [...new Set(T.marks.map((m) => m.kind))];
  const rowsOf = T.marks.slice().sort((a, b) => a.t - b.t);
  const eventsCard = card("Events and V2I",
    T.rows.length ? timelineBox : el("p", {class: "note"}, "Nothing happened on the time line."),
    el("div", {class: "legend"}, kinds.map((k) => el("span", {}, AD.markIcon(k), (AD.MARKS[k] || {}).name || k))),
    rowsOf.length
      ? el("div", {class: "scroll"}, el("table", {class: "grid events", id: "events"},
          el("thead", {}, el("tr", {}, el("th", {class: "num"}, "t (s)"), el("th", {}, ""),
                              el("th", {}, "row"), el("th", {}, "what"), el("th", {}, "detail"))),
          el("tbody", {}, rowsOf.map((m) => el("tr", {class: m.level === "alarm" || m.level === "critical" || m.level === "rejected" ? "bad" : ""},
            el("td", {class: "num"}, num(m.t, 2)),
            el("td", {}, AD.markIcon(m.kind, AD.LEVEL_COLOUR[m.level])),
            el("td", {}, T.rows[m.row]),
            el("td", {class: "mono"}, m.label),
            el("td", {}, m.detail || ""))))))
      : null);
  if (T.rows.length) pending.push(() => timelineChart(timelineBox));
  const lampsBox = el("div", {class: "chart", id: "all-lamps"});
  const lampsCard = card("Lamps of every head", lampsBox);
  if (Object.keys(D.heads || {}).length) pending.push(() => allLampsChart(lampsBox));
  else lampsBox.append(el("p", {class: "note"}, "No lamp was logged (logs/lamps.csv)."));

  // ---- The scenario file, notes ----
  const more = [];
  if ((D.notes || []).length) more.push(el("ul", {class: "notes"}, D.notes.map((n) => el("li", {}, n))));
  if (scenario.text) more.push(el("details", {}, el("summary", {}, "Scenario file"), el("pre", {}, scenario.text)));
  if (inv.command_line) {
    more.push(el("details", {}, el("summary", {}, "Invocation"),
      el("pre", {}, `${(inv.command_line || []).join(" ")}\nout: ${inv.out}\npartition: ${inv.partition}\nlauncher exit: ${inv.launcher_exit}`)));
  }
  page.append(
    el("div", {class: "grid2 charts"}, mapCard, el("div", {class: "stack"}, expectations, speedCard)),
    eventsCard,
    lampsCard,
    el("div", {class: "grid2"}, vehiclesCard, runCard),
    more.length ? card("Files", more) : "",
    el("footer", {}, "autodrive-scenario report · charts by uPlot 1.6.32 (MIT) · no network needed"));

  for (const make of pending) make();

  // ---- Charts ----

  function mapChart(box) {
    const W = D.world;
    if (!W || !W.bounds) {
      box.append(el("p", {class: "note"}, "No map: logs/world.json is missing."));
      return;
    }
    let [x0, y0, x1, y1] = W.bounds;
    for (const c of cars) {
      for (let i = 0; i < c.track.x.length; i++) {
        x0 = Math.min(x0, c.track.x[i]); x1 = Math.max(x1, c.track.x[i]);
        y0 = Math.min(y0, c.track.y[i]); y1 = Math.max(y1, c.track.y[i]);
      }
    }
    const pad = 0.03 * Math.max(x1 - x0, y1 - y0, 0.5);
    const full = {x0: x0 - pad, x1: x1 + pad, y0: y0 - pad, y1: y1 + pad};
    let view = Object.assign({}, full);
    // The ranges that show `view` whole at one scale in the plot's box (device pixels).
    const fit = (u) => {
      const w = u.bbox.width, h = u.bbox.height;
      if (!(w > 0 && h > 0)) return {x: [view.x0, view.x1], y: [view.y0, view.y1]};
      const s = Math.max((view.x1 - view.x0) / w, (view.y1 - view.y0) / h);
      const cx = (view.x0 + view.x1) / 2, cy = (view.y0 + view.y1) / 2;
      return {x: [cx - s * w / 2, cx + s * w / 2], y: [cy - s * h / 2, cy + s * h / 2]};
    };
    const apply = (u) => {
      const r = fit(u);
      u.batch(() => {
        u.setScale("x", {min: r.x[0], max: r.x[1]});
        u.setScale("y", {min: r.y[0], max: r.y[1]});
      });
    };
    const X = (u, v) => u.valToPos(v, "x", true), Y = (u, v) => u.valToPos(v, "y", true);
    const perMetre = (u) => Math.abs(X(u, 1) - X(u, 0));
    const polyline = (u, path, xs, ys) => {
      for (let i = 0; i < xs.length; i++) {
        if (i === 0) path.moveTo(X(u, xs[i]), Y(u, ys[i]));
        else path.lineTo(X(u, xs[i]), Y(u, ys[i]));
      }
    };
    const series = [{}];
    const data = [null];
    const add = (opts, points) => {
      series.push(Object.assign({facets: [{scale: "x", auto: true}, {scale: "y", auto: true}],
                                 points: {show: false}}, opts));
      data.push(points.length ? [points.map((p) => p[0]), points.map((p) => p[1])] : [[full.x0], [full.y0]]);
    };
    const pointsOf = (shapes) => shapes.flatMap((s) => s.x.map((x, i) => [x, s.y[i]]));
    add({label: "centre lines", stroke: "#aab2bd", width: 1, paths: (u) => {
      const p = new Path2D();
      for (const l of W.lanes) polyline(u, p, l.x, l.y);
      return {stroke: p, fill: null, clip: null, flags: 0};
    }}, pointsOf(W.lanes));
    const obstacles = W.statics.filter((s) => s.kind === "obstacle" && !s.timed);
    const timed = W.statics.filter((s) => s.kind === "obstacle" && s.timed);
    const walls = W.statics.filter((s) => s.kind !== "obstacle");
    const shapes = (list) => (u) => {
      const p = new Path2D();
      for (const s of list) { polyline(u, p, s.x, s.y); p.closePath(); }
      return {stroke: p, fill: p, clip: null, flags: 0};
    };
    if (walls.length) {
      add({label: "walls and boxes", stroke: "#8a939e", fill: "#c9ced6", width: 1, paths: shapes(walls)},
          pointsOf(walls));
    }
    if (obstacles.length) {
      add({label: "unmapped obstacles", stroke: "#9a3412", fill: "#fb923c", width: 1.5,
           paths: shapes(obstacles)}, pointsOf(obstacles));
    }
    if (timed.length) {
      add({label: "obstacles placed or removed mid-run", stroke: "#9a3412", fill: "#fed7aa",
           width: 1.5, dash: [4, 3], paths: shapes(timed)}, pointsOf(timed));
    }
    add({label: "stop lines", stroke: "#1f2933", width: 3, paths: (u) => {
      const signal = new Path2D(), stop = new Path2D();
      for (const l of W.stop_lines) polyline(u, l.control === "stop" ? stop : signal, l.x, l.y);
      return {stroke: new Map([["#1f2933", signal], ["#b91c1c", stop]]), fill: null, clip: null, flags: 0};
    }}, pointsOf(W.stop_lines));
    add({label: "routes", stroke: "#94a3b8", width: 1.5, dash: [6, 4], paths: (u) => {
      const m = new Map();
      for (const c of cars) {
        if (!c.route.x.length) continue;
        const p = new Path2D();
        polyline(u, p, c.route.x, c.route.y);
        m.set(colour[c.name] + "80", p);
      }
      return {stroke: m, fill: null, clip: null, flags: 0};
    }}, cars.flatMap((c) => c.route.x.map((x, i) => [x, c.route.y[i]])));
    const firstCar = series.length;
    for (const c of cars) {
      add({label: c.name, stroke: colour[c.name], width: 2.5, paths: (u) => {
        const p = new Path2D();
        polyline(u, p, c.track.x, c.track.y);
        return {stroke: p, fill: null, clip: null, flags: 0};
      }}, c.track.x.map((x, i) => [x, c.track.y[i]]));
    }
    const marks = cars.flatMap((c) => c.marks.filter((m) => m.x != null));
    const marksSeries = series.length;
    add({label: "infractions", stroke: "#dc2626", width: 0, paths: () => ({stroke: null, fill: null, clip: null, flags: 0})},
        marks.map((m) => [m.x, m.y]));

    let cursorT = null;  // null: the end
    const roads = (u) => {
      const ctx = u.ctx;
      ctx.save();
      ctx.beginPath();
      ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
      ctx.clip();
      ctx.strokeStyle = "#edf0f3";
      ctx.lineCap = "round";
      ctx.lineJoin = "round";
      const k = perMetre(u);
      for (const l of W.lanes) {
        ctx.lineWidth = Math.max(1, l.width_m * k);
        const p = new Path2D();
        polyline(u, p, l.x, l.y);
        ctx.stroke(p);
      }
      ctx.restore();
    };
    const over = (u) => {
      const ctx = u.ctx;
      const px = uPlot.pxRatio;
      ctx.save();
      ctx.beginPath();
      ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
      ctx.clip();
      // The heads' numbers beside their stop lines.
      if (u.series[series.findIndex((s) => s.label === "stop lines")].show) {
        ctx.font = `${10 * px}px ${AD.sans()}`;
        ctx.fillStyle = "#475569";
        for (const l of W.stop_lines) {
          if (!l.heads.length) continue;
          // Past the line's end, along it.
          const ax = X(u, l.x[0]), ay = Y(u, l.y[0]), bx = X(u, l.x[1]), by = Y(u, l.y[1]);
          const n = Math.hypot(bx - ax, by - ay) || 1, dx = (bx - ax) / n, dy = (by - ay) / n;
          ctx.textAlign = dx > 0.4 ? "left" : dx < -0.4 ? "right" : "center";
          ctx.textBaseline = dy > 0.4 ? "top" : dy < -0.4 ? "bottom" : "middle";
          ctx.fillText("h" + l.heads.join(",h"), bx + dx * 4 * px, by + dy * 4 * px);
        }
      }
      // Each car: where it started, and its body at the cursor's time (the end otherwise).
      cars.forEach((c, ci) => {
        if (!u.series[firstCar + ci].show || !c.track.t.length) return;
        const t = c.track.t;
        let i = t.length - 1;
        if (cursorT != null) {
          let lo = 0, hi = t.length - 1;
          while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (t[mid] <= cursorT) lo = mid; else hi = mid - 1; }
          i = lo;
        }
        ctx.fillStyle = "#ffffff";
        ctx.strokeStyle = colour[c.name];
        ctx.lineWidth = 2 * px;
        ctx.beginPath();
        ctx.arc(X(u, c.track.x[0]), Y(u, c.track.y[0]), 4 * px, 0, 2 * Math.PI);
        ctx.fill();
        ctx.stroke();
        const yaw = c.track.yaw[i], cos = Math.cos(yaw), sin = Math.sin(yaw);
        const cx = c.track.x[i] + c.centre_ahead_m * cos, cy = c.track.y[i] + c.centre_ahead_m * sin;
        const hl = c.length_m / 2, hw = c.width_m / 2;
        const corner = (a, b) => [X(u, cx + a * cos - b * sin), Y(u, cy + a * sin + b * cos)];
        const body = [corner(-hl, -hw), corner(hl, -hw), corner(hl, hw), corner(-hl, hw)];
        ctx.beginPath();
        body.forEach(([x, y], j) => j ? ctx.lineTo(x, y) : ctx.moveTo(x, y));
        ctx.closePath();
        ctx.fillStyle = colour[c.name] + "cc";
        ctx.fill();
        ctx.strokeStyle = "#ffffff";
        ctx.lineWidth = 1.5 * px;
        ctx.stroke();
        // its front
        const [fx, fy] = corner(hl, 0);
        ctx.beginPath();
        ctx.arc(fx, fy, 2.5 * px, 0, 2 * Math.PI);
        ctx.fillStyle = "#ffffff";
        ctx.fill();
        ctx.font = `600 ${11 * px}px ${AD.sans()}`;
        ctx.fillStyle = colour[c.name];
        ctx.textBaseline = "bottom";
        ctx.textAlign = "left";
        ctx.fillText(cursorT != null ? `${c.name} ${num(t[i], 2)} s` : c.name,
                     X(u, cx) + 8 * px, Y(u, cy) - 6 * px);
      });
      if (u.series[marksSeries].show) {
        for (const m of marks) AD.drawMark(ctx, m.kind, X(u, m.x), Y(u, m.y), 14 * px);
      }
      ctx.restore();
    };
    const height = (w) => {
      const plotW = w - 70;
      const aspect = (full.y1 - full.y0) / Math.max(full.x1 - full.x0, 1e-6);
      return Math.round(Math.min(680, Math.max(320, plotW * aspect + 50)));
    };
    const w = AD.widthOf(box);
    const opts = {
      mode: 2, width: w, height: height(w),
      scales: {x: {time: false, range: (u) => fit(u).x}, y: {range: (u) => fit(u).y}},
      axes: [AD.axis({label: "x (m)", labelSize: 18, size: 34, space: 60}),
             AD.axis({label: "y (m)", labelSize: 18, size: 46, space: 40})],
      series,
      legend: {live: false},
      cursor: {points: {show: false}, drag: {x: true, y: true, setScale: false},
               bind: {dblclick: (u) => () => { view = Object.assign({}, full); apply(u); return null; }}},
      hooks: {
        drawClear: [roads],
        draw: [over],
        ready: [apply],
        setSelect: [(u) => {
          const s = u.select;
          if (s.width < 4 || s.height < 4) return;
          const xa = u.posToVal(s.left, "x"), xb = u.posToVal(s.left + s.width, "x");
          const ya = u.posToVal(s.top + s.height, "y"), yb = u.posToVal(s.top, "y");
          view = {x0: Math.min(xa, xb), x1: Math.max(xa, xb), y0: Math.min(ya, yb), y1: Math.max(ya, yb)};
          u.setSelect({left: 0, top: 0, width: 0, height: 0}, false);
          apply(u);
        }],
      },
    };
    const u = new uPlot(opts, data, box);
    AD.track(u, box, height, apply);
    AD.onCursorTime((t) => { cursorT = t; u.redraw(false); });
  }

  // The speed chart of a car, with its infractions and stop-line crossings as marks.
  function speedChart(c, box) {
    const w = AD.widthOf(box);
    const col = colour[c.name];
    const marks = c.marks;
    const lines = c.stop_lines.filter((l) => l.t_cross != null);
    const draw = (u) => {
      const ctx = u.ctx, px = uPlot.pxRatio;
      ctx.save();
      ctx.beginPath();
      ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
      ctx.clip();
      ctx.font = `${10 * px}px ${AD.sans()}`;
      ctx.textBaseline = "top";
      ctx.textAlign = "left";
      for (const l of lines) {
        const x = u.valToPos(l.t_cross, "x", true);
        ctx.strokeStyle = "#94a3b8";
        ctx.setLineDash([3 * px, 3 * px]);
        ctx.lineWidth = px;
        ctx.beginPath();
        ctx.moveTo(x, u.bbox.top);
        ctx.lineTo(x, u.bbox.top + u.bbox.height);
        ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = "#64707d";
        const text = `${l.control === "stop" ? "stop sign" : "stop line"} ${l.intersection}`;
        const right = x + 3 * px + ctx.measureText(text).width > u.bbox.left + u.bbox.width;
        ctx.textAlign = right ? "right" : "left";
        ctx.fillText(text, right ? x - 3 * px : x + 3 * px, u.bbox.top + 2 * px);
      }
      for (const m of marks) {
        const x = u.valToPos(m.t, "x", true);
        const v = valueAt(c.track, m.t);
        AD.drawMark(ctx, m.kind, x, u.valToPos(v, "y", true), 13 * px);
      }
      ctx.restore();
    };
    const vmin = Math.min(0, ...c.track.v), vmax = Math.max(0.05, ...c.track.v);
    const opts = AD.merge(AD.timeOptions(endS), {
      width: w, height: 170,
      series: [{label: "t (s)", value: (u, v) => v == null ? "—" : num(v, 2) + " s"},
               {label: "speed", stroke: col, width: 2, fill: col + "14",
                value: (u, v) => v == null ? "—" : num(v, 3) + " m/s"}],
      axes: [AD.axis({size: 30}), AD.axis({label: "m/s", labelSize: 14, size: 50, space: 30})],
      scales: {y: {range: () => [vmin, vmax * 1.12]}},
      hooks: {draw: [draw]},
    });
    const u = new uPlot(opts, [c.track.t, c.track.v], box);
    AD.track(u, box, 170);
    AD.timeChart(u);
  }

  function valueAt(track, t) {
    const ts = track.t;
    if (!ts.length) return 0;
    let lo = 0, hi = ts.length - 1;
    while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (ts[mid] <= t) lo = mid; else hi = mid - 1; }
    return track.v[lo];
  }

  // The lamps of the heads on a car's way: one row per head, bands along time, a black tick
  // where the car's front crossed the head's stop line.
  function lampChart(c, box) {
    const rows = [];
    for (const l of c.stop_lines) {
      for (const h of l.heads) {
        if (!rows.some((r) => r.head === h)) rows.push({head: h, label: `h${h}`, tick: l.t_cross});
      }
    }
    if (!rows.length) {
      box.append(el("p", {class: "note"}, "No signalised stop line on this car's way: no lamp to show."));
      return;
    }
    lampStrip(rows, box, 64);
    box.append(el("p", {class: "caption"}, "Lamps of the heads facing its stop lines: ",
      c.stop_lines.filter((l) => l.heads.length).map((l, i) => [i ? "; " : "",
        el("b", {}, l.heads.map((h) => "h" + h).join(", ")), ` at ${l.intersection} from ${l.lane}`,
        l.t_cross != null ? ` (its front crosses at ${num(l.t_cross, 2)} s: black tick)` : " (not crossed)"])));
  }

  // Every head of the city, one row each.
  function allLampsChart(box) {
    const facing = {};
    for (const l of (D.world || {}).stop_lines || []) {
      for (const h of l.heads) facing[h] = `${l.intersection} from ${l.lane}`;
    }
    const ids = Object.keys(D.heads || {}).map(Number).sort((a, b) => a - b);
    lampStrip(ids.map((h) => ({head: h, label: `h${h}`, tick: null})), box, rowAxis);
    box.append(el("p", {class: "caption"}, ids.map((h, i) => [i ? "; " : "", el("b", {}, "h" + h),
      facing[h] ? ` ${facing[h]}` : ""])));
  }

  // Rows of lamp bands on the run's time axis (synced with the other time charts).
  function lampStrip(rows, box, axisSize) {
    const heads = D.heads || {};
    const rowH = 16;
    const height = 26 + rows.length * (rowH + 4);
    const draw = (u) => {
      const ctx = u.ctx, px = uPlot.pxRatio;
      ctx.save();
      ctx.beginPath();
      ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
      ctx.clip();
      rows.forEach((r, i) => {
        const yc = u.valToPos(rows.length - i - 0.5, "y", true);
        const hh = rowH * px;
        const bands = (heads[String(r.head)] || {}).bands || [];
        for (const [from, to, aspect] of bands) {
          const xa = u.valToPos(from, "x", true), xb = u.valToPos(to, "x", true);
          if (xb < u.bbox.left || xa > u.bbox.left + u.bbox.width) continue;
          ctx.fillStyle = AD.lampFill(ctx, aspect);
          ctx.fillRect(xa, yc - hh / 2, Math.max(xb - xa, px), hh);
          if (aspect === 4 || aspect === 5) {
            ctx.strokeStyle = AD.LAMP[aspect];
            ctx.lineWidth = px;
            ctx.strokeRect(xa + px / 2, yc - hh / 2 + px / 2, Math.max(xb - xa - px, px), hh - px);
          }
        }
        if (r.tick != null) {
          const x = u.valToPos(r.tick, "x", true);
          ctx.strokeStyle = "#111827";
          ctx.lineWidth = 2 * px;
          ctx.beginPath();
          ctx.moveTo(x, yc - hh / 2 - 2 * px);
          ctx.lineTo(x, yc + hh / 2 + 2 * px);
          ctx.stroke();
        }
      });
      ctx.restore();
    };
    const opts = AD.merge(AD.timeOptions(endS), {
      width: AD.widthOf(box), height,
      series: [{label: "t (s)"}, {label: "lamps", scale: "y", stroke: "#000000", width: 0,
                paths: () => null, points: {show: false}}],
      axes: [AD.axis({size: 22, grid: {show: false}}),
             AD.axis({size: axisSize, grid: {show: false}, ticks: {show: false}, gap: 6,
                      splits: () => rows.map((_, i) => rows.length - i - 0.5),
                      values: () => rows.map((r) => r.label)})],
      scales: {y: {auto: false, range: () => [0, rows.length]}},
      legend: {show: false},
      hooks: {draw: [draw]},
    });
    const u = new uPlot(opts, [[0, endS], [null, null]], box);
    AD.track(u, box, height);
    AD.timeChart(u);
  }

  function timelineChart(box) {
    const rows = T.rows;
    const rowH = 30;
    const height = 46 + rows.length * rowH;
    const yOf = (u, i) => u.valToPos(rows.length - i - 0.5, "y", true);
    const draw = (u) => {
      const ctx = u.ctx, px = uPlot.pxRatio;
      ctx.save();
      ctx.beginPath();
      // A mark at 0 s or at the end is drawn whole.
      ctx.rect(u.bbox.left - 8 * px, u.bbox.top, u.bbox.width + 16 * px, u.bbox.height);
      ctx.clip();
      ctx.strokeStyle = AD.GRID;
      ctx.lineWidth = px;
      rows.forEach((_, i) => {
        const y = yOf(u, i);
        ctx.beginPath();
        ctx.moveTo(u.bbox.left, y);
        ctx.lineTo(u.bbox.left + u.bbox.width, y);
        ctx.stroke();
      });
      ctx.font = `${10.5 * px}px ${AD.sans()}`;
      ctx.textBaseline = "middle";
      ctx.textAlign = "left";
      // Marks first; then labels where they cover neither a mark nor another label, the
      // infractions' and alarms' first.
      const taken = rows.map(() => []);
      const shown = [];
      for (const m of rowsOf) {
        const x = u.valToPos(m.t, "x", true);
        if (x < u.bbox.left - 10 || x > u.bbox.left + u.bbox.width + 10) continue;
        AD.drawMark(ctx, m.kind, x, yOf(u, m.row), 12 * px, AD.LEVEL_COLOUR[m.level]);
        taken[m.row].push([x - 7 * px, x + 7 * px]);
        shown.push([m, x]);
      }
      const rank = (m) => m.level === "alarm" || m.level === "critical" || m.level === "rejected" ? 0 : m.kind === "stop_line" ? 2 : 1;
      shown.sort((a, b) => rank(a[0]) - rank(b[0]) || a[1] - b[1]);
      const free = (row, a, b) => a >= u.bbox.left && b <= u.bbox.left + u.bbox.width &&
        !taken[row].some(([p, q]) => a < q && b > p);
      for (const [m, x] of shown) {
        const w = ctx.measureText(m.label).width + 4 * px;
        // Right of the mark (past marks packed against it), else left of it.
        let x0 = x + 8 * px;
        for (const [a, b] of taken[m.row].slice().sort((p, q) => p[0] - q[0])) {
          if (a < x0 + 4 * px && b > x0 && b - a < 16 * px) x0 = b + 2 * px;
        }
        if (!free(m.row, x0, x0 + w)) {
          x0 = x - 8 * px - w;
          if (!free(m.row, x0, x0 + w)) continue;
        }
        taken[m.row].push([x0, x0 + w]);
        ctx.fillStyle = m.level === "alarm" || m.level === "critical" ? "#b91c1c" : AD.INK;
        ctx.fillText(m.label, x0 + 2 * px, yOf(u, m.row));
      }
      ctx.restore();
    };
    const opts = AD.merge(AD.timeOptions(endS), {
      width: AD.widthOf(box), height,
      series: [{label: "t (s)"}, {label: "events", scale: "y", stroke: "#000000", width: 0,
                paths: () => null, points: {show: false}}],
      axes: [AD.axis({label: "simulated time (s)", labelSize: 16, size: 26}),
             AD.axis({size: rowAxis, grid: {show: false}, ticks: {show: false},
                      splits: () => rows.map((_, i) => rows.length - i - 0.5),
                      values: () => rows.slice()})],
      scales: {y: {auto: false, range: () => [0, rows.length]}},
      legend: {show: false},
      hooks: {draw: [draw]},
    });
    const u = new uPlot(opts, [[0, endS], [null, null]], box);
    AD.track(u, box, height);
    AD.timeChart(u);
  }

  window.reportReady = true;
})();
