// summary.html: a sweep's runs, drawn from the page's data (summary.json, completed by
// scenarios/internal/report_data.h) with uPlot 1.6.32.
//
// - The sweep and its counts; the variants side by side (per metric: mean ± std, worst, n).
// - Each metric's distribution per variant: a uPlot chart in x/y mode (`mode: 2`), one column
//   per variant with a point per run (spread across the column in the order of the runs; a
//   failed run ringed in red), and the mean ± std drawn over it (hook `draw`).
// - Every run with its result and a link to its report.html (relative, as summary.json gives it).
"use strict";

(() => {
  const {el, num, card} = AD;
  const S = AD.data();
  const page = document.getElementById("page");
  const variants = S.variants || [];
  const metrics = S.metrics || [];
  const colourOf = (i) => AD.CAR_COLOURS[i % AD.CAR_COLOURS.length];
  const sweep = S.sweep || {};
  const allRuns = variants.flatMap((v) => (v.runs || []).map((r) => Object.assign({variant: v.name}, r)));
  // A run that could not be made (its city did not come up, a process failed: report.json's
  // end reason "failed", or exit code 2) is not a run that failed an expectation.
  const notMade = (r) => r.end === "failed" || r.exit_code === 2;
  const failedExpectation = (r) => !notMade(r) && r.passed === false;
  const passedRuns = allRuns.filter((r) => r.passed === true).length;
  const badRuns = allRuns.filter((r) => r.passed !== true).length;
  document.title = `${sweep.name || "sweep"} — ${allRuns.length} runs, ${badRuns} failed`;

  // ---- Header ----
  const count = (value, label, cls) => el("div", {class: "count " + (cls || "")}, el("b", {}, value == null ? "—" : String(value)), el("span", {}, label));
  const failedCount = allRuns.filter(failedExpectation).length;
  page.append(el("header", {class: "top"},
    el("div", {class: "title"}, el("h1", {}, sweep.name || "sweep"),
       el("span", {class: "verdict " + (badRuns ? "fail" : "pass"), id: "verdict"},
          badRuns ? `${badRuns} OF ${allRuns.length} RUNS FAILED` : "ALL RUNS PASSED")),
    sweep.file ? el("p", {class: "file mono"}, sweep.file) : null,
    sweep.scenario ? el("p", {class: "file mono"}, "scenario: " + sweep.scenario) : null,
    el("div", {class: "counts"},
       count(S.runs_total, "runs in the sweep"),
       count(S.runs_done, "runs done", "ok"),
       count(S.runs_failed, "runs that could not be made", (S.runs_failed || 0) > 0 ? "bad" : ""),
       count(failedCount, "failed an expectation", failedCount ? "bad" : ""),
       count(passedRuns, "passed every expectation"),
       count(variants.length, "variants"))));

  // ---- Variants side by side ----
  const params = (v) => Object.entries(v.parameters || {})
    .filter(([k, x]) => !(Array.isArray(x) && !x.length))
    .map(([k, x]) => `${k}: ${typeof x === "string" ? x : Array.isArray(x) ? x.join(" ") : JSON.stringify(x)}`).join(" · ");
  const statCell = (st) => {
    if (!st || !st.n) return el("td", {class: "num stat"}, "—", el("span", {class: "sub"}, "n 0"));
    return el("td", {class: "num stat"},
      el("b", {}, num(st.mean)), st.std != null ? ` ± ${num(st.std)}` : "",
      el("span", {class: "sub"}, `worst ${num(st.worst)} · min ${num(st.min)} · max ${num(st.max)} · n ${st.n}`));
  };
  page.append(card("Variants side by side",
    el("table", {class: "grid", id: "variants"},
      el("thead", {}, el("tr", {}, el("th", {}, "metric"),
        variants.map((v, i) => el("th", {class: "num"},
          el("span", {class: "chip", style: {background: colourOf(i)}}), v.name,
          el("span", {class: "params"}, params(v)))))),
      el("tbody", {},
        el("tr", {}, el("th", {}, "runs passed"), variants.map((v) => {
          const runs = v.runs || [];
          const ok = runs.filter((r) => r.passed === true).length;
          return el("td", {class: "num" + (ok < runs.length ? " bad" : "")}, `${ok} of ${runs.length}`);
        })),
        metrics.map((m) => el("tr", {}, el("th", {class: "mono"}, m, el("span", {class: "sub"}, AD.unit(m) ? ` (${AD.unit(m)})` : "")),
          variants.map((v) => statCell((v.stats || {})[m]))))))));

  // ---- Distributions ----
  const grid = el("div", {class: "dist"});
  page.append(card("Distributions per variant (a point per run; bar: mean ± std; red ring: a failed run)", grid));
  const boxes = metrics.map((m) => {
    const box = el("div", {class: "chart"});
    const missing = allRuns.filter((r) => !r.metrics || r.metrics[m] == null).length;
    grid.append(el("div", {}, el("h3", {}, el("span", {class: "mono"}, m),
      el("span", {class: "sub"}, (AD.unit(m) ? ` ${AD.unit(m)}` : "") + (missing ? ` · ${missing} run(s) not measured` : ""))), box));
    return box;
  });

  // ---- Runs ----
  page.append(card("Runs",
    el("div", {class: "scroll tall"}, el("table", {class: "grid runs", id: "runs"},
      el("thead", {}, el("tr", {}, el("th", {}, "variant"), el("th", {}, "run"), el("th", {class: "num"}, "seed"),
        el("th", {}, "result"), el("th", {}, "report"), el("th", {}, "end"),
        metrics.map((m) => el("th", {class: "num mono"}, m)))),
      el("tbody", {}, allRuns.map((r) => {
        const bad = r.passed !== true;
        const result = notMade(r) ? "✗ NOT MADE" : bad ? "✗ FAILED" : "✓ passed";
        return el("tr", {class: bad ? "bad" : ""},
          el("td", {}, r.variant), el("td", {class: "mono"}, r.id || "—"), el("td", {class: "num"}, num(r.seed)),
          el("td", {}, el("span", {class: bad ? "failed-marker" : "passed-marker"}, result)),
          el("td", {}, r.html ? el("a", {href: AD.href(r.html)}, "report.html") : "—"),
          el("td", {}, r.end != null ? String(r.end) : r.exit_code != null ? `exit ${r.exit_code}` : "—"),
          metrics.map((m) => el("td", {class: "num"}, num((r.metrics || {})[m]))));
      }))))));
  page.append(el("footer", {}, "autodrive-scenario sweep summary · charts by uPlot 1.6.32 (MIT) · no network needed"));

  metrics.forEach((m, mi) => distribution(m, boxes[mi]));

  function distribution(m, box) {
    const series = [{}];
    const data = [null];
    let lo = Infinity, hi = -Infinity;
    const failedPts = [];
    variants.forEach((v, vi) => {
      const runs = (v.runs || []).filter((r) => r.metrics && typeof r.metrics[m] === "number");
      const xs = [], ys = [];
      runs.forEach((r, j) => {
        const x = vi + (runs.length > 1 ? ((j + 0.5) / runs.length - 0.5) * 0.56 : 0);
        xs.push(x);
        ys.push(r.metrics[m]);
        lo = Math.min(lo, r.metrics[m]);
        hi = Math.max(hi, r.metrics[m]);
        if (r.passed !== true) failedPts.push([x, r.metrics[m]]);
      });
      const col = colourOf(vi);
      series.push({label: v.name, stroke: col, fill: col + "99", facets: [{scale: "x", auto: false}, {scale: "y", auto: true}],
        points: {show: false},
        paths: (u, si) => {
          const p = new Path2D();
          const d = u.data[si];
          const r = 3.2 * uPlot.pxRatio;
          for (let i = 0; i < d[0].length; i++) {
            const cx = u.valToPos(d[0][i], "x", true), cy = u.valToPos(d[1][i], "y", true);
            p.moveTo(cx + r, cy);
            p.arc(cx, cy, r, 0, 2 * Math.PI);
          }
          return {stroke: p, fill: p, clip: null, flags: 0};
        }});
      data.push(xs.length ? [xs, ys] : [[vi], [null]]);
    });
    if (!isFinite(lo)) {
      box.append(el("p", {class: "note"}, "No run measured it."));
      return;
    }
    const pad = hi > lo ? (hi - lo) * 0.12 : Math.max(Math.abs(hi) * 0.25, 0.5);
    // Counts and fractions are not negative: no axis below zero for them.
    const bottom = lo >= 0 ? Math.max(lo - pad, -pad * 0.15) : lo - pad;
    const draw = (u) => {
      const ctx = u.ctx, px = uPlot.pxRatio;
      ctx.save();
      variants.forEach((v, vi) => {
        const st = (v.stats || {})[m];
        if (!st || !st.n || st.mean == null) return;
        const xa = u.valToPos(vi - 0.36, "x", true), xb = u.valToPos(vi + 0.36, "x", true);
        const ym = u.valToPos(st.mean, "y", true);
        const sd = st.std || 0;
        const ya = u.valToPos(st.mean - sd, "y", true), yb = u.valToPos(st.mean + sd, "y", true);
        ctx.fillStyle = colourOf(vi) + "1f";
        ctx.fillRect(xa, yb, xb - xa, Math.max(ya - yb, px));
        ctx.strokeStyle = colourOf(vi);
        ctx.lineWidth = 2 * px;
        ctx.beginPath();
        ctx.moveTo(xa, ym);
        ctx.lineTo(xb, ym);
        ctx.stroke();
      });
      ctx.strokeStyle = "#dc2626";
      ctx.lineWidth = 1.8 * px;
      for (const [x, y] of failedPts) {
        ctx.beginPath();
        ctx.arc(u.valToPos(x, "x", true), u.valToPos(y, "y", true), 6 * px, 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.restore();
    };
    const height = 210;
    const opts = {
      mode: 2, width: AD.widthOf(box), height,
      scales: {x: {time: false, auto: false, range: () => [-0.5, variants.length - 0.5]},
               y: {range: () => [bottom, hi + pad]}},
      axes: [AD.axis({size: 28, grid: {show: false}, splits: () => variants.map((_, i) => i),
                      values: () => variants.map((v) => v.name)}),
             AD.axis({size: 56})],
      series,
      legend: {show: false},
      cursor: {points: {show: false}, drag: {x: false, y: false}},
      hooks: {draw: [draw]},
    };
    const u = new uPlot(opts, data, box);
    AD.track(u, box, height);
  }

  window.reportReady = true;
})();
