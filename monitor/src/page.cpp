// The monitor's page: HTML, its style, and its script, with uPlot inline from report/ (so the page
// needs nothing but this server). The script keeps the stream's points, redraws at most five times
// a second, and marks <html> with what it shows (data-connection, data-updates, data-trace-points,
// data-loop-points, data-events, data-last-event, data-trip-delay) so a headless browser's DOM tells
// a test; the address's #press-pause-on=trip presses the pause button when the first trip comes in.
#include <string>

#include "strut/monitor/server.h"
#include "strut/report/html_report.h"

namespace strut::monitor {

namespace {

constexpr const char* kStyle = R"css(
body{margin:0;font:14px/1.4 system-ui,sans-serif;color:#1f2933;background:#f5f7fa}
header{background:#1f3a5f;color:#fff;padding:10px 20px;display:flex;gap:16px;align-items:center;flex-wrap:wrap}
header h1{font-size:18px;margin:0;font-weight:600}
#connection{padding:2px 10px;border-radius:10px;background:#2f8132;font-weight:600}
html[data-connection=disconnected] #connection{background:#ba2525}
html[data-connection=disconnected] main{opacity:.45}
#banner{display:none;background:#ffe3e3;color:#ba2525;padding:8px 20px;font-weight:600}
html[data-connection=disconnected] #banner{display:block}
main{padding:8px 20px;display:grid;grid-template-columns:repeat(auto-fit,minmax(420px,1fr));gap:10px}
section{background:#fff;border:1px solid #d9e2ec;border-radius:4px;padding:6px 10px;min-width:0}
h2{font-size:15px;margin:4px 0}
table{border-collapse:collapse;font-size:13px;width:100%}
td,th{border-bottom:1px solid #e4e7eb;padding:2px 6px;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums}
.bar{height:10px;background:#e4e7eb;border-radius:5px;overflow:hidden}.bar>div{height:10px;background:#2f8132}
.bar.low>div{background:#cb6e17}.bar.out>div{background:#ba2525}
.ok{color:#2f8132}.no{color:#ba2525}
li.done{color:#52606d}li.running{font-weight:700}li.trip{color:#ba2525}
#events{max-height:220px;overflow:auto;font-size:13px;padding-left:18px}
button{font-size:14px;padding:4px 14px;margin-right:8px}
)css";

constexpr const char* kScript = R"js(
(function () {
  "use strict";
  const root = document.documentElement;
  const UNIT = {stroke: [1e3, "mm"], force: [1e-3, "kN"], pressure: [1e-6, "MPa"]};
  let setup = null, T = [], V = [], progress = null, events = [], updates = 0, dirty = false, pressed = false;
  const charts = {};
  const $ = (id) => document.getElementById(id);
  const fmt = (v, d) => (v === null || v === undefined || !isFinite(v)) ? "–" : v.toFixed(d === undefined ? 3 : d);

  function mark(k, v) { root.dataset[k] = String(v); }

  function chart(id, title, xLabel, yLabel, n, loop) {
    const el = $(id);
    const series = [{}];
    const colours = ["#0072b2", "#ba2525", "#ba2525"];
    for (let k = 0; k < n; k++)
      series.push({label: k === 0 ? yLabel : (k === 1 ? "lower limit" : "upper limit"), stroke: colours[k],
                   width: k === 0 ? 1.5 : 1, dash: k === 0 ? undefined : [6, 4], points: {show: false},
                   paths: loop ? linePath : undefined});
    const opts = {title, width: Math.max(300, el.clientWidth - 10), height: 220, series,
                  scales: {x: {time: false}}, legend: {show: false}, cursor: {show: false},
                  axes: [{label: xLabel}, {label: yLabel, size: 60}]};
    if (loop) opts.mode = 2;
    charts[id] = new uPlot(opts, loop ? [null, [[], []]] : [[], ...series.slice(1).map(() => [])], el);
  }

  // Loops turn back on themselves: a path in data order (uPlot's own assumes x ascending).
  function linePath(u, si) {
    const [xs, ys] = u.data[si], path = new Path2D();
    for (let i = 0; i < xs.length; i++) {
      const px = u.valToPos(xs[i], "x", true), py = u.valToPos(ys[i], "y", true);
      if (i) path.lineTo(px, py); else path.moveTo(px, py);
    }
    return {stroke: path, fill: null, clip: null, flags: 0};
  }

  function channel(name) { return setup ? setup.channels.indexOf(name) : -1; }
  function current() { return setup && progress && setup.items[progress.index] ? setup.items[progress.index] : null; }

  function windowFrom() {
    const item = current(), last = T.length ? T[T.length - 1] : 0;
    const periods = item ? 3 / item.frequency : 10;
    return last - Math.max(2, Math.min(periods, 300));
  }

  function drawTraces(from) {
    let start = T.length;
    while (start > 0 && T[start - 1] >= from) start--;
    let points = 0;
    for (const name of ["stroke", "force", "pressure"]) {
      const k = channel(name), c = charts["trace-" + name];
      if (k < 0 || !c) continue;
      const [scale] = UNIT[name], x = T.slice(start), y = V[k].slice(start).map((v) => v * scale);
      const lim = setup.limits[name], data = [x, y];
      if (lim) data.push(x.map(() => lim.lower * scale), x.map(() => lim.upper * scale));
      else data.push(x.map(() => null), x.map(() => null));
      c.setData(data);
      points += x.length;
    }
    mark("tracePoints", points);
  }

  function drawLoops() {
    const item = current(), ks = channel("stroke"), kf = channel("force");
    if (ks < 0 || kf < 0 || !T.length) return;
    const span = item ? 2 / item.frequency : 2, last = T[T.length - 1];
    let start = T.length;
    while (start > 1 && T[start - 1] >= last - span) start--;
    const s = [], f = [], v = [], fv = [];
    for (let i = start; i < T.length; i++) {
      s.push(V[ks][i] * 1e3);
      f.push(V[kf][i] * 1e-3);
      if (i > start && i + 1 < T.length && T[i + 1] > T[i - 1]) {
        v.push((V[ks][i + 1] - V[ks][i - 1]) / (T[i + 1] - T[i - 1]));
        fv.push(V[kf][i] * 1e-3);
      }
    }
    charts["loop-stroke"].setData([null, [s, f]]);
    charts["loop-velocity"].setData([null, [v, fv]]);
    mark("loopPoints", s.length);
  }

  function bar(margin) {
    const m = isFinite(margin) ? Math.max(0, Math.min(1, margin)) : 1;
    const cls = margin < 0 ? "out" : (margin < 0.2 ? "low" : "");
    return `<div class="bar ${cls}"><div style="width:${(100 * m).toFixed(0)}%"></div></div>`;
  }

  function drawTables() {
    const p = progress;
    $("phase").textContent = p ? `${p.experiment} (${p.index + 1}/${p.total}): ${p.phase}, cycle ${p.cycles}, ` +
      `periods ${p.periods_recorded}/${p.periods_requested}` : "waiting for the run";
    if (p) {
      $("margins").innerHTML = ["stroke", "force", "pressure", "following"].map((k) =>
        `<tr><td>${k}</td><td class="num">${fmt(100 * p.margins[k], 0)} %</td><td style="width:60%">${bar(p.margins[k])}</td></tr>`).join("");
      const s = p.steady, t = setup.tolerances;
      const row = (name, value, limit, unit, less) => {
        const ok = value !== null && isFinite(value) && (less ? value <= limit : value >= limit);
        return `<tr><td>${name}</td><td class="num">${fmt(value, 4)}</td><td class="num">${fmt(limit, 4)}</td>` +
               `<td class="${ok ? "ok" : "no"}">${ok ? "within" : "not yet"}</td></tr>`;
      };
      $("steady").innerHTML = s ? [
        row("force change / range", s.force, t.force, "", true),
        row("stroke change / range", s.stroke, t.stroke, "", true),
        row("pressure change / mean", s.pressure, t.pressure, "", true),
        row("drift over the window", s.drift, t.drift, "", true),
        row("cycles agreeing", s.agreeing, t.consecutive, "", false),
        row("recorded s since the first cycle", s.elapsed, t.drift_window, "", false),
      ].join("") + `<tr><td colspan=4>${s.steady ? "steady" : (s.timed_out ? "not steady: time limit" : "waiting")}` +
        ` (measure ${fmt(s.measure, 2)} x tolerance)</td></tr>` : "<tr><td>not settling now</td></tr>";
    }
    $("matrix").innerHTML = setup.items.map((it, i) => {
      const state = !p ? "to come" : (i < p.index || p.phase === "done" ? "done" : (i === p.index ? "running" : "to come"));
      const cls = state === "done" ? "done" : (state === "running" ? "running" : "");
      return `<li class="${cls}">${it.label}: ${it.frequency} Hz, ${fmt(it.amplitude * 1e3, 1)} mm about ` +
             `${fmt(it.static_position * 1e3, 1)} mm — ${state}${state === "running" ? " (" + p.phase + ")" : ""}</li>`;
    }).join("");
    $("events").innerHTML = events.slice().reverse().map((e) =>
      `<li class="${/trip|stop|abort|lost|lag/.test(e.kind + e.text) ? "trip" : ""}">` +
      `<b>${e.kind}</b> ${e.text.replace(/</g, "&lt;")}</li>`).join("");
    mark("events", events.length);
    if (events.length) mark("lastEvent", events[events.length - 1].kind);
  }

  function draw() {
    if (!dirty || !setup) return;
    dirty = false;
    drawTraces(windowFrom());
    drawLoops();
    drawTables();
    mark("drawn", Number(root.dataset.drawn || 0) + 1);
  }

  function trim() {
    const keep = 20000;
    if (T.length > keep) { const d = T.length - keep; T = T.slice(d); V = V.map((c) => c.slice(d)); }
  }

  function build() {
    $("title").textContent = "strut monitor — " + setup.title;
    for (const name of ["stroke", "force", "pressure"])
      if (channel(name) >= 0) chart("trace-" + name, name, "recorded s", `${name} (${UNIT[name][1]})`, 3, false);
    chart("loop-stroke", "force over stroke", "stroke (mm)", "force (kN)", 1, true);
    chart("loop-velocity", "force over velocity", "velocity (m/s)", "force (kN)", 1, true);
    $("controls").style.display = setup.control ? "" : "none";
  }

  function onSnapshot(m) {
    const first = !setup;
    setup = m.setup; T = m.t; V = m.v; progress = m.progress; events = m.events;
    if (first) build();
    dirty = true;
  }

  function onUpdate(m) {
    if (!setup) return;
    T = T.concat(m.t);
    for (let k = 0; k < V.length; k++) V[k] = V[k].concat(m.v[k]);
    trim();
    if (m.progress) progress = m.progress;
    events = events.concat(m.events);
    mark("updates", ++updates);
    // How long after it happened each event reached the page (the hub's clock): data-trip-delay
    // for the first trip, data-last-event-delay for the latest.
    for (const e of m.events) {
      mark("lastEventDelay", (m.now - e.wall).toFixed(3));
      if (e.kind === "trip" && root.dataset.tripDelay === undefined) mark("tripDelay", (m.now - e.wall).toFixed(3));
    }
    // #press-pause-on=KIND (or #press-stop-on=KIND) presses that button when the first event of
    // that kind comes in: for a headless test.
    const press = /^#press-(pause|stop)-on=(.+)$/.exec(location.hash);
    if (press && !pressed && m.events.some((e) => e.kind === press[2])) { pressed = true; control(press[1]); }
    dirty = true;
    if (m.events.length) draw();  // events show at once
  }

  // A failure to draw shows on the page and in <html data-error>, not only in a console.
  function guarded(f) {
    return (e) => {
      try { f(e); } catch (x) { mark("error", x && x.stack ? x.stack : String(x)); $("phase").textContent = "page error: " + x; }
    };
  }

  function connect() {
    const source = new EventSource("events");
    source.onopen = () => mark("connection", "connected");
    source.onerror = () => { mark("connection", "disconnected"); $("connection").textContent = "disconnected"; };
    source.addEventListener("snapshot", guarded((e) => { onSnapshot(JSON.parse(e.data)); $("connection").textContent = "live"; mark("connection", "connected"); }));
    source.addEventListener("update", guarded((e) => { onUpdate(JSON.parse(e.data)); $("connection").textContent = "live"; mark("connection", "connected"); }));
  }

  function control(what) {
    fetch("control/" + what, {method: "POST"}).then((r) => r.text()).then((t) => { $("control-answer").textContent = t; });
  }

  window.addEventListener("load", () => {
    mark("connection", "connecting");
    $("pause").onclick = () => control("pause");
    $("stop").onclick = () => control("stop");
    connect();
    setInterval(guarded(draw), 200);
  });
})();
)js";

}  // namespace

std::string MonitorPage(bool control) {
  std::string page = "<!DOCTYPE html><html lang=\"en\" data-connection=\"connecting\"><head><meta charset=\"utf-8\">"
                     "<title>strut monitor</title><style>";
  page += report::PlotStyle();
  page += kStyle;
  page += "</style></head><body><header><h1 id=\"title\">strut monitor</h1><span id=\"connection\">connecting</span>"
          "<span id=\"phase\"></span><span id=\"controls\" style=\"display:none\">";
  if (control) page += "<button id=\"pause\">Pause after this experiment</button><button id=\"stop\">Stop now</button>";
  else page += "<button id=\"pause\" hidden></button><button id=\"stop\" hidden></button>";
  page += "<span id=\"control-answer\"></span></span></header>"
          "<div id=\"banner\">disconnected: the run has ended or the monitor stopped (the page reconnects when it can)</div>"
          "<main><section><h2>Stroke</h2><div id=\"trace-stroke\"></div></section>"
          "<section><h2>Force</h2><div id=\"trace-force\"></div></section>"
          "<section><h2>Pressure</h2><div id=\"trace-pressure\"></div></section>"
          "<section><h2>Loops of the current experiment</h2><div id=\"loop-stroke\"></div><div id=\"loop-velocity\"></div></section>"
          "<section><h2>Detector margins</h2><table id=\"margins\"></table>"
          "<h2>Steady-state test</h2><table><thead><tr><th>figure</th><th>now</th><th>threshold</th><th></th></tr></thead>"
          "<tbody id=\"steady\"></tbody></table></section>"
          "<section><h2>Matrix</h2><ol id=\"matrix\"></ol></section>"
          "<section><h2>Events</h2><ul id=\"events\"></ul></section></main><script>";
  page += report::PlotScript();
  page += kScript;
  page += "</script></body></html>";
  return page;
}

}  // namespace strut::monitor
