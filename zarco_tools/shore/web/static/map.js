/* zarco shore web: the map.  North-up, metres north/east about the selected
   vessel's origin (its [origin]); positions arrive in WGS-84 degrees and are
   put on the origin's tangent plane (NED) as the boat's own frame does, so a
   mission's metres are the map's.  Plain SVG, no library. */
"use strict";

const WGS84_A = 6378137.0;
const WGS84_F = 1 / 298.257223563;
const WGS84_E2 = WGS84_F * (2 - WGS84_F);
const SVGNS = "http://www.w3.org/2000/svg";
const DEG = Math.PI / 180;

function niceStep(x) {
  // the 1-2-5 step at or above x
  const p = Math.pow(10, Math.floor(Math.log10(x)));
  for (const m of [1, 2, 5, 10]) if (m * p >= x) return m * p;
  return 10 * p;
}

function el(parent, name, attrs, text) {
  const e = document.createElementNS(SVGNS, name);
  for (const k in attrs) if (attrs[k] !== undefined) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  if (parent) parent.appendChild(e);
  return e;
}

class LocalFrame {
  /* the local tangent plane (NED) at the origin, as the boat's own frame:
     geodetic → ECEF → north, east (the sea surface, height 0) */
  constructor(lat0, lon0) {
    this.lat0 = lat0; this.lon0 = lon0;
    this.o = ecef(lat0, lon0);
    const p = lat0 * DEG, l = lon0 * DEG;
    this.sp = Math.sin(p); this.cp = Math.cos(p); this.sl = Math.sin(l); this.cl = Math.cos(l);
  }
  toLocal(lat, lon) {
    const [x, y, z] = ecef(lat, lon);
    const dx = x - this.o[0], dy = y - this.o[1], dz = z - this.o[2];
    const e = -this.sl * dx + this.cl * dy;
    const n = -this.sp * this.cl * dx - this.sp * this.sl * dy + this.cp * dz;
    return [n, e];
  }
  toGeo(n, e) {
    // the point of the plane (down 0) back to latitude and longitude
    const dx = -this.sp * this.cl * n - this.sl * e;
    const dy = -this.sp * this.sl * n + this.cl * e;
    const dz = this.cp * n;
    const x = this.o[0] + dx, y = this.o[1] + dy, z = this.o[2] + dz;
    const lon = Math.atan2(y, x);
    const r = Math.hypot(x, y);
    let lat = Math.atan2(z, r * (1 - WGS84_E2));
    for (let i = 0; i < 5; i++) {
      const s = Math.sin(lat);
      const nr = WGS84_A / Math.sqrt(1 - WGS84_E2 * s * s);
      lat = Math.atan2(z + WGS84_E2 * nr * s, r);
    }
    return [lat / DEG, lon / DEG];
  }
}

function ecef(lat, lon) {
  const p = lat * DEG, l = lon * DEG;
  const s = Math.sin(p), c = Math.cos(p);
  const nr = WGS84_A / Math.sqrt(1 - WGS84_E2 * s * s);
  return [nr * c * Math.cos(l), nr * c * Math.sin(l), nr * (1 - WGS84_E2) * s];
}

class ZarcoMap {
  constructor(svg) {
    this.svg = svg;
    this.frame = null;
    this.provisional = false;
    this.cn = 0; this.ce = 0;  // view centre (m)
    this.scale = 2.0;          // pixels per metre
    this.followBoat = true;
    this.hover = null;         // [x, y] of the cursor (px) or null
    this.scene = null;
    this.onview = null;        // called when the user pans or zooms
    this.onselect = null;      // called with a vessel's name when its marker is clicked
    this.layers = {};
    for (const name of ["grid", "geo", "static", "tracks", "vessels"])
      this.layers[name] = el(svg, "g", {class: name, id: "layer-" + name});
    this._wire();
  }

  setOrigin(lat, lon, provisional) {
    const same = this.frame && this.frame.lat0 === lat && this.frame.lon0 === lon;
    if (same && this.provisional === provisional) return false;
    this.frame = new LocalFrame(lat, lon);
    this.provisional = provisional;
    return true;
  }

  size() {
    const r = this.svg.getBoundingClientRect();
    return [Math.max(r.width, 10), Math.max(r.height, 10)];
  }

  // metres (n, e) → pixels (x, y) and back
  px(n, e) {
    const [w, h] = this.size();
    return [w / 2 + (e - this.ce) * this.scale, h / 2 - (n - this.cn) * this.scale];
  }
  metres(x, y) {
    const [w, h] = this.size();
    return [this.cn - (y - h / 2) / this.scale, this.ce + (x - w / 2) / this.scale];
  }

  zoomBy(f, x, y) {
    const [w, h] = this.size();
    if (x === undefined) { x = w / 2; y = h / 2; }
    const [n, e] = this.metres(x, y);
    this.scale = Math.min(200, Math.max(0.01, this.scale * f));
    const [n2, e2] = this.metres(x, y);
    this.cn += n - n2; this.ce += e - e2;
  }

  fit(points) {
    // show every point given ([n, e] pairs) with a margin
    if (!points.length) return;
    let n0 = Infinity, n1 = -Infinity, e0 = Infinity, e1 = -Infinity;
    for (const [n, e] of points) {
      n0 = Math.min(n0, n); n1 = Math.max(n1, n); e0 = Math.min(e0, e); e1 = Math.max(e1, e);
    }
    const [w, h] = this.size();
    this.cn = (n0 + n1) / 2; this.ce = (e0 + e1) / 2;
    const span = Math.max((n1 - n0) / (h * 0.8), (e1 - e0) / (w * 0.8), 1 / 20);
    this.scale = 1 / span;
  }

  _wire() {
    const svg = this.svg;
    let drag = null;
    svg.addEventListener("pointerdown", (ev) => {
      const v = ev.target.closest("[data-vessel]");
      if (v && this.onselect) { this.onselect(v.getAttribute("data-vessel")); return; }
      drag = [ev.clientX, ev.clientY, this.cn, this.ce];
      svg.setPointerCapture(ev.pointerId);
      svg.classList.add("dragging");
    });
    svg.addEventListener("pointermove", (ev) => {
      const r = svg.getBoundingClientRect();
      this.hover = [ev.clientX - r.left, ev.clientY - r.top];
      if (drag) {
        this.cn = drag[2] + (ev.clientY - drag[1]) / this.scale;
        this.ce = drag[3] - (ev.clientX - drag[0]) / this.scale;
        this.followBoat = false;
      }
      if (this.onview) this.onview();
    });
    const end = () => { drag = null; svg.classList.remove("dragging"); };
    svg.addEventListener("pointerup", end);
    svg.addEventListener("pointercancel", end);
    svg.addEventListener("pointerleave", () => { this.hover = null; if (this.onview) this.onview(); });
    svg.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const r = svg.getBoundingClientRect();
      this.zoomBy(Math.exp(-ev.deltaY * 0.0015), ev.clientX - r.left, ev.clientY - r.top);
      if (this.onview) this.onview();
    }, {passive: false});
  }

  // ----------------------------------------------------------------- drawing

  render(scene) {
    this.scene = scene;
    if (!this.frame) return;
    if (this.followBoat && scene.boat) { this.cn = scene.boat.n; this.ce = scene.boat.e; }
    for (const k in this.layers) this.layers[k].replaceChildren();
    this._grid();
    if (this.hover) this._graticule();
    this._static(scene);
    for (const o of scene.others) this._vessel(o, false);
    this._vessel(scene, true);
  }

  _grid() {
    const g = this.layers.grid;
    const [w, h] = this.size();
    const step = niceStep(90 / this.scale);
    const [nTop, eLeft] = this.metres(0, 0);
    const [nBot, eRight] = this.metres(w, h);
    for (let e = Math.ceil(eLeft / step) * step; e <= eRight; e += step) {
      const [x] = this.px(0, e);
      el(g, "line", {x1: x, y1: 0, x2: x, y2: h, class: Math.abs(e) < step / 2 ? "axis" : ""});
      el(g, "text", {x: x + 3, y: h - 4}, `${fmtM(e)}`);
    }
    for (let n = Math.ceil(nBot / step) * step; n <= nTop; n += step) {
      const [, y] = this.px(n, 0);
      el(g, "line", {x1: 0, y1: y, x2: w, y2: y, class: Math.abs(n) < step / 2 ? "axis" : ""});
      el(g, "text", {x: 4, y: y - 3}, `${fmtM(n)}`);
    }
    // scale bar
    const len = niceStep(100 / this.scale);
    const bar = document.getElementById("scale-bar");
    if (bar) {
      bar.replaceChildren();
      const px = len * this.scale;
      el(bar, "rect", {x: 1, y: 3, width: px, height: 6, fill: "#1c2330"});
      el(bar, "rect", {x: 1 + px / 2, y: 4, width: px / 2 - 1, height: 4, fill: "#fff"});
      document.getElementById("scale-text").textContent = fmtM(len) + " m";
    }
  }

  _graticule() {
    // the geodetic grid in degrees while the cursor is over the map
    const g = this.layers.geo;
    const [w, h] = this.size();
    const [latTop, lonLeft] = this.frame.toGeo(...this.metres(0, 0));
    const [latBot, lonRight] = this.frame.toGeo(...this.metres(w, h));
    const step = niceStep((latTop - latBot) / 5);
    const digits = Math.max(0, -Math.floor(Math.log10(step)));
    for (let lat = Math.ceil(latBot / step) * step; lat <= latTop; lat += step) {
      const [, y] = this.px(...this.frame.toLocal(lat, this.frame.lon0));
      el(g, "line", {x1: 0, y1: y, x2: w, y2: y});
      el(g, "text", {x: w - 90, y: y - 3}, fmtLat(lat, digits));
    }
    const lstep = niceStep((lonRight - lonLeft) / 5);
    const ldigits = Math.max(0, -Math.floor(Math.log10(lstep)));
    for (let lon = Math.ceil(lonLeft / lstep) * lstep; lon <= lonRight; lon += lstep) {
      const [x] = this.px(...this.frame.toLocal(this.frame.lat0, lon));
      el(g, "line", {x1: x, y1: 0, x2: x, y2: h});
      el(g, "text", {x: x + 3, y: 100}, fmtLon(lon, ldigits));
    }
    const [cn, ce] = this.metres(...this.hover);
    const [clat, clon] = this.frame.toGeo(cn, ce);
    const c = document.getElementById("cursor");
    if (c) {
      c.hidden = false;
      c.textContent = `N ${cn.toFixed(1)} m, E ${ce.toFixed(1)} m · ${fmtLat(clat, 6)} ${fmtLon(clon, 6)}`;
    }
  }

  _pts(list) {
    return list.map(([n, e]) => this.px(n, e).map((v) => v.toFixed(1)).join(",")).join(" ");
  }

  _static(s) {
    const g = this.layers.static;
    const m = s.map || {};
    const f = this.frame;
    const ll = (p) => f.toLocal(p.lat_deg, p.lon_deg);
    const fence = m.geofence || {};
    if (fence.radius_m > 0 && m.home) {
      const [x, y] = this.px(...ll(m.home));
      el(g, "circle", {cx: x, cy: y, r: fence.radius_m * this.scale, class: "fence", id: "fence-circle"});
    }
    if (fence.polygon && fence.polygon.length >= 3) {
      el(g, "polygon", {points: this._pts(fence.polygon.map(([a, b]) => f.toLocal(a, b))), class: "fence", id: "fence-polygon"});
    }
    const mi = m.mission;
    if (mi && mi.waypoints && mi.waypoints.length >= 2) {
      const pts = mi.waypoints.map(([a, b]) => f.toLocal(a, b));
      el(g, "polyline", {points: this._pts(pts), class: "mission" + (mi.active ? "" : " done"), id: "mission"});
      const leg = s.state && s.state.leg;
      if (mi.active && leg !== null && leg !== undefined && leg + 1 < pts.length) {
        el(g, "polyline", {points: this._pts([pts[leg], pts[leg + 1]]), class: "mission", "stroke-width": 4});
      }
      for (const p of pts) { const [x, y] = this.px(...p); el(g, "circle", {cx: x, cy: y, r: 3.5, class: "mission-pt"}); }
    }
    const plan = m.auv_plan || (s.plan || []);
    if (plan.length >= 2) {
      el(g, "polyline", {points: this._pts(plan.map(([a, b]) => f.toLocal(a, b))), class: "plan", id: "auv-plan"});
    }
    (m.beacons || []).forEach((b, i) => {
      const [x, y] = this.px(...ll(b));
      el(g, "path", {d: `M${x} ${y - 8} L${x + 7} ${y + 5} L${x - 7} ${y + 5} Z`, class: "beacon", "data-beacon": b.id});
      el(g, "text", {x: x + 9, y: y + 4, class: "beacon-label"}, `B${b.id}${i === m.listener ? " (buoy)" : ""}`);
    });
    if (m.buoy) {
      const [x, y] = this.px(...ll(m.buoy));
      el(g, "circle", {cx: x, cy: y, r: 5, class: "buoy", id: "buoy"});
    }
    if (m.home) {
      const [x, y] = this.px(...ll(m.home));
      el(g, "path", {d: `M${x} ${y - 9} L${x + 8} ${y - 2} L${x + 6} ${y + 7} L${x - 6} ${y + 7} L${x - 8} ${y - 2} Z`, class: "home", id: "home"});
      el(g, "text", {x: x + 10, y: y + 4, class: "home-label"}, "home");
    }
  }

  _vessel(v, selected) {
    const g = el(this.layers.vessels, "g", selected ? {id: "vessel-" + v.name} : {class: "other", "data-vessel": v.name});
    const t = el(this.layers.tracks, "g", selected ? {} : {class: "other"});
    if (v.boatTail && v.boatTail.length > 1) el(t, "polyline", {points: this._pts(v.boatTail), class: "tail boat"});
    if (v.auvTail && v.auvTail.length > 1) el(t, "polyline", {points: this._pts(v.auvTail), class: "tail auv"});
    const a = v.auv;
    if (a) {
      const [x, y] = this.px(a.n, a.e);
      if (a.line) {
        const c = a.course * DEG, L = Math.max(60, 120 / this.scale);
        const [x1, y1] = this.px(a.n - L * Math.cos(c), a.e - L * Math.sin(c));
        const [x2, y2] = this.px(a.n + L * Math.cos(c), a.e + L * Math.sin(c));
        el(g, "line", {x1, y1, x2, y2, class: "fitline", id: selected ? "auv-line" : undefined});
      }
      if (a.cov) {
        const [nn, ne, ee] = a.cov;
        const tr = (ee + nn) / 2, d = Math.sqrt(((ee - nn) / 2) ** 2 + ne * ne);
        const l1 = Math.max(tr + d, 0), l2 = Math.max(tr - d, 0);
        const ang = 0.5 * Math.atan2(2 * ne, ee - nn) / DEG;  // major axis from east toward north
        el(g, "ellipse", {cx: x, cy: y, rx: Math.max(Math.sqrt(l1) * this.scale, 0.5),
          ry: Math.max(Math.sqrt(l2) * this.scale, 0.5), transform: `rotate(${-ang} ${x} ${y})`,
          class: "ellipse", id: selected ? "auv-ellipse" : undefined,
          "data-sigma-major-m": Math.sqrt(l1).toFixed(2), "data-sigma-minor-m": Math.sqrt(l2).toFixed(2)});
      }
      if (v.boat) {
        const [bx, by] = this.px(v.boat.n, v.boat.e);
        el(g, "line", {x1: bx, y1: by, x2: x, y2: y, class: "link-line"});
      }
    }
    if (v.boat) {
      const b = v.boat;
      const [x, y] = this.px(b.n, b.e);
      const m = el(g, "g", {transform: `translate(${x.toFixed(1)},${y.toFixed(1)}) rotate(${b.heading || 0})`,
        id: selected ? "boat" : undefined, "data-n": b.n.toFixed(3), "data-e": b.e.toFixed(3),
        "data-heading": (b.heading || 0).toFixed(1), "data-t": b.t});
      el(m, "path", {d: "M0 -13 L7 7 L0 3 L-7 7 Z", class: "boat-shape"});
      el(g, "text", {x: x + 12, y: y - 10, class: "vessel-label"}, v.name);
    }
    if (a) {  // the AUV above the boat: when the boat is right over it, both show
      const [x, y] = this.px(a.n, a.e);
      const m = el(g, "g", {transform: `translate(${x.toFixed(1)},${y.toFixed(1)}) rotate(${a.course || 0})`,
        id: selected ? "auv" : undefined, "data-n": a.n.toFixed(3), "data-e": a.e.toFixed(3),
        "data-t": a.t});
      el(m, "path", {d: "M0 -7 L4 -2 L4 6 L-4 6 L-4 -2 Z", class: "auv-shape"});
    }
  }
}

function fmtM(v) {
  const a = Math.abs(v);
  return a >= 100 || a === 0 ? v.toFixed(0) : a >= 1 ? String(+v.toFixed(1)) : String(+v.toFixed(2));
}
function fmtLat(lat, d) { return `${Math.abs(lat).toFixed(d)}° ${lat >= 0 ? "N" : "S"}`; }
function fmtLon(lon, d) { return `${Math.abs(lon).toFixed(d)}° ${lon >= 0 ? "E" : "W"}`; }

window.ZarcoMap = ZarcoMap;
window.ZarcoLocalFrame = LocalFrame;
window.zarcoFmt = {fmtM, fmtLat, fmtLon};
