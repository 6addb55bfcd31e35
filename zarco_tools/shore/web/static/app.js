/* zarco shore web: the page.  Telemetry arrives on a WebSocket from the page
   server (every sample as the boat sends it: the state at 5 Hz); commands go
   back as POST /api/command with this page's token. */
"use strict";

const TOKEN = document.querySelector('meta[name="zarco-token"]').content;
const TAIL_MAX = 1500;          // points kept per track tail
const SPARK_S = 300;            // the distance sparkline's window (s)
const STALE_S = 2.0;            // telemetry older than this shows the link as stale
const $ = (id) => document.getElementById(id);

const vessels = new Map();      // name → the page's view of that vessel
let selected = "";
let preferred = "";             // the console's vessel, if it names one
let map = null;
let ws = null;
let wsFailures = 0;
let renderPending = false;
// for the benchmark and the tests: when each state reached the page (ms since the epoch)
window.zarco = {renders: [], samples: 0, bytes: 0, connected: false,
  latest: (kind, name) => { const v = vessels.get(name || selected); return v ? v[kind] : null; },
  selected: () => selected};

function vessel(name) {
  let v = vessels.get(name);
  if (!v) {
    v = {name, state: null, health: null, auv: null, map: null, events: [], role: "unknown",
         received: {}, boatTail: [], auvTail: [], spark: []};
    vessels.set(name, v);
    refreshSelector();
  }
  return v;
}

// ------------------------------------------------------------------ telemetry

function onSample(name, kind, d, now) {
  const v = vessel(name);
  v.received[kind] = now;
  if (kind === "event") {
    v.events.push(d);
    if (v.events.length > 50) v.events.shift();
  } else {
    v[kind] = d;
  }
  if (kind === "state" && d.lat_deg !== null && d.lat_deg !== undefined) {
    addTail(v.boatTail, [d.lat_deg, d.lon_deg], d.t);
  }
  if (kind === "auv") {
    if (d.lat_deg !== null && d.lat_deg !== undefined) addTail(v.auvTail, [d.lat_deg, d.lon_deg], d.t);
    if (d.distance_m !== null && d.distance_m !== undefined) {
      v.spark.push([d.t, d.distance_m]);
      while (v.spark.length && v.spark[0][0] < d.t - SPARK_S) v.spark.shift();
    }
  }
}

function addTail(tail, p, t) {
  const last = tail[tail.length - 1];
  if (last && last[2] === t) return;
  tail.push([p[0], p[1], t]);
  if (tail.length > TAIL_MAX) tail.splice(0, tail.length - TAIL_MAX);
}

function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  ws = new WebSocket(`${proto}//${location.host}/ws`);
  ws.onopen = () => { wsFailures = 0; window.zarco.connected = true; };
  ws.onmessage = (ev) => {
    window.zarco.bytes += ev.data.length;
    const m = JSON.parse(ev.data);
    const now = Date.now();
    if (m.type === "s") {
      window.zarco.samples += 1;
      onSample(m.v, m.k, m.d, now);
      if (m.v === selected || !selected) {
        if (!selected) select(m.v);
        update();
        if (m.k === "state") {
          window.zarco.renders.push([m.v, m.d.t, Date.now()]);
          if (window.zarco.renders.length > 5000) window.zarco.renders.shift();
        }
      } else {
        scheduleRender();
      }
    } else if (m.type === "hello") {
      preferred = m.vessel || "";
      for (const [name, snap] of Object.entries(m.vessels)) {
        const v = vessel(name);
        v.role = snap.role;
        for (const k of ["state", "health", "auv", "map"]) {
          if (snap[k]) onSample(name, k, snap[k], now - 1000 * ((snap.age_s || {})[k] || 0));
        }
        v.events = snap.events || [];
      }
      $("role").dataset.user = m.user;
      if (!selected || !vessels.has(selected)) {
        const names = [...vessels.keys()].sort();
        if (names.length) select(preferred && vessels.has(preferred) ? preferred : names[0]);
      }
      update();
    } else if (m.type === "role") {
      vessel(m.v).role = m.role;
      if (m.v === selected) update();
    }
  };
  ws.onclose = () => {
    window.zarco.connected = false;
    wsFailures += 1;
    $("link").textContent = "page server offline";
    $("link").className = "pill bad";
    // the server may have restarted (and forgotten this page's session): reload then
    setTimeout(() => (wsFailures > 3 ? location.reload() : connect()), 1000 * Math.min(wsFailures, 5));
  };
}

// ------------------------------------------------------------------ selection

function refreshSelector() {
  const sel = $("vessel");
  const names = [...vessels.keys()].sort();
  if (sel.options.length === names.length && [...sel.options].every((o, i) => o.value === names[i])) return;
  sel.replaceChildren(...names.map((n) => new Option(n, n, false, n === selected)));
}

function select(name) {
  if (!vessels.has(name)) return;
  selected = name;
  $("vessel").value = name;
  $("cmd-result").textContent = "";
  $("cmd-result").className = "";
  if (map) map.followBoat = true;
  $("follow-boat").setAttribute("aria-pressed", "true");
  update();
}

// ------------------------------------------------------------------ panels

const fmt = (x, d, unit) => (x === null || x === undefined ? "—" : `${Number(x).toFixed(d)}${unit || ""}`);

function setPill(id, text, cls) {
  const e = $(id);
  e.textContent = text;
  e.className = "pill " + (cls || "");
}

function utcTime(t) {
  return new Date(t * 1000).toISOString().substring(11, 19);
}

function update() {
  const v = vessels.get(selected);
  if (!v) return;
  const s = v.state || {};
  const now = Date.now();
  const age = v.received.state ? (now - v.received.state) / 1000 : null;
  if (age === null) setPill("link", "no state yet", "warn");
  else if (age > STALE_S) setPill("link", `stale ${age.toFixed(0)} s`, "bad");
  else setPill("link", "live", "ok");
  setPill("mode", s.mode || "—", s.mode === "idle" ? "off" : "");
  setPill("armed", s.armed === undefined ? "—" : s.armed ? "armed" : "disarmed", s.armed ? "warn" : "off");
  const fixCls = {rtk_fixed: "ok", rtk_float: "ok", dgps: "warn", single: "warn"}[s.fix] || "bad";
  setPill("fix", s.fix ? `fix ${s.fix}` : "fix —", fixCls);
  const fs = s.failsafes || [];
  $("failsafes").hidden = fs.length === 0;
  $("failsafes").textContent = fs.length ? "failsafe: " + fs.join(", ") : "";

  const op = v.role === "operator";
  $("stop").hidden = !op;
  $("commands").hidden = !op;
  $("stop").textContent = `STOP ${v.name}`;
  const user = $("role").dataset.user || "";
  $("role").textContent = v.role === "operator" ? `operator (${user})`
    : v.role === "viewer" ? `viewer (${user}): watching only` : "checking permissions…";

  $("position").textContent = s.lat_deg === null || s.lat_deg === undefined ? "—"
    : `${zarcoFmt.fmtLat(s.lat_deg, 6)} ${zarcoFmt.fmtLon(s.lon_deg, 6)}` + (s.pos_valid === false ? " (not valid)" : "");
  $("speed").textContent = `${fmt(s.speed_mps, 2, " m/s")}, ${fmt(s.course_deg, 0, "°")}`;
  $("heading").textContent = fmt(s.heading_deg, 1, "°") + (s.heading_valid === false ? " (not valid)" : "");
  $("leg").textContent = s.legs ? `${s.leg === null ? "—" : s.leg + 1} of ${s.legs}` : "—";
  $("xtrack").textContent = fmt(s.xtrack_m, 2, " m");
  $("thrust").textContent = `${fmt(s.u1, 0)}, ${fmt(s.u2, 0)}`;
  $("reason").textContent = s.reason || "—";

  const a = v.auv;
  const aAge = v.received.auv ? (now - v.received.auv) / 1000 : null;
  $("distance").textContent = a && a.distance_m !== null && a.distance_m !== undefined ? a.distance_m.toFixed(1) : "—";
  $("auv-status").textContent = a ? a.status + (aAge > 30 ? ` (${aAge.toFixed(0)} s ago)` : "") : "no track";
  $("auv-status").className = "pill " + (a ? {tracking: "ok", turning: "warn", acquiring: "warn"}[a.status] || "bad" : "off");
  $("auv-detail").textContent = a ? `AUV ${fmt(a.speed_mps, 2, " m/s")}, course ${fmt(a.course_deg, 0, "°")}` +
    (a.pos_cov_m2 ? `, 1σ ${Math.sqrt(Math.max(a.pos_cov_m2[0] || 0, a.pos_cov_m2[2] || 0)).toFixed(1)} m` : "") : "";
  $("sound-speed").textContent = a && typeof a.sound_speed_mps === "number"
    ? `${a.sound_speed_mps.toFixed(1)}` + (typeof a.sound_speed_sigma_mps === "number"
      ? ` ± ${a.sound_speed_sigma_mps.toFixed(1)}` : "") + " m/s" : "—";
  spark(v);
  devices(v, now);
  events(v);
  scheduleRender();
}

function spark(v) {
  const svg = $("spark");
  svg.replaceChildren();
  const pts = v.spark;
  if (pts.length < 2) { $("spark-range").textContent = ""; return; }
  const t1 = pts[pts.length - 1][0], t0 = t1 - SPARK_S;
  let lo = Infinity, hi = -Infinity;
  for (const [, d] of pts) { lo = Math.min(lo, d); hi = Math.max(hi, d); }
  const top = Math.max(hi, lo + 1);
  const line = document.createElementNS("http://www.w3.org/2000/svg", "polyline");
  line.setAttribute("points", pts.map(([t, d]) => `${((t - t0) / SPARK_S * 300).toFixed(1)},${(58 - (d - 0) / top * 56).toFixed(1)}`).join(" "));
  svg.appendChild(line);
  $("spark-range").textContent = `0 – ${top.toFixed(0)} m (now ${pts[pts.length - 1][1].toFixed(1)})`;
}

function devices(v, now) {
  const tab = $("devices");
  const devs = (v.health && v.health.devices) || {};
  const since = v.received.health ? (now - v.received.health) / 1000 : 0;
  const rows = Object.keys(devs).sort().map((n) => {
    const d = devs[n];
    const tr = document.createElement("tr");
    tr.dataset.device = n;
    const th = document.createElement("th"); th.textContent = n;
    const st = document.createElement("td"); st.textContent = d.state; st.className = "st-" + d.state;
    const ag = document.createElement("td");
    ag.textContent = d.age_s === null || d.age_s === undefined ? "never" : `${(d.age_s + since).toFixed(1)} s`;
    ag.title = "since its last valid sentence";
    const ok = document.createElement("td"); ok.textContent = `${d.ok} ok, ${d.bad} bad`;
    tr.append(th, st, ag, ok);
    return tr;
  });
  if (rows.length) tab.replaceChildren(...rows);
}

function events(v) {
  const ol = $("events");
  const items = v.events.slice(-12).reverse().map((e) => {
    const li = document.createElement("li");
    li.className = "k-" + e.kind;
    const t = document.createElement("span"); t.className = "time"; t.textContent = utcTime(e.t);
    const k = document.createElement("span"); k.className = "kind"; k.textContent = e.kind;
    const x = document.createElement("span"); x.textContent = e.text;
    li.append(t, k, x);
    return li;
  });
  ol.replaceChildren(...items);
}

// ------------------------------------------------------------------ map

function scene() {
  const v = vessels.get(selected);
  if (!v) return null;
  const m = v.map;
  if (m && m.origin) {
    if (map.setOrigin(m.origin.lat_deg, m.origin.lon_deg, false)) map.followBoat = true;
  } else if (!map.frame && v.state && v.state.lat_deg !== null && v.state.lat_deg !== undefined) {
    map.setOrigin(v.state.lat_deg, v.state.lon_deg, true);
  }
  if (!map.frame) return null;
  $("origin-note").textContent = map.provisional ? "origin: the first position (the boat's map not heard yet)"
    : `origin ${zarcoFmt.fmtLat(map.frame.lat0, 5)} ${zarcoFmt.fmtLon(map.frame.lon0, 5)}`;
  const put = (x) => {
    const f = map.frame;
    const boat = x.state && x.state.lat_deg !== null && x.state.lat_deg !== undefined
      ? (([n, e]) => ({n, e, heading: x.state.heading_deg, t: x.state.t}))(f.toLocal(x.state.lat_deg, x.state.lon_deg)) : null;
    const a = x.auv && x.auv.lat_deg !== null && x.auv.lat_deg !== undefined && x.auv.status !== "lost"
      ? (([n, e]) => ({n, e, t: x.auv.t, course: x.auv.course_deg, cov: x.auv.pos_cov_m2,
                       line: x.auv.status === "tracking" || x.auv.status === "stale"}))(f.toLocal(x.auv.lat_deg, x.auv.lon_deg)) : null;
    return {name: x.name, boat, auv: a, state: x.state, map: x.map,
            boatTail: local(x.boatTail, f), auvTail: local(x.auvTail, f)};
  };
  const sc = put(v);
  sc.others = [...vessels.values()].filter((o) => o.name !== selected).map(put);
  return sc;
}

function local(tail, f) {
  // a tail's points on the map's plane (each converted once per origin)
  return tail.map((p) => {
    if (p[3] !== f) { const [n, e] = f.toLocal(p[0], p[1]); p[3] = f; p[4] = n; p[5] = e; }
    return [p[4], p[5]];
  });
}

function scheduleRender() {
  if (renderPending) return;
  renderPending = true;
  requestAnimationFrame(() => { renderPending = false; draw(); });
}

function draw() {
  const sc = scene();
  if (sc) map.render(sc);
  if (!map.hover) $("cursor").hidden = true;
  $("follow-boat").setAttribute("aria-pressed", String(map.followBoat));
}

function fitAll() {
  const sc = scene();
  if (!sc) return;
  const pts = [...sc.boatTail, ...sc.auvTail];
  if (sc.boat) pts.push([sc.boat.n, sc.boat.e]);
  if (sc.auv) pts.push([sc.auv.n, sc.auv.e]);
  const m = sc.map || {};
  for (const b of m.beacons || []) pts.push(map.frame.toLocal(b.lat_deg, b.lon_deg));
  for (const p of (m.mission && m.mission.waypoints) || []) pts.push(map.frame.toLocal(p[0], p[1]));
  map.followBoat = false;
  map.fit(pts);
  draw();
}

// ------------------------------------------------------------------ commands

const COMMANDS = {
  arm: ["arm", {}], disarm: ["disarm", {}], hold: ["mode", {mode: "hold"}], resume: ["resume", {}],
  follow: ["follow", {}], return: ["mode", {mode: "return"}], stop: ["stop", {}],
};

async function send(what) {
  const v = vessels.get(selected);
  if (!v || v.role !== "operator") return;
  const [name, args] = COMMANDS[what];
  const out = $("cmd-result");
  out.className = "";
  out.textContent = `${what} → ${v.name}…`;
  const t0 = performance.now();
  let r;
  try {
    const resp = await fetch("/api/command", {
      method: "POST", credentials: "same-origin",
      headers: {"Content-Type": "application/json", "X-Zarco-Token": TOKEN},
      body: JSON.stringify({vessel: v.name, name, args}),
    });
    r = await resp.json();
  } catch (err) {
    r = {ok: false, reason: `page server not reachable (${err})`};
  }
  const ms = (performance.now() - t0).toFixed(0);
  const text = r.ok ? `${what}: accepted by ${v.name}, mode ${r.mode} (${ms} ms)`
    : `${what}: REFUSED${r.refused_by ? " by the " + r.refused_by : ""}: ${r.reason}`;
  out.textContent = text;
  out.className = r.ok ? "ok" : "bad";
  const li = document.createElement("li");
  li.textContent = `${new Date().toISOString().substring(11, 19)} ${text}`;
  $("cmd-log").prepend(li);
  while ($("cmd-log").children.length > 6) $("cmd-log").lastChild.remove();
}

// ------------------------------------------------------------------ start

function start() {
  map = new ZarcoMap($("map"));
  map.onview = () => { $("follow-boat").setAttribute("aria-pressed", String(map.followBoat)); scheduleRender(); };
  map.onselect = (name) => select(name);
  $("vessel").addEventListener("change", (ev) => select(ev.target.value));
  $("zoom-in").addEventListener("click", () => { map.zoomBy(1.5); draw(); });
  $("zoom-out").addEventListener("click", () => { map.zoomBy(1 / 1.5); draw(); });
  $("fit").addEventListener("click", fitAll);
  $("follow-boat").addEventListener("click", () => { map.followBoat = !map.followBoat; draw(); });
  $("stop").addEventListener("click", () => send("stop"));
  for (const b of document.querySelectorAll("#commands button[data-cmd]")) {
    b.addEventListener("click", () => send(b.dataset.cmd));
  }
  document.addEventListener("keydown", (ev) => {
    if (ev.key === "Escape") { ev.preventDefault(); send("stop"); return; }
    if (ev.target && ["INPUT", "SELECT", "TEXTAREA"].includes(ev.target.tagName)) return;
    if (ev.key === "+" || ev.key === "=") { map.zoomBy(1.5); draw(); }
    else if (ev.key === "-") { map.zoomBy(1 / 1.5); draw(); }
    else if (ev.key === "0") fitAll();
    else if (ev.key === "f") { map.followBoat = !map.followBoat; draw(); }
  });
  window.addEventListener("resize", scheduleRender);
  setInterval(update, 1000);  // ages and the link's freshness move on without samples
  connect();
}

start();
