// What report.html and summary.html share: the page's data, DOM and number helpers, the colours
// (one per car, the lamps' own), the marks drawn for infractions and events, and the charts'
// common options (uPlot 1.6.32, inline before this script as the global `uPlot`). Charts follow
// their card's width, on screen and when printed. No network: nothing here loads anything.
"use strict";

const AD = (() => {
  // One colour per car, none of them a lamp's (red, yellow, green) so that a car never reads as
  // a light.
  const CAR_COLOURS = ["#2563eb", "#9333ea", "#0e7490", "#c026d3", "#4338ca", "#0f766e",
                       "#be185d", "#1e3a8a", "#6d28d9", "#334155"];
  // Aspects as common/aspect.h numbers them: 0 off, 1 red, 2 yellow, 3 green, 4 flashing red,
  // 5 flashing yellow.
  const LAMP = {0: "#3f4652", 1: "#dc2626", 2: "#f5b400", 3: "#16a34a", 4: "#dc2626", 5: "#f5b400"};
  const LAMP_NAME = {0: "dark", 1: "red", 2: "yellow", 3: "green", 4: "flashing red",
                     5: "flashing yellow"};
  const INK = "#1f2933", MUTED = "#64707d", GRID = "#e8ebef", AXIS_FONT = "11px " + sans();
  // What a mark's kind is drawn as (shape, colour), on the map, the speed charts and the time line.
  const MARKS = {
    collision: {shape: "cross", colour: "#111827", name: "collision"},
    red_light: {shape: "triangle", colour: "#dc2626", name: "red-light violation"},
    stop_sign: {shape: "octagon", colour: "#b91c1c", name: "stop-sign violation"},
    lane_departure: {shape: "diamond", colour: "#ea580c", name: "lane departure"},
    goal: {shape: "flag", colour: "#15803d", name: "goal reached"},
    stop_line: {shape: "tick", colour: "#64707d", name: "front crosses a stop line"},
    scenario: {shape: "diamond", colour: "#7c3aed", name: "scenario event applied"},
    spat: {shape: "square", colour: "#475569", name: "SPaT plan or status change"},
    event: {shape: "circle", colour: "#64707d", name: "SCM event"},
    request: {shape: "triangle", colour: "#2563eb", name: "V2I request"},
    status: {shape: "down", colour: "#2563eb", name: "V2I answer"},
  };
  const LEVEL_COLOUR = {warning: "#d97706", alarm: "#dc2626", critical: "#7f1d1d",
                        granted: "#16a34a", completed: "#16a34a", rejected: "#dc2626",
                        cancelled: "#64707d"};

  function sans() {
    return 'system-ui, -apple-system, "Segoe UI", "DejaVu Sans", "Liberation Sans", Arial, sans-serif';
  }

  function data() {
    return JSON.parse(document.getElementById("page-data").textContent);
  }

  // el("td", {class: "num", title: "..."}, child, "text", ...): children are nodes or text
  // (never parsed as HTML).
  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v == null || v === false) continue;
      if (k === "style" && typeof v === "object") Object.assign(e.style, v);
      else e.setAttribute(k, v === true ? "" : v);
    }
    for (const c of children.flat(Infinity)) {
      if (c == null || c === false) continue;
      e.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
    return e;
  }

  function num(x, digits) {
    if (x == null || typeof x !== "number" || !isFinite(x)) return "—";
    if (Number.isInteger(x) && digits == null) return String(x);
    const d = digits != null ? digits : Math.abs(x) >= 100 ? 1 : Math.abs(x) >= 1 ? 3 : 4;
    return x.toFixed(d).replace(/(\.\d*?[1-9])0+$|\.0+$/, "$1");
  }

  // The unit a metric's name ends with.
  function unit(key) {
    const units = [["_mps3", "m/s³"], ["_mps2", "m/s²"], ["_mps", "m/s"], ["_j_per_kg", "J/kg"],
                   ["_per_km", "/km"], ["_hz", "Hz"], ["_m", "m"], ["_s", "s"]];
    for (const [suffix, u] of units) if (key.endsWith(suffix)) return u;
    return "";
  }

  // A mark of `kind` centred at canvas pixels (x, y), `size` pixels across.
  function drawMark(ctx, kind, x, y, size, colour) {
    const m = MARKS[kind] || MARKS.event;
    const c = colour || m.colour;
    const r = size / 2;
    ctx.save();
    ctx.fillStyle = c;
    ctx.strokeStyle = "#ffffff";
    ctx.lineWidth = Math.max(1, size / 8);
    ctx.beginPath();
    switch (m.shape) {
      case "cross": {
        ctx.strokeStyle = "#ffffff";
        ctx.lineWidth = size / 2.2;
        ctx.lineCap = "round";
        ctx.moveTo(x - r * 0.7, y - r * 0.7); ctx.lineTo(x + r * 0.7, y + r * 0.7);
        ctx.moveTo(x + r * 0.7, y - r * 0.7); ctx.lineTo(x - r * 0.7, y + r * 0.7);
        ctx.stroke();
        ctx.strokeStyle = c;
        ctx.lineWidth = size / 4.5;
        ctx.stroke();
        ctx.restore();
        return;
      }
      case "triangle":
        ctx.moveTo(x, y - r); ctx.lineTo(x + r, y + r * 0.8); ctx.lineTo(x - r, y + r * 0.8);
        break;
      case "down":
        ctx.moveTo(x, y + r); ctx.lineTo(x + r, y - r * 0.8); ctx.lineTo(x - r, y - r * 0.8);
        break;
      case "diamond":
        ctx.moveTo(x, y - r); ctx.lineTo(x + r, y); ctx.lineTo(x, y + r); ctx.lineTo(x - r, y);
        break;
      case "square":
        ctx.rect(x - r * 0.8, y - r * 0.8, r * 1.6, r * 1.6);
        break;
      case "octagon":
        for (let i = 0; i < 8; i++) {
          const a = Math.PI / 8 + i * Math.PI / 4;
          ctx.lineTo(x + r * Math.cos(a), y + r * Math.sin(a));
        }
        break;
      case "flag":
        ctx.moveTo(x - r * 0.6, y + r); ctx.lineTo(x - r * 0.6, y - r);
        ctx.lineTo(x + r, y - r * 0.45); ctx.lineTo(x - r * 0.6, y + r * 0.1);
        break;
      case "tick":
        ctx.strokeStyle = c;
        ctx.lineWidth = Math.max(1.5, size / 6);
        ctx.moveTo(x, y - r); ctx.lineTo(x, y + r);
        ctx.stroke();
        ctx.restore();
        return;
      default:
        ctx.arc(x, y, r * 0.85, 0, 2 * Math.PI);
    }
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
    ctx.restore();
  }

  // A mark as a small picture for legends and tables.
  function markIcon(kind, colour) {
    const px = window.devicePixelRatio || 1;
    const c = el("canvas", {class: "mark-icon", width: 14 * px, height: 14 * px});
    const ctx = c.getContext("2d");
    drawMark(ctx, kind, 7 * px, 7 * px, 11 * px, colour);
    return c;
  }

  // Diagonal stripes of a colour on white: how a flashing aspect is drawn (a steady band is
  // plain colour).
  const patterns = {};
  function lampFill(ctx, aspect) {
    if (aspect !== 4 && aspect !== 5) return LAMP[aspect] || LAMP[0];
    const key = aspect + "@" + uPlot.pxRatio;
    if (!patterns[key]) {
      const n = Math.round(8 * uPlot.pxRatio);
      const tile = document.createElement("canvas");
      tile.width = tile.height = n;
      const t = tile.getContext("2d");
      t.fillStyle = "#ffffff";
      t.fillRect(0, 0, n, n);
      t.strokeStyle = LAMP[aspect];
      t.lineWidth = n * 0.35;
      t.beginPath();
      t.moveTo(-n, n * 2); t.lineTo(n * 2, -n);
      t.moveTo(-n, n); t.lineTo(n, -n);
      t.moveTo(0, n * 2); t.lineTo(n * 2, 0);
      t.stroke();
      patterns[key] = t;
    }
    return ctx.createPattern(patterns[key].canvas, "repeat");
  }

  function lampChip(aspect) {
    return el("span", {class: "lamp-chip lamp-" + aspect, title: LAMP_NAME[aspect]});
  }

  // Axis options in the pages' style.
  function axis(extra) {
    return Object.assign({
      stroke: MUTED, font: AXIS_FONT, labelFont: "600 11px " + sans(),
      grid: {stroke: GRID, width: 1}, ticks: {stroke: GRID, width: 1, size: 4},
    }, extra || {});
  }

  // The width of `text` in the axes' font, in CSS pixels (for an axis as wide as its labels).
  let measure = null;
  function textWidth(text) {
    if (!measure) {
      measure = document.createElement("canvas").getContext("2d");
      measure.font = AXIS_FONT;
    }
    return measure.measureText(String(text)).width;
  }

  // Charts follow their card's width (and a printed page's).
  const charts = [];
  function track(u, box, height, resized) {
    charts.push({u, box, height, resized});
  }
  function widthOf(box) {
    return Math.max(240, Math.floor(box.getBoundingClientRect().width));
  }
  function resizeAll() {
    for (const c of charts) {
      const w = widthOf(c.box);
      const h = typeof c.height === "function" ? c.height(w) : c.height;
      if (w !== c.u.width || h !== c.u.height) {
        c.u.setSize({width: w, height: h});
        if (c.resized) c.resized(c.u);
      }
    }
  }
  let pending = null;
  window.addEventListener("resize", () => {
    if (pending) cancelAnimationFrame(pending);
    pending = requestAnimationFrame(resizeAll);
  });
  window.addEventListener("beforeprint", resizeAll);
  window.addEventListener("afterprint", resizeAll);

  // Time charts share the cursor and the zoom: drag to zoom in on all, double-click for all.
  const timeCharts = [];
  let zooming = false;
  function timeChart(u) {
    timeCharts.push(u);
  }
  function onTimeScale(u, key) {
    if (key !== "x" || zooming) return;
    zooming = true;
    const {min, max} = u.scales.x;
    for (const other of timeCharts) {
      if (other !== u && (other.scales.x.min !== min || other.scales.x.max !== max)) {
        other.setScale("x", {min, max});
      }
    }
    zooming = false;
  }

  // Called with the time under the cursor of any time chart (null when it leaves).
  const cursorListeners = [];
  function onCursorTime(f) {
    cursorListeners.push(f);
  }
  function cursorTime(u) {
    const left = u.cursor.left;
    const t = left != null && left >= 0 ? u.posToVal(left, "x") : null;
    for (const f of cursorListeners) f(t);
  }

  // The options every time chart has: x is seconds since the run's start (not a date), one
  // cursor for all, zoom on all.
  function timeOptions(endS, extra) {
    return Object.assign({
      scales: {x: {time: false, range: (u, min, max) => [0, Math.max(endS, max || 0, 1e-3)]}},
      cursor: {sync: {key: "run-time", setSeries: false}, points: {show: false},
               drag: {x: true, y: false, setScale: true}},
      hooks: {setScale: [onTimeScale], setCursor: [cursorTime]},
    }, extra || {});
  }

  function merge(opts, extra) {
    const out = Object.assign({}, opts, extra);
    out.hooks = Object.assign({}, opts.hooks);
    for (const [k, v] of Object.entries(extra.hooks || {})) {
      out.hooks[k] = (out.hooks[k] || []).concat(v);
    }
    out.scales = Object.assign({}, opts.scales, extra.scales || {});
    return out;
  }

  function card(title, ...children) {
    return el("section", {class: "card"}, el("h2", {}, title), ...children);
  }

  // Relative or absolute paths as an href: each part percent-encoded, the slashes kept.
  function href(path) {
    return String(path).split("/").map(encodeURIComponent).join("/");
  }

  return {CAR_COLOURS, LAMP, LAMP_NAME, MARKS, LEVEL_COLOUR, INK, MUTED, GRID, AXIS_FONT,
          data, el, num, unit, drawMark, textWidth, markIcon, lampFill, lampChip, axis, track, widthOf,
          resizeAll, timeChart, onCursorTime, timeOptions, merge, card, href, sans};
})();
