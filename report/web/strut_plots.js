/* strut report figures (docs/reports.md): draws every figure of a strut HTML report with uPlot.
 * The report defines strutData (number arrays shared between figures, referenced by index) and
 * calls strutDrawFigures(list of figure specs) once at the end of the body. Each drawn figure's
 * <div> gets data-drawn="1"; <html> gets data-figures-drawn = how many drew and, for a figure that
 * failed, data-figures-failed, so a headless browser's DOM dump tells whether every plot drew. */
(function () {
  "use strict";

  // Colour-blind-safe palette (Okabe-Ito, darker blue first).
  const palette = ["#0b5394", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#6a3d9a", "#000000"];
  const colour = (i) => palette[i % palette.length];
  const AXIS = {stroke: "#3e4c59", grid: {stroke: "#e4e7eb", width: 1}, ticks: {stroke: "#9aa5b1", width: 1}};
  // A y axis as wide as its longest tick label, so the axis title never overlaps the numbers.
  const yAxisSize = (u, values) => (values ? Math.max(...values.map((v) => String(v).length)) * 7 + 22 : 50);

  function numbers(ref, n) {
    if (ref === null || ref === undefined) return Array.from({length: n}, (_, i) => i);
    return typeof ref === "number" ? window.strutData[ref] : ref;
  }

  // Data extent of several arrays, nulls skipped; widened a little so nothing sits on the frame.
  function extent(arrays, pad) {
    let lo = Infinity, hi = -Infinity;
    for (const a of arrays) for (const v of a) if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) return [0, 1];
    if (lo === hi) { const d = lo === 0 ? 1 : Math.abs(lo) * 0.05; return [lo - d, hi + d]; }
    const d = (hi - lo) * pad;
    return [lo - d, hi + d];
  }

  function format(v) {
    if (v === null || !isFinite(v)) return "–";
    const a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e6) ? v.toExponential(3) : String(+v.toPrecision(5));
  }

  // One line under the plot: the coordinates (or the cell) under the cursor. Appended to the
  // figure's <div> after the chart (show), so it sits below it.
  function readout() {
    const p = document.createElement("div");
    p.className = "readout";
    p.textContent = "\u00a0";
    return p;
  }

  function show(u, el, line) {
    el.appendChild(line);
    return u;
  }

  function base(fig, el, extra) {
    const opts = {
      mode: 2,
      title: fig.title,
      width: Math.max(240, el.clientWidth),
      height: fig.height || 320,
      scales: {x: {time: false}, y: {}},
      axes: [Object.assign({label: fig.x}, AXIS), Object.assign({label: fig.y, size: yAxisSize}, AXIS)],
      legend: {show: fig.legend !== false, live: false},
      cursor: {drag: {x: true, y: true, uni: 30}, points: {show: false}},
      hooks: {draw: [() => { el.dataset.drawn = "1"; }]},
    };
    return Object.assign(opts, extra);
  }

  function setCursorReadout(line, text) {
    return (u) => {
      const {left, top} = u.cursor;
      line.textContent = left == null || left < 0 ? "\u00a0" : text(u, left, top) || "\u00a0";
    };
  }

  // Paths in data order, as the data are (loops turn back on themselves; uPlot's own line path
  // assumes x ascending). A null x or y breaks the line.
  function linePath(u, si) {
    const [xs, ys] = u.data[si], path = new Path2D();
    let pen = false;
    for (let i = 0; i < xs.length; i++) {
      if (xs[i] === null || ys[i] === null) { pen = false; continue; }
      const px = u.valToPos(xs[i], "x", true), py = u.valToPos(ys[i], "y", true);
      if (pen) path.lineTo(px, py); else path.moveTo(px, py);
      pen = true;
    }
    return {stroke: path, fill: null, clip: null, flags: 0};
  }

  function markerPath(radius) {
    return (u, si) => {
      const [xs, ys] = u.data[si], path = new Path2D(), r = radius * (devicePixelRatio || 1);
      for (let i = 0; i < xs.length; i++) {
        if (xs[i] === null || ys[i] === null) continue;
        const px = u.valToPos(xs[i], "x", true), py = u.valToPos(ys[i], "y", true);
        path.moveTo(px + r, py);
        path.arc(px, py, r, 0, 2 * Math.PI);
      }
      return {stroke: null, fill: path, clip: null, flags: 0};
    };
  }

  // Lines and markers of y over x, each series with its own x. Markers (measured data) are drawn
  // first, small and light, so the lines (the model) stay visible on top of them.
  function xy(fig, el) {
    const order = fig.series.map((s, i) => i);
    order.sort((a, b) => (fig.series[a].mode === "markers" ? 0 : 1) - (fig.series[b].mode === "markers" ? 0 : 1));
    const series = [null], data = [null];
    for (const i of order) {
      const s = fig.series[i];
      const y = numbers(s.y), x = numbers(s.x, y.length);
      const c = colour(i);
      if (s.mode === "markers") {
        series.push({label: s.name, stroke: c, fill: c + "59", width: 0, paths: markerPath(1.6), points: {show: false}});
      } else if (s.mode === "lines+markers") {
        const dots = markerPath(2.5);
        series.push({label: s.name, stroke: c, fill: c, width: 1.5, points: {show: false},
                     paths: (u, si) => Object.assign(linePath(u, si), {fill: dots(u, si).fill})});
      } else {
        series.push({label: s.name, stroke: c, width: 1.5, paths: linePath, points: {show: false}});
      }
      data.push([x, y]);
    }
    const line = readout();
    const opts = base(fig, el, {series});
    // Called with the shown series' data extent (not on zoom): x tight, y with a small margin.
    opts.scales.x.range = (u, lo, hi) => extent([[lo, hi]], 0);
    opts.scales.y.range = (u, lo, hi) => extent([[lo, hi]], 0.04);
    opts.hooks.setCursor = [setCursorReadout(line, (u, l, t) =>
      `${fig.x}: ${format(u.posToVal(l, "x"))}    ${fig.y}: ${format(u.posToVal(t, "y"))}`)];
    return show(new uPlot(opts, data, el), el, line);
  }

  // Per category a marker at the mean and a bar of +- half (figure spec: categories, series with
  // mean and half), several series side by side.
  function errorbars(fig, el) {
    const n = fig.categories.length, m = fig.series.length;
    const step = m > 1 ? Math.min(0.15, 0.6 / (m - 1)) : 0;
    const series = [null], data = [null], ends = [];
    fig.series.forEach((s, k) => {
      const offset = (k - 0.5 * (m - 1)) * step;
      const x = s.mean.map((_, i) => i + offset);
      series.push({label: s.name, stroke: colour(k), fill: colour(k), width: 0, paths: markerPath(3.5),
                   points: {show: false}});
      data.push([x, s.mean]);
      s.mean.forEach((v, i) => { if (v !== null && s.half[i] !== null) ends.push(v - s.half[i], v + s.half[i]); });
    });
    ends.push(0);  // zero stays in view: the reference a residual mean is read against
    const yr = extent([ends], 0.06);
    const line = readout();
    const opts = base(fig, el, {series});
    opts.legend.show = m > 1;
    opts.scales.x.range = () => [-0.5, n - 0.5];
    opts.scales.y.range = () => yr;
    opts.axes[0].splits = () => fig.categories.map((_, i) => i);
    opts.axes[0].values = (u, splits) => splits.map((i) => fig.categories[i] ?? "");
    opts.axes[0].grid = {show: false};
    opts.hooks.draw.unshift((u) => {
      const ctx = u.ctx, r = devicePixelRatio || 1;
      ctx.save();
      // Zero line.
      const y0 = u.valToPos(0, "y", true);
      ctx.strokeStyle = "#7b8794";
      ctx.lineWidth = 1.5 * r;
      ctx.beginPath(); ctx.moveTo(u.bbox.left, y0); ctx.lineTo(u.bbox.left + u.bbox.width, y0); ctx.stroke();
      fig.series.forEach((s, k) => {
        if (!u.series[k + 1].show) return;
        ctx.strokeStyle = colour(k);
        ctx.lineWidth = 1.5 * r;
        ctx.beginPath();
        s.mean.forEach((v, i) => {
          if (v === null || s.half[i] === null) return;
          const x = u.valToPos(data[k + 1][0][i], "x", true);
          const lo = u.valToPos(v - s.half[i], "y", true), hi = u.valToPos(v + s.half[i], "y", true);
          ctx.moveTo(x, lo); ctx.lineTo(x, hi);
          ctx.moveTo(x - 4 * r, lo); ctx.lineTo(x + 4 * r, lo);
          ctx.moveTo(x - 4 * r, hi); ctx.lineTo(x + 4 * r, hi);
        });
        ctx.stroke();
      });
      ctx.restore();
      el.dataset.bars = String(fig.series.reduce((a, s) => a + s.mean.filter((v, i) => v !== null && s.half[i] !== null).length, 0));
    });
    opts.hooks.setCursor = [setCursorReadout(line, (u, l) => {
      const i = Math.round(u.posToVal(l, "x"));
      if (i < 0 || i >= n) return "";
      return fig.categories[i] + ": " + fig.series.map((s) =>
        `${s.name} ${format(s.mean[i])} ${fig.bars} ${format(s.half[i])}`).join("    ");
    })];
    return show(new uPlot(opts, data, el), el, line);
  }

  // Colour of v on the scale [[t, "#rrggbb"], ...] over [zmin, zmax].
  function scaleColour(scale, t) {
    t = Math.min(1, Math.max(0, t));
    for (let i = 1; i < scale.length; i++) {
      if (t <= scale[i][0] || i === scale.length - 1) {
        const [t0, c0] = scale[i - 1], [t1, c1] = scale[i];
        const f = t1 > t0 ? (t - t0) / (t1 - t0) : 0;
        const rgb = [1, 3, 5].map((p) => {
          const a = parseInt(c0.substr(p, 2), 16), b = parseInt(c1.substr(p, 2), 16);
          return Math.round(a + (b - a) * f);
        });
        return {css: `rgb(${rgb.join(",")})`, dark: 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2] < 120};
      }
    }
    return {css: scale[0][1], dark: false};
  }

  // A labelled square matrix: coloured cells, values written in them (annotate), hover read-out.
  function heatmap(fig, el) {
    const n = fig.labels.length;
    const line = readout();
    const opts = base(fig, el, {series: [null, {label: fig.title, paths: () => null, points: {show: false}}]});
    opts.legend.show = false;
    opts.height = fig.height;
    opts.width = Math.min(el.clientWidth, fig.height + 120);
    opts.cursor.drag = {x: false, y: false};
    opts.scales.x.range = () => [-0.5, n - 0.5];
    opts.scales.y.range = () => [-0.5, n - 0.5];
    opts.scales.y.dir = -1;  // row 0 on top, as the matrix is written
    for (const axis of opts.axes) {
      axis.splits = () => fig.labels.map((_, i) => i);
      axis.values = (u, splits) => splits.map((i) => fig.labels[i] ?? "");
      axis.grid = {show: false};
      axis.label = "";
    }
    opts.axes[0].rotate = n > 8 ? -45 : 0;
    opts.axes[1].size = 80;
    opts.hooks.draw.unshift((u) => {
      const ctx = u.ctx, r = devicePixelRatio || 1;
      ctx.save();
      ctx.textAlign = "center";
      ctx.textBaseline = "middle";
      ctx.font = `${(n > 12 ? 10 : 12) * r}px system-ui, sans-serif`;
      for (let i = 0; i < n; i++) for (let j = 0; j < n; j++) {
        const v = fig.z[i][j];
        const x0 = u.valToPos(j - 0.5, "x", true), x1 = u.valToPos(j + 0.5, "x", true);
        const y0 = u.valToPos(i - 0.5, "y", true), y1 = u.valToPos(i + 0.5, "y", true);
        const c = v === null ? {css: "#ffffff", dark: false} : scaleColour(fig.colours, (v - fig.zmin) / (fig.zmax - fig.zmin));
        ctx.fillStyle = c.css;
        ctx.fillRect(Math.min(x0, x1) + r, Math.min(y0, y1) + r, Math.abs(x1 - x0) - r, Math.abs(y1 - y0) - r);
        if (fig.annotate && v !== null) {
          ctx.fillStyle = c.dark ? "#ffffff" : "#1f2933";
          ctx.fillText(v.toFixed(fig.digits).replace(/^-(0\.?0*)$/, "$1"), (x0 + x1) / 2, (y0 + y1) / 2);
        }
      }
      ctx.restore();
    });
    opts.hooks.setCursor = [setCursorReadout(line, (u, l, t) => {
      const j = Math.round(u.posToVal(l, "x")), i = Math.round(u.posToVal(t, "y"));
      if (i < 0 || j < 0 || i >= n || j >= n) return "";
      return `${fig.labels[i]} / ${fig.labels[j]}: ${format(fig.z[i][j])}`;
    })];
    return show(new uPlot(opts, [null, [[], []]], el), el, line);
  }

  const kinds = {xy, errorbars, heatmap};

  window.strutDrawFigures = function (figures) {
    const root = document.documentElement, plots = [];
    for (const fig of figures) {
      const el = document.getElementById(fig.id);
      try {
        plots.push([kinds[fig.kind](fig, el), el, fig]);
      } catch (e) {
        el.dataset.error = String(e);
        el.textContent = "This plot could not be drawn: " + e;
        root.dataset.figuresFailed = (root.dataset.figuresFailed ? root.dataset.figuresFailed + " " : "") + fig.id;
      }
    }
    // uPlot draws on a microtask after construction: count once every figure had its turn.
    setTimeout(() => {
      root.dataset.figuresDrawn = String(document.querySelectorAll("div.plot[data-drawn='1']").length);
    }, 0);
    let pending = 0;
    window.addEventListener("resize", () => {
      cancelAnimationFrame(pending);
      pending = requestAnimationFrame(() => {
        for (const [u, el, fig] of plots)
          u.setSize({width: fig.kind === "heatmap" ? Math.min(el.clientWidth, fig.height + 120) : Math.max(240, el.clientWidth),
                     height: u.height});
      });
    });
  };
})();
