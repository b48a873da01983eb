// autodrive dashboard: the browser side. Plain JavaScript, no library, no build step, no
// external resource. Protocol: docs/dashboard.md (server-sent events from /api/stream, actions
// to POST /api/action). Every event handler is guarded: a bad message shows the error badge in
// the header and never throws to the console.
'use strict';
(function () {
  const SVGNS = 'http://www.w3.org/2000/svg';
  const $ = (id) => document.getElementById(id);

  // ---------------------------------------------------------------- test/benchmark surface
  const dash = (window.dashboard = {
    connected: false,
    stateReceived: false,
    latencies: { lamps: [], spat: [], fleet: [], traffic: [] },
    messages: {},
    errors: 0,
    lastError: '',
    selected: null,
    // time spent in each event's handler (ms): [count, total, max]; for the benchmark
    handlerMs: {},
  });
  const LAT_KEEP = 1000; // per event, for tests and the benchmark
  const RECENT_KEEP = 200; // across events, for the header read-out
  const recentLat = [];

  // ---------------------------------------------------------------- small helpers
  const ESC = { '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' };
  function esc(v) {
    return v === null || v === undefined ? '' : String(v).replace(/[&<>"']/g, (c) => ESC[c]);
  }
  function num(v, dflt) {
    const n = typeof v === 'number' ? v : typeof v === 'string' && v !== '' ? Number(v) : NaN;
    return Number.isFinite(n) ? n : dflt;
  }
  function arr(v) {
    return Array.isArray(v) ? v : [];
  }
  function str(v) {
    return v === null || v === undefined ? '' : String(v);
  }
  // An id that refers to something: intersection, approach and group ids are never 0 (0 and ""
  // mean none in the messages).
  function isRef(v) {
    return v !== undefined && v !== null && v !== '' && v !== 0 && v !== '0';
  }
  function pad2(n) {
    return n < 10 ? '0' + n : String(n);
  }
  function fmtTime(sec) {
    const s = num(sec, NaN);
    if (!Number.isFinite(s)) return '--:--:--';
    const d = new Date(s * 1000);
    return pad2(d.getHours()) + ':' + pad2(d.getMinutes()) + ':' + pad2(d.getSeconds());
  }
  function fmtAge(s) {
    if (!Number.isFinite(s)) return '–';
    if (s < 1) return '<1s';
    if (s < 90) return Math.floor(s) + 's';
    if (s < 5400) return Math.floor(s / 60) + 'm';
    if (s < 172800) return Math.floor(s / 3600) + 'h';
    return Math.floor(s / 86400) + 'd';
  }
  function fmtHz(v) {
    const n = num(v, NaN);
    if (!Number.isFinite(n)) return '–';
    return n >= 10 ? n.toFixed(0) : n.toFixed(1);
  }
  const collator = new Intl.Collator(undefined, { numeric: true, sensitivity: 'base' });

  function fail(where, e) {
    dash.errors++;
    dash.lastError = where + ': ' + (e && e.message ? e.message : String(e));
    const b = $('errbadge');
    if (b) {
      b.hidden = false;
      b.textContent = dash.errors + (dash.errors === 1 ? ' error' : ' errors');
      b.title = dash.lastError + '\n(click to clear)';
    }
  }
  function guard(where, fn) {
    return function (a, b, c) {
      try {
        return fn(a, b, c);
      } catch (e) {
        fail(where, e);
        return undefined;
      }
    };
  }
  function attempt(where, fn) {
    try {
      fn();
    } catch (e) {
      fail(where, e);
    }
  }

  // The server's clock (s), estimated from the last message that carried one (`now` of spat
  // and fleet) plus the local time elapsed since; the local clock before any.
  const clock = { now: NaN, at: 0 };
  function noteNow(n) {
    const v = num(n, NaN);
    if (Number.isFinite(v)) {
      clock.now = v;
      clock.at = performance.now();
    }
  }
  function serverNow() {
    return Number.isFinite(clock.now)
      ? clock.now + (performance.now() - clock.at) / 1000
      : Date.now() / 1000;
  }

  // ---------------------------------------------------------------- colours and names
  const LAMP_FILL = ['#3a3f44', '#ff3b30', '#ffb000', '#2ee66b'];
  const LAMP_NAME = ['off', 'red', 'yellow', 'green'];
  function lampNum(v) {
    const n = num(v, 0);
    return Math.round(n);
  }
  const SG = {
    protected_movement_allowed: ['sg-green', 'green', '#2ee66b'],
    permissive_movement_allowed: ['sg-perm', 'perm. green', '#8fd694'],
    protected_clearance: ['sg-yellow', 'yellow', '#ffb000'],
    permissive_clearance: ['sg-yellow', 'yellow', '#ffb000'],
    caution_conflicting_traffic: ['sg-caution', 'caution', '#ffd54f'],
    stop_and_remain: ['sg-red', 'red', '#ff3b30'],
    stop_then_proceed: ['sg-redflash', 'stop → go', '#c2185b'],
    pre_movement: ['sg-pre', 'red+amber', '#ff7a1a'],
    dark: ['sg-dark', 'dark', '#2b3036'],
  };
  const SG_UNKNOWN = ['sg-unknown', 'n/a', '#555c66'];
  function sg(state) {
    return SG[state] || SG_UNKNOWN;
  }
  const SOURCES = ['eye', 'sim', 'odometry', 'fused', 'ips'];
  function sourceKey(s) {
    const v = str(s).toLowerCase();
    if (v.startsWith('sim')) return 'sim';
    if (v.startsWith('odom')) return 'odometry';
    return SOURCES.includes(v) ? v : 'other';
  }
  const SUMO_FILL = {
    passenger: '#7f95b8',
    private: '#7f95b8',
    taxi: '#c9b458',
    bus: '#d59a4a',
    coach: '#d59a4a',
    truck: '#a98b73',
    trailer: '#a98b73',
    delivery: '#a98b73',
    emergency: '#ff6b6b',
    authority: '#ff6b6b',
    bicycle: '#63c5a5',
    moped: '#63c5a5',
    motorcycle: '#63c5a5',
    pedestrian: '#e8e8e8',
  };
  const SUMO_OTHER = '#9aa3ad';
  const PALETTE = ['#4fc3f7', '#ffb74d', '#81c784', '#e57373', '#ba68c8', '#fff176', '#4db6ac', '#f06292'];
  const SEV_NAME = ['info', 'warning', 'alarm', 'critical'];
  const SEV_SHORT = ['info', 'warn', 'alarm', 'crit'];
  const MODES = ['auto', 'fixed', 'actuated', 'manual', 'flash', 'dark'];
  const BLOCK_BUTTONS =
    '<button type="button" data-action="mode-auto" title="mode auto">auto</button>' +
    '<button type="button" data-action="mode-fixed" title="mode fixed">fixed</button>' +
    '<button type="button" data-action="mode-actuated" title="mode actuated">act</button>' +
    '<button type="button" data-action="mode-manual" title="mode manual">man</button>' +
    '<button type="button" data-action="mode-flash" class="warn" title="mode flash">flash</button>' +
    '<button type="button" data-action="mode-dark" class="warn" title="mode dark">dark</button>' +
    '<button type="button" data-action="advance" title="advance (manual mode)">adv</button>' +
    '<button type="button" data-action="reset" title="reset a latched fault">reset</button>';

  // ---------------------------------------------------------------- the map
  const svg = $('map');
  const viewport = $('viewport');
  const mapImg = $('mapimg');
  const gAreas = $('xareas');
  const gSigns = $('signs');
  const gHeads = $('heads');
  const gCars = $('cars');
  const canvas = $('traffic');
  const mapWrap = $('mapwrap');

  const M = {
    map: null,
    W: 800,
    H: 800,
    margin: 0,
    ppm: 100,
    hm: 8,
    href: '',
    // viewport: content point p (map px) is at viewBox point t + z p
    zoom: 1,
    tx: 0,
    ty: 0,
    // fit of the viewBox into the element (css px): screen = o + f * viewBox
    fit: 1,
    ox: 0,
    oy: 0,
    cw: 0,
    ch: 0,
    left: 0,
    top: 0,
    carLen: 38,
    headR: 4,
  };
  const headEls = new Map(); // head id -> circle
  const lamps = new Map(); // head id -> lamp (also heads the map does not draw)
  const cars = new Map(); // vehicle id -> {g, body, label, title, key}
  let fleet = []; // the latest fleet's vehicles
  let objects = []; // the latest SUMO objects
  let trafficQueued = false;

  function toPx(x, y) {
    return [M.margin + x * M.ppm, M.margin + (M.hm - y) * M.ppm];
  }
  function scale() {
    return M.fit * M.zoom; // css px per map px
  }

  // The fit of the map into its element, from the element's size as the ResizeObserver last
  // reported it (no forced layout: with a big city a layout costs a lot).
  function measure() {
    const f = Math.min(M.cw / M.W, M.ch / M.H);
    M.fit = Number.isFinite(f) && f > 0 ? f : 1;
    M.ox = (M.cw - M.W * M.fit) / 2;
    M.oy = (M.ch - M.H * M.fit) / 2;
  }

  function setupMap(m) {
    const W = num(m && m.width_px, 0);
    const H = num(m && m.height_px, 0);
    if (!m || !(W > 0) || !(H > 0)) {
      M.map = null;
      $('nomap').hidden = false;
      $('nomap').textContent = 'this city has no map';
      mapImg.removeAttribute('href');
      gAreas.textContent = '';
      gSigns.textContent = '';
      gHeads.textContent = '';
      headEls.clear();
      return;
    }
    $('nomap').hidden = true;
    const tr = m.transform || {};
    const changed = M.W !== W || M.H !== H || M.href !== str(m.svg || '/map.svg') || !M.map;
    M.map = m;
    M.W = W;
    M.H = H;
    M.margin = num(tr.margin_px, 0);
    M.ppm = num(tr.px_per_m, 100) || 100;
    M.hm = num(tr.height_m, (H - 2 * M.margin) / M.ppm);
    svg.setAttribute('viewBox', '0 0 ' + W + ' ' + H);
    // the picture's margin (title, scale bar) is left out: the header names the city and the
    // page draws its own scale bar
    const clip = $('mapcliprect');
    clip.setAttribute('x', M.margin);
    clip.setAttribute('y', M.margin);
    clip.setAttribute('width', Math.max(0, W - 2 * M.margin));
    clip.setAttribute('height', Math.max(0, H - 2 * M.margin));
    if (changed) {
      M.href = str(m.svg || '/map.svg');
      mapImg.setAttribute('width', W);
      mapImg.setAttribute('height', H);
      mapImg.setAttribute('href', M.href);
      M.zoom = 1;
      M.tx = 0;
      M.ty = 0;
      applyViewport();
    }
    measure();
    buildSigns(arr(m.signs));
    buildHeads(arr(m.heads));
    // areas are built with the intersections (they need the block names)
  }

  function buildSigns(signs) {
    const out = [];
    for (const s of signs) {
      const x = num(s.x, NaN);
      const y = num(s.y, NaN);
      if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
      const [u, v] = toPx(x, y);
      const val = s.value === undefined || s.value === null || s.value === 0 ? '' : ' ' + s.value;
      out.push(
        '<circle class="sign" cx="' + u.toFixed(1) + '" cy="' + v.toFixed(1) + '" r="4"><title>' +
          esc(str(s.type || 'sign') + val + (s.id !== undefined ? ' (sign ' + s.id + ')' : '')) +
          '</title></circle>'
      );
    }
    gSigns.innerHTML = out.join('');
  }

  function buildHeads(heads) {
    const out = [];
    for (const h of heads) {
      const x = num(h.x, NaN);
      const y = num(h.y, NaN);
      if (h.id === undefined || h.id === null || !Number.isFinite(x) || !Number.isFinite(y)) continue;
      const id = String(h.id);
      const [u, v] = toPx(x, y);
      const lamp = lamps.has(id) ? lamps.get(id) : 0;
      const xname = xNameOf(h.intersection);
      out.push(
        '<circle id="head-' + esc(id) + '" class="head" data-lamp="' + lamp + '" data-head="' + esc(id) +
          '"' + (xname ? ' data-xname="' + esc(xname) + '"' : '') +
          ' cx="' + u.toFixed(1) + '" cy="' + v.toFixed(1) + '" r="' + M.headR.toFixed(2) +
          '" fill="' + (LAMP_FILL[lamp] || LAMP_FILL[0]) + '"><title>signal_' + esc(id) +
          (xname ? ' (' + esc(xname) + (h.side ? ', ' + esc(String(h.side)) + ' approach' : '') + ')' : '') +
          '</title></circle>'
      );
    }
    gHeads.innerHTML = out.join('');
    headEls.clear();
    for (const el of gHeads.children) {
      el._lamp = Number(el.getAttribute('data-lamp'));
      headEls.set(el.getAttribute('data-head'), el);
    }
  }

  function setLamp(id, value) {
    const key = String(id);
    const n = lampNum(value);
    lamps.set(key, n);
    devLampChanged(key);
    const el = headEls.get(key);
    if (!el || el._lamp === n) return;
    el._lamp = n;
    el.setAttribute('data-lamp', String(n));
    el.setAttribute('fill', LAMP_FILL[n] || '#8a6fd1');
  }

  function buildAreas() {
    const out = [];
    const list = [];
    for (const rec of X.values()) {
      if (!rec.mi) continue;
      const x = num(rec.mi.x, NaN);
      const y = num(rec.mi.y, NaN);
      if (Number.isFinite(x) && Number.isFinite(y)) list.push([rec, x, y]);
    }
    // the side: a tile (1 m) or less when intersections are closer
    let near = Infinity;
    if (list.length > 1 && list.length <= 2500) {
      for (let i = 0; i < list.length; i++) {
        for (let j = i + 1; j < list.length; j++) {
          const d = Math.hypot(list[i][1] - list[j][1], list[i][2] - list[j][2]);
          if (d > 1e-6 && d < near) near = d;
        }
      }
    }
    const side = Math.min(1.0, Number.isFinite(near) ? 0.9 * near : 1.0) * M.ppm;
    for (const [rec, x, y] of list) {
      const [u, v] = toPx(x, y);
      out.push(
        '<rect class="xarea" data-xname="' + esc(rec.name) + '" x="' + (u - side / 2).toFixed(1) +
          '" y="' + (v - side / 2).toFixed(1) + '" width="' + side.toFixed(1) + '" height="' +
          side.toFixed(1) + '" rx="' + (side * 0.08).toFixed(1) + '"><title>' + esc(rec.name) +
          '</title></rect>'
      );
    }
    gAreas.innerHTML = out.join('');
    for (const el of gAreas.children) {
      const rec = X.get(el.getAttribute('data-xname'));
      if (rec) {
        rec.area = el;
        areaClass(rec);
      }
    }
  }

  function areaClass(rec) {
    if (!rec.area) return;
    const mode = rec.I ? str(rec.I.mode) : '';
    const cls =
      'xarea' +
      (rec.name === selected ? ' sel' : '') +
      (rec.I && rec.I.latched ? ' latched' : '') +
      (mode === 'flash' || mode === 'dark' ? ' degraded' : '');
    if (rec.area.getAttribute('class') !== cls) rec.area.setAttribute('class', cls);
  }

  // Marker sizes follow the zoom so that they stay visible on big maps and small when zoomed in.
  function applyScale() {
    const s = scale();
    // about the size of a head on the map, but 3 to 11 px on the screen
    const hr = Math.min(Math.max(0.065 * M.ppm, 3 / s), 11 / s);
    const hrq = Math.round(hr * 100) / 100;
    if (hrq !== M.headR) {
      M.headR = hrq;
      const r = hrq.toFixed(2);
      for (const el of headEls.values()) el.setAttribute('r', r);
    }
    svg.style.setProperty('--lf', (11 / s).toFixed(3) + 'px');
    svg.style.setProperty('--sr', Math.max(0.035 * M.ppm, 2.5 / s).toFixed(2) + 'px');
    svg.style.setProperty('--sw', (1 / s).toFixed(3) + 'px');
    const L = Math.max(0.318 * M.ppm, 6, 12 / s);
    if (Math.abs(L - M.carLen) > 1e-3) {
      M.carLen = L;
      for (const c of cars.values()) placeCarBody(c);
    }
    for (const c of cars.values()) c.label.setAttribute('y', (-0.55 * M.carLen - 3 / s).toFixed(2));
    scaleBar(s);
  }

  function scaleBar(s) {
    const el = $('scalebar');
    if (!M.map) {
      el.hidden = true;
      return;
    }
    const pxPerM = M.ppm * s;
    const target = 110 / pxPerM; // metres in about 110 px
    const p = Math.pow(10, Math.floor(Math.log10(target)));
    let m = p;
    for (const k of [1, 2, 5, 10]) if (k * p <= target) m = k * p;
    el.hidden = false;
    el.firstElementChild.style.width = (m * pxPerM).toFixed(1) + 'px';
    el.lastElementChild.textContent = m >= 1 ? m + ' m' : Math.round(m * 100) + ' cm';
  }

  function applyViewport() {
    viewport.setAttribute(
      'transform',
      'translate(' + M.tx.toFixed(3) + ' ' + M.ty.toFixed(3) + ') scale(' + M.zoom.toFixed(5) + ')'
    );
  }

  let viewQueued = false;
  function viewChanged() {
    if (viewQueued) return;
    viewQueued = true;
    requestAnimationFrame(
      guard('view', () => {
        viewQueued = false;
        applyViewport();
        applyScale();
        drawTraffic();
      })
    );
  }

  function zoomAt(sx, sy, factor) {
    // sx, sy: css px within the svg element; keep the content point under it fixed
    const z1 = Math.min(80, Math.max(1, M.zoom * factor));
    const qx = (sx - M.ox) / M.fit;
    const qy = (sy - M.oy) / M.fit;
    const px = (qx - M.tx) / M.zoom;
    const py = (qy - M.ty) / M.zoom;
    M.zoom = z1;
    M.tx = qx - z1 * px;
    M.ty = qy - z1 * py;
    if (z1 === 1) {
      M.tx = 0;
      M.ty = 0;
    }
    viewChanged();
  }

  // For tests: the map point (metres) of a point in the map's own pixels (what toPx gives and
  // the cars' layer is drawn in).
  dash.mapOfPx = (u, v) => [(u - M.margin) / M.ppm, M.hm - (v - M.margin) / M.ppm];

  function screenToMap(sx, sy) {
    const qx = (sx - M.ox) / M.fit;
    const qy = (sy - M.oy) / M.fit;
    const u = (qx - M.tx) / M.zoom;
    const v = (qy - M.ty) / M.zoom;
    return [(u - M.margin) / M.ppm, M.hm - (v - M.margin) / M.ppm];
  }

  // ---- lab cars
  function makeCar(id) {
    const g = document.createElementNS(SVGNS, 'g');
    g.setAttribute('id', 'car-' + id);
    g.setAttribute('class', 'car');
    const body = document.createElementNS(SVGNS, 'g');
    body.setAttribute('class', 'body');
    body.innerHTML =
      '<rect x="-0.5" y="-0.275" width="1" height="0.55" rx="0.08"></rect>' +
      '<path class="nose" d="M0.47,0 L0.12,-0.2 L0.12,0.2 Z"></path>' +
      '<path class="hdg" d="M0.5,0 L0.95,0"></path>';
    const title = document.createElementNS(SVGNS, 'title');
    const label = document.createElementNS(SVGNS, 'text');
    label.setAttribute('class', 'carlabel');
    label.textContent = id;
    g.appendChild(title);
    g.appendChild(body);
    g.appendChild(label);
    gCars.appendChild(g);
    const c = { id, g, body, label, title, yaw: 0, tkey: '', src: '' };
    label.setAttribute('y', (-0.55 * M.carLen - 3 / scale()).toFixed(2));
    cars.set(id, c);
    return c;
  }
  // A lab car's pose is the middle of its rear axle (docs/eye.md, docs/vehicle_sim.md); a Nigel's
  // body (0.318 m long) is centred half its wheelbase (0.14154 m) ahead of it, in body lengths.
  const CAR_CENTRE_AHEAD = 0.07077 / 0.318;
  function placeCarBody(c) {
    c.body.setAttribute(
      'transform',
      'rotate(' + ((-c.yaw * 180) / Math.PI).toFixed(2) + ') scale(' + M.carLen.toFixed(3) + ') translate(' +
        CAR_CENTRE_AHEAD.toFixed(4) + ' 0)'
    );
  }

  function applyFleet(vehicles, stamp) {
    fleet = vehicles;
    const seen = new Set();
    for (const v of vehicles) {
      if (!v || v.id === undefined || v.id === null) continue;
      const id = String(v.id);
      seen.add(id);
      const c = cars.get(id) || makeCar(id);
      const x = num(v.x, NaN);
      const y = num(v.y, NaN);
      c.g.setAttribute('data-x', str(v.x));
      c.g.setAttribute('data-y', str(v.y));
      // The time of the observation drawn (the fleet message's when the vehicle has none).
      const observed = v.observed !== undefined ? v.observed : stamp;
      if (observed !== undefined) c.g.setAttribute('data-stamp', str(observed));
      if (Number.isFinite(x) && Number.isFinite(y)) {
        const [u, w] = toPx(x, y);
        c.g.setAttribute('transform', 'translate(' + u.toFixed(2) + ' ' + w.toFixed(2) + ')');
        c.g.style.display = '';
      } else {
        c.g.style.display = 'none';
      }
      const yaw = num(v.yaw, 0);
      if (yaw !== c.yaw || !c.body.hasAttribute('transform')) {
        c.yaw = yaw;
        placeCarBody(c);
      }
      const src = sourceKey(v.source);
      if (src !== c.src) {
        c.src = src;
        c.g.setAttribute('class', 'car src-' + src);
        c.g.setAttribute('data-source', str(v.source));
      }
      const sp = num(v.speed, NaN);
      const tkey =
        id + ' · ' + str(v.source || 'unknown source') +
        (Number.isFinite(sp) ? ' · ' + sp.toFixed(2) + ' m/s' : '') +
        (isRef(v.lane) ? ' · lane ' + v.lane : '') +
        (isRef(v.intersection)
          ? ' · ' + (xNameOf(v.intersection) || 'intersection ' + v.intersection) + (isRef(v.approach) ? ' approach ' + v.approach : '')
          : '') +
        (Number.isFinite(num(v.to_stop_line, NaN)) ? ' · ' + num(v.to_stop_line, 0).toFixed(2) + ' m to the stop line' : '');
      if (tkey !== c.tkey) {
        c.tkey = tkey;
        c.title.textContent = tkey;
      }
    }
    for (const [id, c] of cars) {
      if (!seen.has(id)) {
        c.g.remove();
        cars.delete(id);
      }
    }
  }

  // ---- SUMO traffic on the canvas
  function queueTraffic() {
    if (trafficQueued) return;
    trafficQueued = true;
    requestAnimationFrame(guard('traffic draw', drawTraffic));
  }
  function drawTraffic() {
    trafficQueued = false;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(M.cw * dpr));
    const h = Math.max(1, Math.round(M.ch * dpr));
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
    const ctx = canvas.getContext('2d');
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, w, h);
    if (!M.map || objects.length === 0) return;
    // device px = A + B * map px
    const B = dpr * M.fit * M.zoom;
    const Ax = dpr * (M.ox + M.fit * M.tx);
    const Ay = dpr * (M.oy + M.fit * M.ty);
    const S = B * M.ppm; // device px per metre
    const X0 = Ax + B * M.margin;
    const Y0 = Ay + B * (M.margin + M.hm * M.ppm);
    const minL = 4 * dpr;
    const minW = 2.2 * dpr;
    const buckets = new Map();
    for (const o of objects) {
      if (!Array.isArray(o) || o.length < 4) continue;
      const x = o[2];
      const y = o[3];
      if (typeof x !== 'number' || typeof y !== 'number') continue;
      const cx = X0 + S * x;
      const cy = Y0 - S * y;
      if (cx < -50 || cy < -50 || cx > w + 50 || cy > h + 50) continue;
      const yaw = typeof o[4] === 'number' ? o[4] : 0;
      const hl = Math.max((typeof o[5] === 'number' && o[5] > 0 ? o[5] : 0.3) * S, minL) / 2;
      const hw = Math.max((typeof o[6] === 'number' && o[6] > 0 ? o[6] : 0.16) * S, minW) / 2;
      const c = Math.cos(yaw);
      const s = -Math.sin(yaw); // screen y grows down
      const fill = SUMO_FILL[o[1]] || SUMO_OTHER;
      let path = buckets.get(fill);
      if (!path) {
        path = new Path2D();
        buckets.set(fill, path);
      }
      // corners: centre +- hl (c, s) +- hw (-s, c)
      const ax = hl * c;
      const ay = hl * s;
      const bx = -hw * s;
      const by = hw * c;
      path.moveTo(cx + ax + bx, cy + ay + by);
      path.lineTo(cx + ax - bx, cy + ay - by);
      path.lineTo(cx - ax - bx, cy - ay - by);
      path.lineTo(cx - ax + bx, cy - ay + by);
      path.closePath();
    }
    ctx.globalAlpha = 0.82;
    ctx.lineWidth = Math.max(1, dpr * 0.8);
    ctx.strokeStyle = 'rgba(10,14,20,0.85)';
    for (const [fill, path] of buckets) {
      ctx.fillStyle = fill;
      ctx.fill(path);
      ctx.stroke(path);
    }
    ctx.globalAlpha = 1;
  }

  // ---- map interaction: wheel zoom, drag pan, click selects
  let drag = null;
  svg.addEventListener(
    'wheel',
    guard('wheel', (e) => {
      if (!M.map) return;
      e.preventDefault();
      const dy = e.deltaMode === 1 ? e.deltaY * 16 : e.deltaY;
      zoomAt(e.clientX - M.left, e.clientY - M.top, Math.exp(-dy * 0.0015));
    }),
    { passive: false }
  );
  svg.addEventListener(
    'pointerdown',
    guard('pointerdown', (e) => {
      if (e.button !== 0) return;
      drag = { x: e.clientX, y: e.clientY, tx: M.tx, ty: M.ty, moved: false };
    })
  );
  window.addEventListener(
    'pointermove',
    guard('pointermove', (e) => {
      if (drag) {
        const dx = e.clientX - drag.x;
        const dy = e.clientY - drag.y;
        if (!drag.moved && Math.hypot(dx, dy) > 4) {
          drag.moved = true;
          mapWrap.classList.add('panning');
        }
        if (drag.moved) {
          M.tx = drag.tx + dx / M.fit;
          M.ty = drag.ty + dy / M.fit;
          viewChanged();
        }
        return;
      }
      if (e.target && e.target.closest && e.target.closest('#map') && M.map) {
        const [x, y] = screenToMap(e.clientX - M.left, e.clientY - M.top);
        let what = '';
        const t = e.target;
        if (t.hasAttribute && t.hasAttribute('data-head')) {
          const n = t._lamp;
          what = 'head ' + t.getAttribute('data-head') + (t.hasAttribute('data-xname') ? ' · ' + t.getAttribute('data-xname') : '') + ' · ' + (LAMP_NAME[n] || 'lamp ' + n) + '   ';
        } else if (t.hasAttribute && t.hasAttribute('data-xname')) {
          what = t.getAttribute('data-xname') + '   ';
        }
        $('cursor').textContent = what + 'x ' + x.toFixed(2) + ' m  y ' + y.toFixed(2) + ' m';
      }
    })
  );
  window.addEventListener(
    'pointerup',
    guard('pointerup', (e) => {
      const d = drag;
      drag = null;
      mapWrap.classList.remove('panning');
      if (!d || d.moved) return;
      const t = e.target && e.target.closest ? e.target.closest('#map [data-xname]') : null;
      if (t) select(t.getAttribute('data-xname'), true);
    })
  );
  svg.addEventListener('dblclick', guard('dblclick', () => fitView()));
  function fitView() {
    M.zoom = 1;
    M.tx = 0;
    M.ty = 0;
    viewChanged();
  }
  $('zoom-in').addEventListener('click', guard('zoom', () => zoomAt(M.cw / 2, M.ch / 2, 1.5)));
  $('zoom-out').addEventListener('click', guard('zoom', () => zoomAt(M.cw / 2, M.ch / 2, 1 / 1.5)));
  $('zoom-fit').addEventListener('click', guard('zoom', fitView));

  const ro = new ResizeObserver(
    guard('resize', (entries) => {
      for (const en of entries) {
        if (en.target !== mapWrap) continue;
        M.cw = en.contentRect.width;
        M.ch = en.contentRect.height;
        const r = mapWrap.getBoundingClientRect(); // layout is clean in a ResizeObserver callback
        M.left = r.left;
        M.top = r.top;
      }
      requestAnimationFrame(
        guard('resize', () => {
          measure();
          applyScale();
          drawTraffic();
        })
      );
    })
  );
  ro.observe(mapWrap);

  // ---------------------------------------------------------------- intersections
  // One record per signalised intersection, keyed by name; joined to SPaT by id.
  const X = new Map(); // name -> rec
  const xIdToName = new Map(); // String(id) -> name
  const mapXs = new Map(); // name -> map intersection (any control)
  let selected = null;
  let allExpanded = false;
  let listBuilt = false; // blocks for intersections found later are added one by one
  const xsecsEl = $('xsecs');

  function xNameOf(ref) {
    if (!isRef(ref)) return null;
    const k = String(ref);
    if (xIdToName.has(k)) return xIdToName.get(k);
    if (X.has(k) || mapXs.has(k)) return k;
    return null;
  }

  function newRec(name, id) {
    return {
      name,
      id: id === undefined ? null : id,
      mi: mapXs.get(name) || null,
      I: null,
      X: null,
      spatNow: NaN,
      spatAt: 0,
      plans: new Set(),
      hist: new Map(), // group id -> [[ms, state]…], the last 5 minutes
      el: null,
      hEl: null,
      lEl: null,
      gEl: null,
      area: null,
      hkey: '',
      gkey: '',
      cds: [],
      expanded: false,
    };
  }

  function signalised(mi) {
    return !mi || mi.control === undefined || mi.control === null || mi.control === 'signal';
  }

  // Builds the whole list (on `state`): the map's signalised intersections, then any other the
  // SCM or the SPaT names.
  function buildXsecs(mapList, iList, xList) {
    listBuilt = false;
    X.clear();
    xIdToName.clear();
    mapXs.clear();
    for (const mi of mapList) {
      if (!mi) continue;
      const name = str(mi.name !== undefined && mi.name !== null && mi.name !== '' ? mi.name : mi.id);
      if (!name) continue;
      mapXs.set(name, mi);
      if (isRef(mi.id)) xIdToName.set(String(mi.id), name);
      if (signalised(mi)) X.set(name, newRec(name, mi.id));
    }
    for (const i of iList) ensureRec(i && i.name, i && i.id);
    for (const x of xList) if (x) ensureRec((isRef(x.id) && xIdToName.get(String(x.id))) || x.name, x.id);
    allExpanded = X.size <= 6;
    const html = [];
    for (const rec of X.values()) {
      html.push(
        '<div class="xsec" id="x-' + esc(rec.name) + '" data-xname="' + esc(rec.name) +
          '" data-mode="" data-stage="" data-latched="false"><div class="xh"></div>' +
          '<div class="xl" hidden></div><div class="xg"></div><div class="xb">' + BLOCK_BUTTONS +
          '</div></div>'
      );
    }
    if (xObserver) xObserver.disconnect();
    xsecsEl.innerHTML = html.length ? html.join('') : '<div class="empty">no signalised intersection</div>';
    for (const el of xsecsEl.children) {
      const rec = X.get(el.getAttribute('data-xname'));
      if (!rec) continue;
      rec.el = el;
      rec.hEl = el.children[0];
      rec.lEl = el.children[1];
      rec.gEl = el.children[2];
      observeRec(rec);
    }
    listBuilt = true;
  }

  // The intersections' blocks out of sight (a big city's list is mostly scrolled away) are not
  // drawn as their data comes: they are marked and drawn when they come into view, so that a
  // second's changes to a thousand intersections do not hold up the page's other messages.
  // Their attributes (mode, stage, latch) are always current.
  const xObserver =
    typeof IntersectionObserver === 'function'
      ? new IntersectionObserver(
          guard('intersections in view', (entries) => {
            for (const e of entries) {
              const rec = X.get(e.target.getAttribute('data-xname'));
              if (!rec || rec.el !== e.target) continue;
              rec.visible = e.isIntersecting;
              if (rec.visible && rec.dirty) {
                rec.dirty = false;
                renderHead(rec);
                renderGroups(rec);
              }
            }
          }),
          { rootMargin: '200px' }
        )
      : null;
  function observeRec(rec) {
    rec.visible = true; // until the observer says otherwise
    rec.dirty = false;
    if (xObserver) xObserver.observe(rec.el);
  }

  // A record for an intersection the SCM or SPaT names; null for one the map says is not
  // signalised. Adds a block at the end when the list is already built.
  function ensureRec(name0, id) {
    if (!isRef(id)) id = null;
    let name = name0 !== undefined && name0 !== null && name0 !== '' ? String(name0) : null;
    if (!name && id !== null) name = xIdToName.get(String(id)) || String(id);
    if (!name) return null;
    if (id !== null && !xIdToName.has(String(id))) xIdToName.set(String(id), name);
    let rec = X.get(name);
    if (rec) {
      if (rec.id === null && id !== null) rec.id = id;
      return rec;
    }
    const mi = mapXs.get(name);
    if (mi && !signalised(mi)) return null;
    rec = newRec(name, id);
    X.set(name, rec);
    if (listBuilt) {
      const empty = xsecsEl.querySelector('.empty');
      if (empty) empty.remove();
      const el = document.createElement('div');
      el.className = 'xsec';
      el.id = 'x-' + name;
      el.setAttribute('data-xname', name);
      el.setAttribute('data-mode', '');
      el.setAttribute('data-stage', '');
      el.setAttribute('data-latched', 'false');
      el.innerHTML = '<div class="xh"></div><div class="xl" hidden></div><div class="xg"></div><div class="xb">' + BLOCK_BUTTONS + '</div>';
      xsecsEl.appendChild(el);
      rec.el = el;
      rec.hEl = el.children[0];
      rec.lEl = el.children[1];
      rec.gEl = el.children[2];
      observeRec(rec);
      renderRec(rec);
      if (!selected) select(name, false);
    }
    return rec;
  }

  function mergeI(i) {
    if (!i || typeof i !== 'object') return null;
    const rec = ensureRec(i.name, i.id);
    if (!rec) return null;
    rec.I = i;
    if (i.plan) rec.plans.add(String(i.plan));
    return rec;
  }

  function mergeX(x, now) {
    if (!x || typeof x !== 'object') return null;
    // SPaT is keyed by id: the name of the intersection with that id wins over the SPaT's own
    const known = isRef(x.id) ? xIdToName.get(String(x.id)) : undefined;
    const rec = ensureRec(known || x.name, x.id);
    if (!rec) return null;
    rec.X = x;
    const n = num(now, NaN);
    rec.spatNow = n;
    rec.spatAt = performance.now();
    if (x.plan) rec.plans.add(String(x.plan));
    const t = Date.now();
    for (const g of arr(x.groups)) {
      if (!g) continue;
      const gid = String(g.id);
      let h = rec.hist.get(gid);
      if (!h) rec.hist.set(gid, (h = []));
      const st = str(g.state);
      if (!h.length || h[h.length - 1][1] !== st) h.push([t, st]);
      const t0 = t - 300000;
      while (h.length > 1 && h[1][0] < t0) h.shift();
    }
    return rec;
  }

  function recNow(rec) {
    return Number.isFinite(rec.spatNow) ? rec.spatNow + (performance.now() - rec.spatAt) / 1000 : serverNow();
  }

  function problem(rec) {
    const I = rec.I || {};
    const mode = str(I.mode);
    return !!I.latched || mode === 'flash' || mode === 'dark' || arr(rec.X && rec.X.flags).length > 0;
  }

  function renderRec(rec) {
    if (!rec.el) return;
    renderHead(rec);
    renderGroups(rec);
    areaClass(rec);
    applyXFilter(rec);
  }

  function renderHead(rec) {
    const I = rec.I;
    const x = rec.X;
    const key = JSON.stringify([I, x && x.flags, x && x.plan, x && x.status, rec.name === selected]);
    if (key === rec.hkey) return;
    const el = rec.el;
    const mode = I ? str(I.mode) : '';
    const latched = !!(I && I.latched);
    el.setAttribute('data-mode', mode);
    el.setAttribute('data-stage', I && I.stage !== undefined && I.stage !== null ? str(I.stage) : '');
    el.setAttribute('data-latched', latched ? 'true' : 'false');
    el.classList.toggle('latched', latched);
    el.classList.toggle('degraded', mode === 'flash' || mode === 'dark');
    el.classList.toggle('sel', rec.name === selected);
    if (rec.visible === false && rec.name !== selected) {
      rec.dirty = true;
      return;
    }
    rec.hkey = key;
    const h = [];
    h.push('<span class="xn">' + esc(rec.name) + '</span>');
    if (I) {
      h.push('<span class="mode m-' + esc(mode || 'none') + '">' + esc(mode || '?') + '</span>');
      if (I.requested && I.requested !== I.mode) h.push('<span class="req" title="requested mode">→ ' + esc(I.requested) + '</span>');
      const plan = I.plan || (x && x.plan);
      if (plan) {
        h.push(
          '<span class="plan" title="plan ' + esc(plan) + (I.plan_by ? ', by ' + esc(I.plan_by) : '') + '">' + esc(plan) +
            (I.plan_by ? '<i>' + (I.plan_by === 'operator' ? 'op' : I.plan_by === 'schedule' ? 'sched' : esc(I.plan_by)) + '</i>' : '') +
            '</span>'
        );
      }
      if (I.stage !== undefined && I.stage !== null && I.stage !== '') h.push('<span class="stage" title="stage">st ' + esc(I.stage) + '</span>');
    } else if (x) {
      if (x.plan) h.push('<span class="plan">' + esc(x.plan) + '</span>');
      h.push('<span class="nodata">no SCM status</span>');
    } else {
      h.push('<span class="nodata">no data yet</span>');
    }
    for (const f of arr(x && x.flags)) {
      const fs = str(f);
      const bad = /fail|flash|conflict|fault|off|no_valid|manual|preempt/i.test(fs);
      h.push('<span class="flag' + (bad ? ' bad' : '') + '" title="SPaT flag' + (x && x.status !== undefined ? ', status ' + esc(x.status) : '') + '">' + esc(fs) + '</span>');
    }
    rec.hEl.innerHTML = h.join('');
    rec.hEl.title = I && I.text ? str(I.text) : '';
    if (latched) {
      rec.lEl.hidden = false;
      rec.lEl.textContent = 'LATCHED: ' + (typeof I.latched === 'string' ? I.latched : JSON.stringify(I.latched));
    } else {
      rec.lEl.hidden = true;
      rec.lEl.textContent = '';
    }
  }

  function groupName(rec, gid) {
    const mg = rec.mi ? arr(rec.mi.groups).find((g) => g && String(g.id) === gid) : null;
    return mg && mg.name ? String(mg.name) : '';
  }

  function renderGroups(rec) {
    const expanded = allExpanded || rec.name === selected;
    const groups = arr(rec.X && rec.X.groups);
    const key = expanded
      ? JSON.stringify([1, groups, rec.spatNow])
      : JSON.stringify([0, groups.map((g) => g && g.state)]);
    if (key === rec.gkey && expanded === rec.expanded) return;
    if (rec.visible === false && rec.name !== selected) {
      rec.dirty = true;
      return;
    }
    rec.gkey = key;
    rec.expanded = expanded;
    rec.el.classList.toggle('expanded', expanded);
    rec.cds = [];
    if (!groups.length) {
      // the map's groups, state unknown
      const mg = rec.mi ? arr(rec.mi.groups) : [];
      rec.gEl.innerHTML = mg.length
        ? mg.map((g) => '<span class="chip sm sg-unknown" title="group ' + esc(g.id) + ' ' + esc(g.name) + ': no SPaT">' + esc(g.id) + '</span>').join('')
        : '<span class="nodata">no SPaT</span>';
      return;
    }
    if (!expanded) {
      const chips = rec.gEl.children;
      if (chips.length === groups.length && rec.gEl.firstElementChild && rec.gEl.firstElementChild.classList.contains('chip') && groups.every((g, i) => g && chips[i]._gid === String(g.id))) {
        // the same groups: only their colours change
        for (let i = 0; i < groups.length; i++) {
          const c = 'chip sm ' + sg(groups[i].state)[0];
          if (chips[i].className !== c) {
            chips[i].className = c;
            chips[i].title = chips[i]._t + str(groups[i].state);
          }
        }
        return;
      }
      rec.gEl.innerHTML = groups
        .map((g) => {
          if (!g) return '';
          const gid = String(g.id);
          const s = sg(g.state);
          const nm = groupName(rec, gid);
          return '<span class="chip sm ' + s[0] + '" title="group ' + esc(gid) + (nm ? ' ' + esc(nm) : '') + ': ' + esc(g.state) + '">' + esc(gid) + '</span>';
        })
        .join('');
      let i = 0;
      for (const g of groups) {
        if (!g) continue;
        const c = rec.gEl.children[i++];
        c._gid = String(g.id);
        const nm = groupName(rec, c._gid);
        c._t = 'group ' + c._gid + (nm ? ' ' + nm : '') + ': ';
      }
      return;
    }
    const rows = [];
    for (const g of groups) {
      if (!g) continue;
      const gid = String(g.id);
      const s = sg(g.state);
      const nm = groupName(rec, gid);
      rows.push(
        '<div class="grow"><span class="gname" title="signal group ' + esc(gid) + '">' + esc(gid) + (nm ? ' <small>' + esc(nm) + '</small>' : '') +
          '</span><span class="chip ' + s[0] + '" title="' + esc(g.state) + '">' + esc(s[1]) +
          '</span><span class="cd mono"></span><span class="cdx mono"></span></div>'
      );
    }
    rec.gEl.innerHTML = rows.join('');
    let i = 0;
    for (const g of groups) {
      if (!g) continue;
      const row = rec.gEl.children[i++];
      rec.cds.push({ g, cd: row.children[2], cdx: row.children[3], a: '', b: '' });
    }
    countdown(rec);
  }

  function secs(v) {
    if (v > 3600) return '>1h';
    return (v < 0 ? 0 : v).toFixed(1);
  }
  function countdown(rec) {
    if (!rec.cds.length) return;
    const now = recNow(rec);
    for (const c of rec.cds) {
      const min = num(c.g.min_end, NaN);
      const a = Number.isFinite(min) ? secs(min - now) + ' s' : '–';
      const lk = num(c.g.likely, NaN);
      const mx = num(c.g.max_end, NaN);
      let b = '';
      if (Number.isFinite(lk)) b += 'likely ' + secs(lk - now);
      if (Number.isFinite(mx)) b += (b ? ' · ' : '') + 'max ' + secs(mx - now);
      if (a !== c.a) c.cd.textContent = c.a = a;
      if (b !== c.b) c.cdx.textContent = c.b = b;
    }
  }

  function select(name, fromMap) {
    if (!name || !X.has(name)) return;
    const old = selected;
    selected = name;
    dash.selected = name;
    if (old && old !== name && X.has(old)) {
      const o = X.get(old);
      o.hkey = '';
      renderRec(o);
    }
    const rec = X.get(name);
    rec.hkey = '';
    renderRec(rec);
    $('sel-name').textContent = name;
    $('charts-sel').textContent = name;
    fillPlans();
    if (fromMap && rec.el) {
      if (rec.el.hidden) {
        $('xsec-filter').value = '';
        $('xsec-problems').checked = false;
        applyXFilterAll();
      }
      rec.el.scrollIntoView({ block: 'nearest' });
    }
    drawCharts();
  }

  function fillPlans() {
    const sel = $('plan-select');
    const rec = selected ? X.get(selected) : null;
    const plans = ['auto'].concat(rec ? Array.from(rec.plans).filter((p) => p !== 'auto').sort(collator.compare) : []);
    const key = plans.join('\n');
    if (sel.dataset.key === key) return;
    const other = planOther();
    const cur = sel.value;
    sel.dataset.key = key;
    sel.innerHTML =
      plans.map((p) => '<option value="' + esc(p) + '">' + esc(p) + '</option>').join('') + '<option value="" data-other="1">other…</option>';
    if (other) sel.selectedIndex = sel.options.length - 1;
    else if (plans.includes(cur)) sel.value = cur;
    $('plan-other').hidden = !planOther();
  }
  // "other…" chosen: the plan is typed in the text field
  function planOther() {
    const o = $('plan-select').selectedOptions[0];
    return !!(o && o.hasAttribute('data-other'));
  }

  function summariseX() {
    let latched = 0;
    let degraded = 0;
    for (const rec of X.values()) {
      if (rec.I && rec.I.latched) latched++;
      const m = rec.I ? rec.I.mode : '';
      if (m === 'flash' || m === 'dark') degraded++;
    }
    const el = $('xsec-summary');
    el.innerHTML =
      X.size + ' signalised' + (latched ? ' · <b class="bad">' + latched + ' latched</b>' : '') +
      (degraded ? ' · <b class="warn">' + degraded + ' flash/dark</b>' : '');
  }

  function applyXFilter(rec) {
    if (!rec.el) return;
    const f = xFilter.text;
    const hide = (f && !rec.name.toLowerCase().includes(f)) || (xFilter.problems && !problem(rec));
    if (rec.el.hidden !== hide) rec.el.hidden = hide;
  }
  const xFilter = { text: '', problems: false };
  function applyXFilterAll() {
    xFilter.text = $('xsec-filter').value.trim().toLowerCase();
    xFilter.problems = $('xsec-problems').checked;
    for (const rec of X.values()) applyXFilter(rec);
  }
  $('xsec-filter').addEventListener('input', guard('filter', applyXFilterAll));
  $('xsec-problems').addEventListener('change', guard('filter', applyXFilterAll));
  xsecsEl.addEventListener(
    'click',
    guard('select', (e) => {
      const b = e.target.closest('.xsec');
      if (b && !e.target.closest('button')) select(b.getAttribute('data-xname'), false);
    })
  );

  // ---------------------------------------------------------------- actions
  const tokenEl = $('token');
  let needToken = true;
  try {
    tokenEl.value = sessionStorage.getItem('autodrive.dashboard.token') || '';
  } catch (e) {
    /* storage may be unavailable */
  }
  tokenEl.addEventListener(
    'input',
    guard('token', () => {
      try {
        sessionStorage.setItem('autodrive.dashboard.token', tokenEl.value);
      } catch (e) {
        /* storage may be unavailable */
      }
    })
  );
  $('tokenform').addEventListener('submit', (e) => e.preventDefault());

  function showResult(kind, text) {
    const el = $('action-result');
    el.classList.remove('pending');
    el.setAttribute('data-result', kind);
    el.textContent = text;
    el.title = new Date().toLocaleTimeString();
  }

  function describe(command, args) {
    if (command === 'mode') return args.intersection + ': mode ' + args.mode;
    if (command === 'plan') return args.intersection + ': plan ' + args.plan;
    if (command === 'advance' || command === 'reset') return args.intersection + ': ' + command;
    if (command === 'ack') return 'acknowledge event ' + args.id;
    if (command === 'config_apply') return 'apply configuration (' + str(args.yaml).length + ' bytes)';
    return command;
  }

  function sendAction(command, args) {
    const what = describe(command, args);
    const token = tokenEl.value.trim();
    if (!token && needToken) {
      showResult('unauthorized', '✗ ' + what + ': no token — enter the operator token (actions need one)');
      return Promise.resolve(null);
    }
    const el = $('action-result');
    el.classList.add('pending');
    el.textContent = '… ' + what;
    const headers = { 'Content-Type': 'application/json' };
    if (token) headers.Authorization = 'Bearer ' + token;
    return fetch('/api/action', {
      method: 'POST',
      headers,
      body: JSON.stringify({ command, args }),
      cache: 'no-store',
    })
      .then((r) =>
        r.text().then((text) => {
          let body = null;
          try {
            body = text ? JSON.parse(text) : null;
          } catch (e) {
            body = null;
          }
          const msg = body && body.message ? ' — ' + body.message : '';
          if (r.status === 401) {
            showResult('unauthorized', '✗ ' + what + ': the token was refused (401)' + msg);
          } else if (!r.ok) {
            showResult('error', '✗ ' + what + ': HTTP ' + r.status + msg);
          } else if (!body || typeof body !== 'object') {
            showResult('error', '✗ ' + what + ': unreadable answer');
          } else if (body.result === 'ok') {
            showResult('ok', '✓ ' + what + msg);
          } else if (body.result === 'rejected') {
            showResult('rejected', '✗ ' + what + ': rejected' + msg);
          } else {
            showResult('error', '✗ ' + what + ': ' + str(body.result || 'no result') + msg);
          }
          return body;
        })
      )
      .catch((e) => {
        showResult('error', '✗ ' + what + ': ' + (e && e.message ? e.message : 'network error'));
        return null;
      });
  }

  document.addEventListener(
    'click',
    guard('action', (e) => {
      const b = e.target && e.target.closest ? e.target.closest('button[data-action], button[data-ack]') : null;
      if (!b || b.disabled) return;
      if (b.hasAttribute('data-ack')) {
        const row = b.closest('.ev');
        const ev = row && row._e;
        // the id as text: as the brief's examples have it, and safe for 64-bit ids; and in a city
        // of districts the event's district (each district's SCM numbers its own events)
        const args = { id: str(ev && ev.id !== undefined && ev.id !== null ? ev.id : b.getAttribute('data-ack')) };
        if (ev && isRef(ev.district)) args.district = str(ev.district);
        sendAction('ack', args);
        return;
      }
      const action = b.getAttribute('data-action');
      if (action === 'config-apply') {
        applyConfig();
        return;
      }
      const block = b.closest('.xsec');
      const name = block ? block.getAttribute('data-xname') : selected;
      if (!name) {
        showResult('error', '✗ no intersection selected');
        return;
      }
      if (block && name !== selected) select(name, false);
      if (action.startsWith('mode-')) {
        sendAction('mode', { intersection: name, mode: action.slice(5) });
      } else if (action === 'advance' || action === 'reset') {
        sendAction(action, { intersection: name });
      } else if (action === 'plan') {
        const sel = $('plan-select');
        const plan = planOther() ? $('plan-other').value.trim() : sel.value;
        if (!plan) {
          showResult('error', '✗ ' + name + ': no plan given');
          return;
        }
        sendAction('plan', { intersection: name, plan });
      }
    })
  );
  $('plan-select').addEventListener(
    'change',
    guard('plan', () => {
      $('plan-other').hidden = !planOther();
      if (planOther()) $('plan-other').focus();
    })
  );

  $('config-file').addEventListener(
    'change',
    guard('config file', () => {
      const f = $('config-file').files && $('config-file').files[0];
      if (!f) return;
      f.text().then(
        (t) => {
          $('config-text').value = t;
        },
        (e) => showResult('error', '✗ cannot read ' + f.name + ': ' + (e && e.message))
      );
    })
  );
  function applyConfig() {
    const text = $('config-text').value;
    if (!text.trim()) {
      showResult('error', '✗ apply configuration: the text is empty (paste YAML or choose a file)');
      return;
    }
    const lines = text.split('\n').length;
    if (!window.confirm('Apply this configuration (' + lines + ' lines) to the running city?')) return;
    sendAction('config_apply', { yaml: text });
  }

  // ---------------------------------------------------------------- events and alarms
  const EV_KEEP = 500;
  const evEl = $('events');
  const evRows = new Map(); // key -> row
  let evSeq = 0;
  // An id is its source's (the SCM's event log, a light host's session) in its district (each
  // district's SCM has a log of its own): two sources, or two districts, may use one.
  function evKey(e) {
    if (e.id === undefined || e.id === null) return 'local-' + ++evSeq;
    return (isRef(e.district) ? str(e.district) + '/' : '') + str(e.source) + '#' + String(e.id);
  }
  function evHtml(e) {
    const sev = Math.max(0, Math.min(3, Math.round(num(e.severity, 0))));
    const xi = isRef(e.intersection) ? xNameOf(e.intersection) || 'intersection ' + e.intersection : '';
    const where = [e.district, e.source, xi, e.device].filter((v) => isRef(v)).join(' · ');
    let st = e.active ? 'active' : sev > 0 ? 'cleared' : '';
    if (e.acked_by) st += (st ? ' · ' : '') + 'acked by ' + str(e.acked_by);
    const ackable = sev >= 2 && e.active && !e.acked_by;
    const stamp = num(e.stamp, NaN);
    return (
      '<span class="et mono" title="' + esc(Number.isFinite(stamp) ? new Date(stamp * 1000).toISOString() : '') + '">' + fmtTime(e.stamp) +
      '</span><span class="es" title="severity ' + sev + ': ' + SEV_NAME[sev] + '">' + SEV_SHORT[sev] + '</span><span class="em"><b class="ec mono">' + esc(e.code) +
      '</b> ' + esc(e.message) + (where ? ' <small>' + esc(where) + '</small>' : '') +
      '</span><span class="est">' + esc(st) + (ackable ? '<button type="button" class="ack" data-ack="' + esc(e.id) + '">acknowledge</button>' : '') + '</span>'
    );
  }
  function evClass(e) {
    const sev = Math.max(0, Math.min(3, Math.round(num(e.severity, 0))));
    return 'ev sev-' + sev + (e.active ? ' active' : ' cleared') + (sev >= 2 && e.active && !e.acked_by ? ' alarm' : '') + (e.acked_by ? ' acked' : '');
  }
  function makeEvRow(e) {
    const row = document.createElement('div');
    row._e = e;
    row.className = evClass(e);
    row.setAttribute('data-id', str(e.id));
    if (isRef(e.intersection)) row.setAttribute('data-x', str(e.intersection));
    row.innerHTML = evHtml(e);
    return row;
  }
  function addEvent(e, top) {
    if (!e || typeof e !== 'object') return;
    const key = evKey(e);
    const old = evRows.get(key);
    if (old) {
      old._e = Object.assign({}, old._e, e);
      old.className = evClass(old._e);
      old.innerHTML = evHtml(old._e);
      return;
    }
    const row = makeEvRow(e);
    row._key = key;
    evRows.set(key, row);
    if (top) evEl.insertBefore(row, evEl.firstChild);
    else evEl.appendChild(row);
    trimEvents();
  }
  function trimEvents() {
    while (evRows.size > EV_KEEP && evEl.lastElementChild) {
      const last = evEl.lastElementChild;
      evRows.delete(last._key);
      last.remove();
    }
  }
  function evOrder(a, b) {
    const d = num(b.stamp, 0) - num(a.stamp, 0);
    if (d) return d;
    return collator.compare(str(b.id), str(a.id));
  }
  function setEvents(list) {
    evEl.textContent = '';
    evRows.clear();
    const sorted = list.filter((e) => e && typeof e === 'object').slice().sort(evOrder).slice(0, EV_KEEP);
    const frag = document.createDocumentFragment();
    for (const e of sorted) {
      const key = evKey(e);
      if (evRows.has(key)) continue;
      const row = makeEvRow(e);
      row._key = key;
      evRows.set(key, row);
      frag.appendChild(row);
    }
    evEl.appendChild(frag);
    summariseEvents();
  }
  function summariseEvents() {
    let alarms = 0;
    for (const row of evRows.values()) if (row.classList.contains('alarm')) alarms++;
    $('events-summary').innerHTML = evRows.size + ' shown' + (alarms ? ' · <b class="bad">' + alarms + ' unacknowledged</b>' : '');
    const ac = $('alarmcount');
    ac.hidden = alarms === 0;
    ac.textContent = alarms + (alarms === 1 ? ' alarm' : ' alarms');
  }
  function ackEvent(m) {
    const row = evRows.get(evKey({ id: m.id, source: m.source, district: m.district }));
    if (!row) return;
    row._e = Object.assign({}, row._e, { acked_by: m.by || 'someone', acked_at: m.at });
    row.className = evClass(row._e);
    row.innerHTML = evHtml(row._e);
    summariseEvents();
  }
  $('events-alarms').addEventListener(
    'change',
    guard('filter', () => evEl.classList.toggle('alarms-only', $('events-alarms').checked))
  );
  $('events-history').addEventListener(
    'click',
    guard('history', () => {
      const b = $('events-history');
      b.disabled = true;
      b.textContent = 'loading…';
      fetch('/api/events?limit=200', { cache: 'no-store' })
        .then((r) => (r.ok ? r.json() : Promise.reject(new Error('HTTP ' + r.status))))
        .then(
          guard('history', (body) => {
            const merged = new Map();
            for (const row of evRows.values()) merged.set(row._key, row._e);
            for (const e of arr(body && body.events)) {
              if (!e || typeof e !== 'object') continue;
              const k = e.id !== undefined && e.id !== null ? evKey(e) : 'h-' + ++evSeq;
              merged.set(k, Object.assign({}, merged.get(k) || {}, e));
            }
            setEvents(Array.from(merged.values()));
          })
        )
        .catch((e) => fail('history', e))
        .finally(() => {
          b.disabled = false;
          b.textContent = 'history';
        });
    })
  );
  evEl.addEventListener(
    'click',
    guard('event select', (e) => {
      if (e.target.closest('button')) return;
      const row = e.target.closest('.ev[data-x]');
      if (row) {
        const name = xNameOf(row.getAttribute('data-x'));
        if (name) select(name, true);
      }
    })
  );

  // ---------------------------------------------------------------- devices
  // A city may have thousands of devices: the table only holds the rows in view (plus a margin),
  // between two spacer rows; up to DEV_ALL rows are all in the table.
  const devBody = $('devices').tBodies[0];
  const devWrap = $('devices').parentElement;
  const DEV_ROW_H = 20; // px, as in style.css
  const DEV_ALL = 150;
  const devices = new Map(); // id -> {d, key}
  let devSorted = []; // records by id
  let devShown = []; // those that pass the filter
  const devFilter = { text: '', problems: false };
  const devView = { top: 0, height: 400, queued: false, ageEls: [] };
  // A device the SCM no longer hears is "lost", whatever it said last.
  function devHealth(d) {
    return d.lost ? 'lost' : str(d.health || 'unknown');
  }
  function devCells(d) {
    const health = devHealth(d);
    const lamp = devLampCell(d);
    const detail = str(d.detail);
    return (
      '<td class="mono" title="' + esc([d.kind, d.backend, d.host].filter(Boolean).join(' · ')) + '">' + esc(d.id) +
      '</td><td><span class="health h-' + esc(health) + '">' + esc(health) + '</span></td><td>' + esc(d.mode) +
      '</td><td>' + lamp + '</td><td class="det" title="' + esc(detail) + '">' + esc(detail) + '</td><td class="age mono"></td>'
    );
  }
  // A light's lamp column: what its head shows now (its signal_<i>/state, live), else the aspect
  // its last status reported (0..5: a fail-safe flash is 4), by name.
  const ASPECT_NAME = ['off', 'red', 'yellow', 'green', 'flashing red', 'flashing yellow'];
  const ASPECT_FILL = [LAMP_FILL[0], LAMP_FILL[1], LAMP_FILL[2], LAMP_FILL[3], LAMP_FILL[1], LAMP_FILL[2]];
  function devLampCell(d) {
    const head = /^signal_(\d+)$/.exec(str(d.id));
    let n = head && lamps.has(head[1]) ? lamps.get(head[1]) : undefined;
    if (n === undefined) {
      const v = d.lamp;
      if (v === undefined || v === null || v === '') return '';
      n = typeof v === 'number' ? v : ASPECT_NAME.indexOf(String(v));
    }
    if (!(n >= 0 && n < ASPECT_NAME.length)) return esc(String(n));
    return '<i class="dot" style="background:' + ASPECT_FILL[n] + '"></i>' + ASPECT_NAME[n];
  }
  // A lamp changed: its row's lamp cell, when the row is in the table.
  function devLampChanged(head) {
    if (!$('p-devices').open) return;
    const row = devBody.querySelector('tr[data-id="signal_' + head + '"]');
    const rec = devices.get('signal_' + head);
    if (row && rec && row.cells.length > 3) row.cells[3].innerHTML = devLampCell(rec.d);
  }
  function devProblem(d) {
    return devHealth(d) !== 'ok';
  }
  function devVisible(d) {
    const f = devFilter.text;
    if (devFilter.problems && !devProblem(d)) return false;
    if (!f) return true;
    return [d.id, d.kind, d.backend, d.health, d.mode, d.detail, d.host].some((v) => str(v).toLowerCase().includes(f));
  }
  function devResort() {
    devSorted = Array.from(devices.values()).sort((a, b) => collator.compare(str(a.d.id), str(b.d.id)));
    devRefilter();
  }
  function devRefilter() {
    devShown = devSorted.filter((r) => devVisible(r.d));
    queueDevRows();
  }
  function queueDevRows() {
    if (devView.queued) return;
    devView.queued = true;
    requestAnimationFrame(guard('devices', renderDevRows));
  }
  function renderDevRows() {
    devView.queued = false;
    if (!$('p-devices').open) return;
    const n = devShown.length;
    let first = 0;
    let last = n;
    if (n > DEV_ALL) {
      first = Math.max(0, Math.floor(devView.top / DEV_ROW_H) - 15);
      last = Math.min(n, Math.ceil((devView.top + devView.height) / DEV_ROW_H) + 15);
    }
    const html = [];
    const spacer = (h) => '<tr class="spacer"><td colspan="6" style="height:' + h + 'px"></td></tr>';
    if (first > 0) html.push(spacer(first * DEV_ROW_H));
    for (let i = first; i < last; i++) {
      const d = devShown[i].d;
      html.push('<tr class="dh-' + esc(devHealth(d)) + '" data-id="' + esc(d.id) + '">' + devCells(d) + '</tr>');
    }
    if (last < n) html.push(spacer((n - last) * DEV_ROW_H));
    if (!n) html.push('<tr class="empty"><td colspan="6">' + (devices.size ? 'no device matches' : 'no device') + '</td></tr>');
    devBody.innerHTML = html.join('');
    devView.ageEls = [];
    for (const tr of devBody.rows) {
      if (tr.className === 'spacer' || tr.className === 'empty') continue;
      devView.ageEls.push([tr.lastElementChild, devices.get(tr.getAttribute('data-id'))]);
    }
    devAges();
  }
  function devAges() {
    const now = serverNow();
    for (const [el, rec] of devView.ageEls) {
      if (!rec) continue;
      // A device the SCM still hears is live: its row comes again only when its status
      // changes, so the age of its last report is known only for one lost (or never heard).
      const last = num(rec.d.last, NaN);
      const live = rec.d.lost === false && Number.isFinite(last);
      const t = live ? 'live' : fmtAge(Number.isFinite(last) ? now - last : NaN);
      if (el.textContent !== t) el.textContent = t;
    }
  }
  function setDevices(list) {
    devices.clear();
    for (const d of list) if (d && d.id !== undefined && d.id !== null) devices.set(String(d.id), { d, key: JSON.stringify(d) });
    devResort();
    summariseDevices();
  }
  function mergeDevices(list) {
    let added = false;
    let changed = false;
    for (const d of list) {
      if (!d || d.id === undefined || d.id === null) continue;
      const id = String(d.id);
      const key = JSON.stringify(d);
      const rec = devices.get(id);
      if (rec && rec.key === key) continue;
      changed = true;
      if (rec) {
        rec.d = d;
        rec.key = key;
      } else {
        devices.set(id, { d, key });
        added = true;
      }
    }
    if (!changed) return;
    if (added) devResort();
    else devRefilter();
    summariseDevices();
  }
  function summariseDevices() {
    const n = { ok: 0, degraded: 0, fault: 0, offline: 0, lost: 0, other: 0 };
    for (const r of devices.values()) {
      const h = devHealth(r.d);
      if (h in n) n[h]++;
      else n.other++;
    }
    const parts = [devices.size + ' devices'];
    if (n.degraded) parts.push('<b class="warn">' + n.degraded + ' degraded</b>');
    if (n.fault) parts.push('<b class="bad">' + n.fault + ' fault</b>');
    if (n.offline) parts.push('<b class="off">' + n.offline + ' offline</b>');
    if (n.lost) parts.push('<b class="bad">' + n.lost + ' lost</b>');
    $('devices-summary').innerHTML = parts.join(' · ');
  }
  function applyDevFilter() {
    devFilter.text = $('devices-filter').value.trim().toLowerCase();
    devFilter.problems = $('devices-problems').checked;
    devRefilter();
  }
  $('devices-filter').addEventListener('input', guard('filter', applyDevFilter));
  $('devices-problems').addEventListener('change', guard('filter', applyDevFilter));
  $('p-devices').addEventListener('toggle', guard('devices', queueDevRows));
  devWrap.addEventListener(
    'scroll',
    guard('devices', () => {
      devView.top = devWrap.scrollTop;
      if (devShown.length > DEV_ALL) queueDevRows();
    }),
    { passive: true }
  );
  new ResizeObserver(
    guard('devices', (entries) => {
      for (const en of entries) devView.height = en.contentRect.height || devView.height;
      if (devShown.length > DEV_ALL) queueDevRows();
    })
  ).observe(devWrap);

  // ---------------------------------------------------------------- processes
  const procs = new Map();
  function renderProcs() {
    const list = Array.from(procs.values()).sort((a, b) => collator.compare(str(a.name), str(b.name)));
    $('p-processes').hidden = list.length === 0;
    let bad = 0;
    $('processes').tBodies[0].innerHTML = list
      .map((p) => {
        const st = str(p.state);
        const ok = /^(running|ok|up|ready|started)$/i.test(st);
        if (!ok) bad++;
        return (
          '<tr><td class="mono">' + esc(p.name) + '</td><td><span class="health h-' + (ok ? 'ok' : /start|wait|stopp/i.test(st) ? 'degraded' : 'fault') + '">' + esc(st) +
          '</span></td><td class="mono">' + esc(p.pid) + '</td><td class="mono' + (num(p.restarts, 0) > 0 ? ' warn' : '') + '">' + esc(p.restarts) +
          '</td><td class="det" title="' + esc(p.detail) + '">' + esc(p.detail) + '</td></tr>'
        );
      })
      .join('');
    $('processes-summary').innerHTML = list.length + ' processes' + (bad ? ' · <b class="warn">' + bad + ' not running</b>' : '');
  }
  function mergeProcs(list, replace) {
    if (replace) procs.clear();
    for (const p of list) if (p && p.name !== undefined && p.name !== null) procs.set(String(p.name), p);
    renderProcs();
  }

  // ---------------------------------------------------------------- V2I requests
  const reqs = new Map(); // vehicle/request -> {r, at}
  const REQ_KEEP = 200;
  function reqKey(r) {
    return str(r.vehicle) + '/' + str(r.request);
  }
  function mergeReqs(list, replace) {
    if (replace) reqs.clear();
    const t = Date.now();
    for (const r of list) {
      if (!r || typeof r !== 'object') continue;
      const k = reqKey(r);
      reqs.delete(k); // re-insert: the map's order is the order of updates
      reqs.set(k, { r, at: t });
    }
    while (reqs.size > REQ_KEEP) reqs.delete(reqs.keys().next().value);
    renderReqs();
  }
  function renderReqs() {
    const now = serverNow();
    const rows = [];
    let active = 0;
    const list = Array.from(reqs.values()).reverse();
    for (const { r } of list) {
      const st = str(r.status);
      if (/^(granted|pending|requested|queued|processing)$/i.test(st)) active++;
      const eg = num(r.expected_green, NaN);
      let egt = '';
      if (Number.isFinite(eg)) {
        if (eg > 1e8) {
          const d = eg - now;
          egt = d > 0 ? 'in ' + d.toFixed(1) + ' s' : fmtTime(eg);
        } else {
          egt = eg.toFixed(1) + ' s';
        }
      } else if (r.expected_green !== undefined && r.expected_green !== null) {
        egt = str(r.expected_green);
      }
      const cls = /grant/i.test(st) ? 'h-ok' : /reject|denied|fail|expired|cancel/i.test(st) ? 'h-fault' : 'h-degraded';
      rows.push(
        '<tr' + (r.reason ? ' title="' + esc(r.reason) + '"' : '') + '><td class="mono">' + esc(r.vehicle) +
          (r.request !== undefined && r.request !== null ? '<small> #' + esc(r.request) + '</small>' : '') +
          '</td><td>' + esc(xNameOf(r.intersection) || r.intersection) + '</td><td><span class="health ' + cls + '">' + esc(st) + '</span></td><td class="mono">' + esc(isRef(r.group) ? r.group : '–') +
          '</td><td class="mono">' + esc(egt) + '</td></tr>'
      );
    }
    $('requests').tBodies[0].innerHTML = rows.length ? rows.join('') : '<tr class="empty"><td colspan="5">no V2I request</td></tr>';
    $('requests-summary').textContent = reqs.size ? reqs.size + ' · ' + active + ' open' : '';
  }

  // ---------------------------------------------------------------- cameras
  const BLANK = 'data:image/gif;base64,R0lGODlhAQABAIAAAAAAAP///yH5BAEAAAAALAAAAAABAAEAAAIBRAA7';
  let cameraList = [];
  const camOpen = new Set();
  let camFirstShown = false; // the first camera streams from the start, until the user hides it
  function renderCameras() {
    const box = $('cameras');
    // stop every stream first
    for (const img of box.querySelectorAll('img')) {
      img.src = BLANK;
      img.remove();
    }
    box.textContent = '';
    $('cameras-summary').textContent = cameraList.length ? String(cameraList.length) : 'none';
    if (!cameraList.length) {
      box.innerHTML = '<div class="empty">no camera in this city</div>';
      return;
    }
    if (!camFirstShown) {
      camFirstShown = true;
      camOpen.add(str(cameraList[0].name));
    }
    for (const c of cameraList) {
      const name = str(c.name);
      const div = document.createElement('div');
      div.className = 'cam';
      div.innerHTML =
        '<div class="camh"><button type="button" class="camtoggle" aria-pressed="false">show</button> <b>' + esc(name) + '</b> <small class="mono">' + esc(c.topic) + '</small></div>';
      const btn = div.querySelector('button');
      btn.addEventListener('click', guard('camera', () => toggleCamera(div, name, !camOpen.has(name))));
      box.appendChild(div);
      if (camOpen.has(name)) toggleCamera(div, name, true);
    }
  }
  function toggleCamera(div, name, open) {
    const btn = div.querySelector('button');
    let img = div.querySelector('img');
    if (open) {
      camOpen.add(name);
      if (!img) {
        img = document.createElement('img');
        img.alt = 'camera ' + name;
        img.className = 'camimg';
        img.addEventListener('error', () => {
          if (img.src !== BLANK) img.classList.add('broken');
        });
        img.src = '/camera/' + encodeURIComponent(name) + '.mjpg';
        img.title = 'click: larger / smaller';
        img.addEventListener('click', () => img.classList.toggle('big'));
        div.appendChild(img);
      }
      btn.textContent = 'hide';
      btn.setAttribute('aria-pressed', 'true');
    } else {
      camOpen.delete(name);
      if (img) {
        img.src = BLANK;
        img.remove();
      }
      btn.textContent = 'show';
      btn.setAttribute('aria-pressed', 'false');
    }
  }
  $('p-cameras').addEventListener(
    'toggle',
    guard('cameras', () => {
      if ($('p-cameras').open) return;
      for (const div of $('cameras').querySelectorAll('.cam')) {
        const name = div.querySelector('b').textContent;
        if (camOpen.has(name)) toggleCamera(div, name, false);
      }
    })
  );

  // ---------------------------------------------------------------- charts
  const WINDOW_MS = 300000;
  const samples = []; // one a second: {t, sumo, appr: {xkey: {approach: n}}, queue: {xkey: n}, rates}
  let lastStats = null;
  function takeSample() {
    const appr = {};
    const queue = {};
    for (const v of fleet) {
      if (!v || !isRef(v.intersection)) continue;
      const k = String(v.intersection);
      if (isRef(v.approach)) {
        const a = String(v.approach);
        const o = appr[k] || (appr[k] = {});
        o[a] = (o[a] || 0) + 1;
      }
      const sp = num(v.speed, NaN);
      const ts = num(v.to_stop_line, NaN);
      if (Number.isFinite(sp) && Math.abs(sp) < 0.02 && ts > 0 && ts < 1.5) queue[k] = (queue[k] || 0) + 1;
    }
    let qall = 0;
    for (const k in queue) qall += queue[k];
    const st = lastStats || {};
    samples.push({
      t: Date.now(),
      sumo: objects.length,
      appr,
      queue,
      qall,
      rates: { eye: num(st.eye_hz, null), spat: num(st.spat_hz, null), fleet: num(st.fleet_hz, null), traffic: num(st.traffic_hz, null) },
    });
    const t0 = Date.now() - WINDOW_MS - 2000;
    while (samples.length && samples[0].t < t0) samples.shift();
  }
  // Canvas widths as the ResizeObserver reports them (reading clientWidth would force a layout).
  const chartRO = new ResizeObserver(
    guard('charts', (entries) => {
      let grew = false;
      for (const en of entries) {
        if (!en.target._w && en.contentRect.width > 0) grew = true;
        en.target._w = en.contentRect.width;
      }
      if (grew) drawCharts();
    })
  );
  for (const id of ['chart-approach', 'chart-queue', 'chart-spat', 'chart-rates']) chartRO.observe($(id));
  function prep(cv, hCss) {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(50, cv._w || 300);
    const h = hCss;
    if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) {
      cv.width = Math.round(w * dpr);
      cv.height = Math.round(h * dpr);
      cv.style.height = h + 'px';
    }
    const ctx = cv.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    // setting a font resolves style: only when the canvas was reset (resized)
    if (cv._font !== cv.width + 'x' + cv.height) {
      cv._font = cv.width + 'x' + cv.height;
      ctx.font = '10px system-ui, sans-serif';
    }
    return { ctx, w, h };
  }
  function niceMax(v) {
    if (!(v > 0)) return 1;
    const p = Math.pow(10, Math.floor(Math.log10(v)));
    for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= v) return m * p;
    return 10 * p;
  }
  function timeAxis(ctx, x0, x1, y, t1) {
    ctx.fillStyle = '#7d8794';
    ctx.strokeStyle = 'rgba(255,255,255,0.06)';
    ctx.textAlign = 'center';
    ctx.textBaseline = 'top';
    for (let m = 5; m >= 0; m--) {
      const x = x1 - ((m * 60000) / WINDOW_MS) * (x1 - x0);
      ctx.beginPath();
      ctx.moveTo(x + 0.5, 4);
      ctx.lineTo(x + 0.5, y);
      ctx.stroke();
      ctx.fillText(m ? '−' + m + 'm' : 'now', Math.min(x, x1 - 10), y + 2);
    }
    void t1;
  }
  function lineChart(cv, series, opt) {
    const { ctx, w, h } = prep(cv, opt.height || 84);
    const L = 30;
    const R = opt.right ? 34 : 8;
    const T = 6;
    const Bm = 14;
    const x0 = L;
    const x1 = w - R;
    const y0 = h - Bm;
    const y1 = T;
    const t1 = Date.now();
    const tx = (t) => x1 - ((t1 - t) / WINDOW_MS) * (x1 - x0);
    let maxL = 0;
    let maxR = 0;
    for (const s of series) for (const p of s.pts) if (p[1] !== null) (s.right ? (maxR = Math.max(maxR, p[1])) : (maxL = Math.max(maxL, p[1])));
    maxL = niceMax(opt.minMax ? Math.max(maxL, opt.minMax) : maxL);
    maxR = niceMax(maxR);
    timeAxis(ctx, x0, x1, y0, t1);
    ctx.strokeStyle = 'rgba(255,255,255,0.08)';
    ctx.fillStyle = '#7d8794';
    ctx.textBaseline = 'middle';
    for (const f of [0, 0.5, 1]) {
      const y = Math.round(y0 - f * (y0 - y1)) + 0.5;
      ctx.beginPath();
      ctx.moveTo(x0, y);
      ctx.lineTo(x1, y);
      ctx.stroke();
      ctx.textAlign = 'right';
      ctx.fillText(fmtAxis(maxL * f), x0 - 4, y);
      if (opt.right) {
        ctx.textAlign = 'left';
        ctx.fillText(fmtAxis(maxR * f), x1 + 4, y);
      }
    }
    ctx.save();
    ctx.beginPath();
    ctx.rect(x0, 0, x1 - x0, h);
    ctx.clip();
    for (const s of series) {
      const max = s.right ? maxR : maxL;
      ctx.strokeStyle = s.color;
      ctx.lineWidth = s.width || 1.5;
      ctx.setLineDash(s.dash ? [4, 3] : []);
      ctx.beginPath();
      let pen = false;
      let lastY = 0;
      for (const p of s.pts) {
        if (p[1] === null || !Number.isFinite(p[1])) {
          pen = false;
          continue;
        }
        const x = tx(p[0]);
        const y = y0 - (p[1] / max) * (y0 - y1);
        if (!pen) ctx.moveTo(x, y);
        else if (s.step) {
          ctx.lineTo(x, lastY);
          ctx.lineTo(x, y);
        } else ctx.lineTo(x, y);
        pen = true;
        lastY = y;
      }
      ctx.stroke();
    }
    ctx.restore();
    ctx.setLineDash([]);
    if (opt.empty) {
      ctx.fillStyle = '#5d6673';
      ctx.textAlign = 'center';
      ctx.textBaseline = 'middle';
      ctx.fillText(opt.empty, (x0 + x1) / 2, (y0 + y1) / 2);
    }
  }
  function fmtAxis(v) {
    if (v === 0) return '0';
    if (v >= 1000) return (v / 1000).toFixed(v >= 10000 ? 0 : 1) + 'k';
    return Number.isInteger(v) ? String(v) : v.toFixed(1);
  }
  function legend(id, items) {
    const el = $(id);
    const key = JSON.stringify(items);
    if (el.dataset.key === key) return;
    el.dataset.key = key;
    el.innerHTML = items
      .map((i) => '<span><i class="sw' + (i.dash ? ' dash' : '') + '" style="border-color:' + i.color + '"></i>' + esc(i.label) + '</span>')
      .join('');
  }
  function selKeys() {
    const rec = selected ? X.get(selected) : null;
    if (!rec) return [];
    const k = [rec.name];
    if (rec.id !== null && rec.id !== undefined && String(rec.id) !== rec.name) k.push(String(rec.id));
    return k;
  }
  function drawCharts() {
    if (!$('p-charts').open) return;
    attempt('chart approach', drawApproachChart);
    attempt('chart queue', drawQueueChart);
    attempt('chart spat', drawSpatChart);
    attempt('chart rates', drawRatesChart);
  }
  function drawApproachChart() {
    const keys = selKeys();
    const approaches = new Set();
    for (const s of samples) for (const k of keys) if (s.appr[k]) for (const a in s.appr[k]) approaches.add(a);
    const list = Array.from(approaches).sort(collator.compare);
    const series = list.map((a, i) => ({
      label: 'approach ' + a,
      color: PALETTE[i % PALETTE.length],
      step: true,
      pts: samples.map((s) => {
        let n = 0;
        for (const k of keys) n += (s.appr[k] && s.appr[k][a]) || 0;
        return [s.t, n];
      }),
    }));
    series.push({ label: 'SUMO total (right)', color: '#9aa3ad', dash: true, right: true, width: 1, pts: samples.map((s) => [s.t, s.sumo]) });
    lineChart($('chart-approach'), series, { right: true, minMax: 2, empty: list.length ? '' : keys.length ? 'no lab car on an approach' : 'no intersection selected' });
    legend('lg-approach', series.map((s) => ({ label: s.label, color: s.color, dash: s.dash })));
  }
  function drawQueueChart() {
    const keys = selKeys();
    const series = [
      {
        label: (selected || 'selected') + ' queue',
        color: '#ff8a65',
        step: true,
        width: 2,
        pts: samples.map((s) => {
          let n = 0;
          for (const k of keys) n += s.queue[k] || 0;
          return [s.t, n];
        }),
      },
      { label: 'all intersections', color: '#6b7785', dash: true, step: true, width: 1, pts: samples.map((s) => [s.t, s.qall]) },
    ];
    lineChart($('chart-queue'), series, { minMax: 2 });
    legend('lg-queue', series.map((s) => ({ label: s.label, color: s.color, dash: s.dash })));
  }
  function drawSpatChart() {
    const cv = $('chart-spat');
    const rec = selected ? X.get(selected) : null;
    const gids = rec ? Array.from(rec.hist.keys()).sort(collator.compare) : [];
    const rowH = 12;
    const h = Math.max(36, gids.length * (rowH + 2) + 18);
    const { ctx, w } = prep(cv, h);
    const x0 = 44;
    const x1 = w - 8;
    const y0 = h - 14;
    const t1 = Date.now();
    const tx = (t) => Math.max(x0, x1 - ((t1 - t) / WINDOW_MS) * (x1 - x0));
    timeAxis(ctx, x0, x1, y0, t1);
    if (!gids.length) {
      ctx.fillStyle = '#5d6673';
      ctx.textAlign = 'center';
      ctx.textBaseline = 'middle';
      ctx.fillText(rec ? 'no SPaT yet' : 'no intersection selected', (x0 + x1) / 2, y0 / 2);
      return;
    }
    ctx.textBaseline = 'middle';
    gids.forEach((gid, i) => {
      const y = 3 + i * (rowH + 2);
      ctx.fillStyle = '#9aa3ad';
      ctx.textAlign = 'right';
      const nm = groupName(rec, gid);
      ctx.fillText((nm ? nm.slice(0, 6) + ' ' : '') + gid, x0 - 4, y + rowH / 2);
      const h2 = rec.hist.get(gid);
      for (let j = 0; j < h2.length; j++) {
        const a = tx(h2[j][0]);
        const b = j + 1 < h2.length ? tx(h2[j + 1][0]) : x1;
        if (b <= a) continue;
        ctx.fillStyle = sg(h2[j][1])[2];
        ctx.fillRect(a, y, b - a, rowH);
      }
    });
  }
  function drawRatesChart() {
    const defs = [
      ['eye', 'eye', '#36c5f0'],
      ['spat', 'SPaT', '#2ee66b'],
      ['fleet', 'fleet', '#ffb74d'],
      ['traffic', 'traffic', '#b57cff'],
    ];
    const series = defs.map(([k, label, color]) => ({ label, color, pts: samples.map((s) => [s.t, s.rates[k]]) }));
    lineChart($('chart-rates'), series, { empty: lastStats ? '' : 'no stats yet' });
    legend('lg-rates', series.map((s) => ({ label: s.label, color: s.color })));
  }
  $('p-charts').addEventListener('toggle', guard('charts', drawCharts));

  // ---------------------------------------------------------------- the stream
  function replaceState(s) {
    dash.stateReceived = true;
    $('city').textContent = s.city ? str(s.city) : s.map && s.map.name ? str(s.map.name) : 'city';
    document.title = (s.city ? s.city + ' · ' : '') + 'autodrive dashboard';
    needToken = s.actions_need_token !== false;
    noteNow(s.now);
    lamps.clear();
    const hs = s.heads && typeof s.heads === 'object' ? s.heads : {};
    for (const k in hs) lamps.set(String(k), lampNum(hs[k]));
    const m = s.map || null;
    // The intersection index first: the heads refer to intersections.
    attempt('state: intersections', () => {
      buildXsecs(arr(m && m.intersections), arr(s.intersections), arr(s.spat));
    });
    attempt('state: map', () => setupMap(m));
    attempt('state: intersections', () => {
      for (const i of arr(s.intersections)) mergeI(i);
      for (const x of arr(s.spat)) mergeX(x, s.now);
      buildAreas();
      for (const rec of X.values()) renderRec(rec);
      if (!selected || !X.has(selected)) {
        selected = null;
        const first = X.keys().next();
        if (!first.done) select(first.value, false);
        else {
          $('sel-name').textContent = 'no intersection';
          fillPlans();
        }
      } else {
        select(selected, false);
      }
      summariseX();
    });
    attempt('state: fleet', () => {
      for (const c of cars.values()) c.g.remove();
      cars.clear();
      applyFleet(arr(s.vehicles));
    });
    attempt('state: traffic', () => {
      objects = arr(s.objects);
      $('sumo-count').textContent = objects.length;
    });
    attempt('state: devices', () => setDevices(arr(s.devices)));
    attempt('state: processes', () => mergeProcs(arr(s.processes), true));
    attempt('state: requests', () => mergeReqs(arr(s.requests), true));
    attempt('state: events', () => setEvents(arr(s.events)));
    attempt('state: cameras', () => {
      cameraList = arr(s.cameras).filter((c) => c && c.name !== undefined && c.name !== null);
      for (const n of Array.from(camOpen)) if (!cameraList.some((c) => str(c.name) === n)) camOpen.delete(n);
      renderCameras();
    });
    measure();
    applyScale();
    drawTraffic();
    drawCharts();
  }

  const handlers = {
    state: replaceState,
    lamps(m) {
      const h = m.heads && typeof m.heads === 'object' ? m.heads : {};
      for (const k in h) setLamp(k, h[k]);
    },
    spat(m) {
      noteNow(m.now);
      for (const x of arr(m.intersections)) {
        const rec = mergeX(x, m.now);
        if (rec) {
          renderGroups(rec);
          renderHead(rec);
          applyXFilter(rec);
          if (rec.name === selected) fillPlans();
        }
      }
    },
    fleet(m) {
      noteNow(m.now);
      applyFleet(arr(m.vehicles), m.now);
    },
    traffic(m) {
      objects = arr(m.objects);
      $('sumo-count').textContent = objects.length;
      queueTraffic();
    },
    intersections(m) {
      for (const i of arr(m.intersections)) {
        const rec = mergeI(i);
        if (rec) {
          renderRec(rec);
          if (rec.name === selected) fillPlans();
        }
      }
      summariseX();
    },
    devices(m) {
      mergeDevices(arr(m.devices));
    },
    processes(m) {
      mergeProcs(arr(m.processes), false);
    },
    event(m) {
      addEvent(m.event, true);
      summariseEvents();
    },
    events(m) {
      // A burst, gathered by the server (a storm of device alarms): oldest first.
      for (const e of arr(m.events)) addEvent(e, true);
      summariseEvents();
    },
    ack(m) {
      ackEvent(m);
    },
    requests(m) {
      mergeReqs(arr(m.requests), false);
    },
    stats(m) {
      lastStats = m;
      $('rates').textContent =
        'eye ' + fmtHz(m.eye_hz) + ' · spat ' + fmtHz(m.spat_hz) + ' · fleet ' + fmtHz(m.fleet_hz) + ' · traffic ' + fmtHz(m.traffic_hz) + ' Hz' +
        (m.clients !== undefined ? ' · ' + m.clients + (m.clients === 1 ? ' client' : ' clients') : '');
    },
  };

  const LIVE_STREAMS = new Set(['lamps', 'spat', 'fleet', 'traffic']);
  function noteMessage(name, m) {
    dash.messages[name] = (dash.messages[name] || 0) + 1;
    lastMessageAt = performance.now();
    const rx = m && typeof m === 'object' ? num(m.rx, NaN) : NaN;
    if (!Number.isFinite(rx)) return;
    const l = Date.now() - rx;
    const a = dash.latencies[name] || (dash.latencies[name] = []);
    a.push(l);
    if (a.length > LAT_KEEP) a.splice(0, a.length - LAT_KEEP);
    // The header's figure: the live streams only (events and devices may carry old stamps:
    // the latched history a new connection gets).
    if (LIVE_STREAMS.has(name)) {
      recentLat.push(l);
      if (recentLat.length > RECENT_KEEP) recentLat.splice(0, recentLat.length - RECENT_KEEP);
    }
  }

  let es = null;
  let lastMessageAt = 0;
  let retryTimer = 0;
  function setConn(live) {
    dash.connected = live;
    const c = $('conn');
    c.textContent = live ? 'live' : 'reconnecting…';
    c.className = live ? 'conn-live' : 'conn-down';
  }
  function connect() {
    retryTimer = 0;
    if (typeof EventSource === 'undefined') {
      $('conn').textContent = 'no EventSource in this browser';
      return;
    }
    es = new EventSource('/api/stream');
    es.onopen = guard('open', () => setConn(true));
    es.onerror = guard('stream', () => {
      setConn(false);
      // The browser retries by itself unless the answer was not an event stream; then we do.
      if (es && es.readyState === 2 && !retryTimer) {
        es.close();
        retryTimer = setTimeout(connect, 3000);
      }
    });
    for (const name of Object.keys(handlers)) {
      es.addEventListener(name, (ev) => {
        const t0 = performance.now();
        try {
          const m = JSON.parse(ev.data);
          noteMessage(name, m);
          if (!m || typeof m !== 'object') throw new Error('not a JSON object');
          handlers[name](m);
        } catch (e) {
          fail(name, e);
        }
        const dt = performance.now() - t0;
        const h = dash.handlerMs[name] || (dash.handlerMs[name] = [0, 0, 0]);
        h[0]++;
        h[1] += dt;
        if (dt > h[2]) h[2] = dt;
      });
    }
  }

  // ---------------------------------------------------------------- one timer for the page
  let ticks = 0;
  function tick() {
    // countdowns, a few times a second
    for (const rec of X.values()) if (rec.expanded && rec.cds.length) countdown(rec);
    if (++ticks % 4 !== 0) return;
    // once a second
    const d = new Date();
    $('clock').textContent = pad2(d.getHours()) + ':' + pad2(d.getMinutes()) + ':' + pad2(d.getSeconds());
    if (recentLat.length) {
      const s = recentLat.slice().sort((a, b) => a - b);
      const q = (p) => s[Math.min(s.length - 1, Math.floor(p * s.length))];
      const p50 = q(0.5);
      const p99 = q(0.99);
      const el = $('latency');
      el.textContent = 'p50 ' + Math.round(p50) + ' ms · p99 ' + Math.round(p99) + ' ms';
      el.className = 'mono' + (p99 > 500 ? ' bad' : p99 > 150 ? ' warn' : '');
    }
    if (dash.connected) {
      const idle = (performance.now() - lastMessageAt) / 1000;
      $('conn').title = idle > 3 ? 'no message for ' + Math.round(idle) + ' s' : 'event stream open';
      $('conn').classList.toggle('idle', idle > 3);
    }
    attempt('sample', takeSample);
    drawCharts();
    attempt('devices', devAges);
    if (reqs.size) attempt('requests', renderReqs);
  }
  setInterval(guard('tick', tick), 250);

  $('errbadge').addEventListener('click', () => {
    dash.errors = 0;
    $('errbadge').hidden = true;
  });

  window.addEventListener('error', (e) => {
    fail('page', e.error || e.message);
  });
  window.addEventListener('unhandledrejection', (e) => {
    fail('page', e.reason);
    e.preventDefault();
  });

  attempt('start', () => {
    measure();
    fillPlans();
    renderReqs();
    renderProcs();
    connect();
  });
})();
