// Plots drawn in the browser from the numbers the API returns: line plots in SVG (one polyline
// per series, one vertex per finite point), heat maps on a canvas (cell by cell), a grid map in
// SVG (one clickable rect per point), colour bars. Hand-written, no library: the daemon serves
// every file it needs. The elements carry data-* attributes with what they show (points, cells,
// value range), which the browser test reads.

const SVG_NS = "http://www.w3.org/2000/svg";

export function svg(tag, attrs = {}, parent = null) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  if (parent) parent.appendChild(el);
  return el;
}

// About `count` round tick values covering [lo, hi] (1, 2 or 5 times a power of ten apart).
export function niceTicks(lo, hi, count = 5) {
  if (!Number.isFinite(lo) || !Number.isFinite(hi)) return [];
  if (hi < lo) [lo, hi] = [hi, lo];
  if (hi === lo) return [lo];
  const raw = (hi - lo) / Math.max(1, count);
  const power = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw) || 10 * power;
  const ticks = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) {
    ticks.push(Math.abs(t) < step * 1e-9 ? 0 : t);
  }
  return ticks;
}

// A number for an axis or a table: 3 significant digits, exponents outside 1e-3..1e5.
export function fmt(v) {
  if (v === null || v === undefined || Number.isNaN(v)) return "—";
  if (!Number.isFinite(v)) return v > 0 ? "∞" : "-∞";
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2);
  return String(Number(v.toPrecision(3)));
}

// Viridis, sampled at nine points and interpolated linearly: t in [0, 1] -> [r, g, b].
const VIRIDIS = [
  [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
  [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37],
];
export function colormap(t) {
  if (!Number.isFinite(t)) return [200, 200, 200];
  const x = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(x));
  const f = x - i;
  return VIRIDIS[i].map((c, k) => Math.round(c + f * (VIRIDIS[i + 1][k] - c)));
}
const css = (rgb) => `rgb(${rgb[0]},${rgb[1]},${rgb[2]})`;

export const PALETTE = ["#2a6f97", "#e76f51", "#2a9d8f", "#8e44ad", "#e9c46a", "#264653",
                        "#d62828", "#6a994e"];

function extent(arrays) {
  let lo = Infinity, hi = -Infinity;
  for (const a of arrays) for (const v of a) {
    if (Number.isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
  }
  return lo <= hi ? [lo, hi] : [0, 1];
}

// A line plot: `series` = [{name, x, y, color?}]. Returns the <svg>; each series is a
// <polyline class="series" data-series=name data-points=N> with one vertex per finite (x, y).
export function linePlot(series, { width = 640, height = 280, xLabel = "", yLabel = "",
                                   id = "" } = {}) {
  const m = { l: 64, r: 16, t: 14, b: 42 };
  const root = svg("svg", { viewBox: `0 0 ${width} ${height}`, class: "plot", role: "img" });
  if (id) root.id = id;
  const [x0, x1] = extent(series.map((s) => s.x));
  let [y0, y1] = extent(series.map((s) => s.y));
  if (y0 === y1) { y0 -= 1; y1 += 1; }
  const pw = width - m.l - m.r, ph = height - m.t - m.b;
  const sx = (x) => m.l + (x1 === x0 ? pw / 2 : ((x - x0) / (x1 - x0)) * pw);
  const sy = (y) => m.t + ph - ((y - y0) / (y1 - y0)) * ph;
  const axes = svg("g", { class: "axes" }, root);
  for (const t of niceTicks(x0, x1, 6)) {
    svg("line", { x1: sx(t), x2: sx(t), y1: m.t, y2: m.t + ph, class: "gridline" }, axes);
    svg("text", { x: sx(t), y: m.t + ph + 16, "text-anchor": "middle" }, axes).textContent = fmt(t);
  }
  for (const t of niceTicks(y0, y1, 5)) {
    svg("line", { x1: m.l, x2: m.l + pw, y1: sy(t), y2: sy(t), class: "gridline" }, axes);
    svg("text", { x: m.l - 6, y: sy(t) + 4, "text-anchor": "end" }, axes).textContent = fmt(t);
  }
  svg("rect", { x: m.l, y: m.t, width: pw, height: ph, class: "frame" }, axes);
  svg("text", { x: m.l + pw / 2, y: height - 6, "text-anchor": "middle", class: "label" },
      axes).textContent = xLabel;
  svg("text", { x: 14, y: m.t + ph / 2, "text-anchor": "middle", class: "label",
                transform: `rotate(-90 14 ${m.t + ph / 2})` }, axes).textContent = yLabel;
  series.forEach((s, k) => {
    const color = s.color || PALETTE[k % PALETTE.length];
    const pts = [];
    for (let i = 0; i < Math.min(s.x.length, s.y.length); ++i) {
      if (Number.isFinite(s.x[i]) && Number.isFinite(s.y[i])) {
        pts.push(`${sx(s.x[i]).toFixed(1)},${sy(s.y[i]).toFixed(1)}`);
      }
    }
    svg("polyline", { points: pts.join(" "), fill: "none", stroke: color, "stroke-width": 1.6,
                      class: "series", "data-series": s.name, "data-points": pts.length }, root);
    const ly = m.t + 14 + 16 * k;
    svg("line", { x1: m.l + pw - 150, x2: m.l + pw - 130, y1: ly - 4, y2: ly - 4, stroke: color,
                  "stroke-width": 2 }, root);
    svg("text", { x: m.l + pw - 124, y: ly, class: "legend" }, root).textContent = s.name;
  });
  return root;
}

// A colour bar from lo to hi (an SVG fragment of `height`, ticks on the right).
function colorBar(parent, x, y, w, h, lo, hi, label) {
  const g = svg("g", { class: "colorbar" }, parent);
  const steps = 32;
  for (let i = 0; i < steps; ++i) {
    svg("rect", { x, y: y + h - ((i + 1) * h) / steps, width: w, height: h / steps + 0.5,
                  fill: css(colormap((i + 0.5) / steps)) }, g);
  }
  for (const t of niceTicks(lo, hi, 4)) {
    const ty = y + h - ((t - lo) / (hi - lo || 1)) * h;
    svg("text", { x: x + w + 4, y: ty + 4 }, g).textContent = fmt(t);
  }
  if (label) svg("text", { x, y: y - 6, class: "label" }, g).textContent = label;
  return g;
}

// Draws rows x cols values (row-major, row 0 at the bottom) on `canvas` with axes: x from
// xRange over the columns, y from yRange over the rows. `log`: colour by log10, floored `decades`
// below the largest value (smaller values take the lowest colour). Sets data-rows, data-cols,
// data-cells (finite cells drawn), data-vmin, data-vmax on the canvas.
export function heatMap(canvas, values, rows, cols, { xRange = [0, cols], yRange = [0, rows],
                        xLabel = "", yLabel = "", barLabel = "", log = false, decades = 4 } = {}) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  const m = { l: 56, r: 86, t: 16, b: 40 };
  const pw = W - m.l - m.r, ph = H - m.t - m.b;
  ctx.clearRect(0, 0, W, H);
  const tr = (v) => (log ? (v > 0 ? Math.log10(v) : NaN) : v);
  let lo = Infinity, hi = -Infinity;
  for (const v of values) {
    const t = tr(v);
    if (Number.isFinite(t)) { lo = Math.min(lo, t); hi = Math.max(hi, t); }
  }
  if (!(lo <= hi)) { lo = 0; hi = 1; }
  if (log) lo = Math.max(lo, hi - decades);
  if (hi === lo) hi = lo + 1;
  const img = ctx.createImageData(cols, rows);
  let drawn = 0;
  for (let r = 0; r < rows; ++r) {
    for (let c = 0; c < cols; ++c) {
      const t = tr(values[r * cols + c]);
      const p = ((rows - 1 - r) * cols + c) * 4;
      if (!Number.isFinite(t) && !(log && values[r * cols + c] === 0)) {
        img.data[p + 3] = 0;
        continue;
      }
      const rgb = colormap(Number.isFinite(t) ? (t - lo) / (hi - lo) : 0);
      img.data.set([rgb[0], rgb[1], rgb[2], 255], p);
      ++drawn;
    }
  }
  const off = document.createElement("canvas");
  off.width = cols;
  off.height = rows;
  off.getContext("2d").putImageData(img, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(off, m.l, m.t, pw, ph);
  drawAxes(ctx, m, pw, ph, xRange, yRange, xLabel, yLabel);
  drawBar(ctx, W - m.r + 14, m.t, 14, ph, lo, hi, barLabel || (log ? "log10" : ""));
  Object.assign(canvas.dataset, { rows, cols, cells: drawn, vmin: lo, vmax: hi });
}

function drawAxes(ctx, m, pw, ph, xRange, yRange, xLabel, yLabel) {
  ctx.strokeStyle = "#555";
  ctx.strokeRect(m.l + 0.5, m.t + 0.5, pw, ph);
  ctx.fillStyle = "#222";
  ctx.font = "11px sans-serif";
  ctx.textAlign = "center";
  const [x0, x1] = xRange, [y0, y1] = yRange;
  for (const t of niceTicks(x0, x1, 6)) {
    const x = m.l + ((t - x0) / (x1 - x0 || 1)) * pw;
    ctx.fillText(fmt(t), x, m.t + ph + 14);
  }
  ctx.textAlign = "right";
  for (const t of niceTicks(y0, y1, 5)) {
    const y = m.t + ph - ((t - y0) / (y1 - y0 || 1)) * ph;
    ctx.fillText(fmt(t), m.l - 5, y + 4);
  }
  ctx.textAlign = "center";
  ctx.fillText(xLabel, m.l + pw / 2, m.t + ph + 32);
  ctx.save();
  ctx.translate(13, m.t + ph / 2);
  ctx.rotate(-Math.PI / 2);
  ctx.fillText(yLabel, 0, 0);
  ctx.restore();
}

function drawBar(ctx, x, y, w, h, lo, hi, label) {
  for (let i = 0; i < h; ++i) {
    ctx.fillStyle = css(colormap(1 - i / h));
    ctx.fillRect(x, y + i, w, 1);
  }
  ctx.fillStyle = "#222";
  ctx.textAlign = "left";
  for (const t of niceTicks(lo, hi, 4)) {
    ctx.fillText(fmt(t), x + w + 4, y + h - ((t - lo) / (hi - lo || 1)) * h + 4);
  }
  if (label) ctx.fillText(label, x - 6, y + h + 16);
}

// A field raster (nx x ny cells, row-major in y, NaN/null outside the body) on `canvas`, with the
// body's aspect ratio kept. Vectors (components > 1) are drawn as their magnitude.
export function fieldImage(canvas, field) {
  const { nx, ny, components } = field;
  const c = Math.max(1, components || 1);
  const values = new Float64Array(nx * ny);
  for (let i = 0; i < nx * ny; ++i) {
    let s = 0, ok = true;
    for (let k = 0; k < c; ++k) {
      const v = field.values[i * c + k];
      if (v === null || !Number.isFinite(v)) ok = false; else s += v * v;
    }
    values[i] = ok ? (c > 1 ? Math.sqrt(s) : field.values[i]) : NaN;
  }
  const scale = 1e6;  // axes in µm
  heatMap(canvas, values, ny, nx, {
    xRange: [field.x_min * scale, field.x_max * scale],
    yRange: [field.y_min * scale, field.y_max * scale],
    xLabel: "x (µm)", yLabel: "y (µm)",
    barLabel: `${field.name}${c > 1 ? " |·|" : ""} (${field.units})`,
  });
  Object.assign(canvas.dataset, { frame: field.frame, nx, ny });
}

// A grid reduction over two axes: one <rect class="cell" data-job-id data-value> per point,
// rows = values of `yAxis`, columns = values of `xAxis`, coloured by value (grey where NaN).
// `cell(i, j)` gives {value, job, state} of column i, row j; `onClick(job)` follows a cell.
export function gridMap(xAxis, yAxis, cell, { width = 640, height = 360, id = "",
                        barLabel = "", onClick = null } = {}) {
  const m = { l: 80, r: 90, t: 14, b: 48 };
  const root = svg("svg", { viewBox: `0 0 ${width} ${height}`, class: "plot", role: "img" });
  if (id) root.id = id;
  const nx = xAxis.values.length, ny = yAxis.values.length;
  const pw = width - m.l - m.r, ph = height - m.t - m.b;
  const cw = pw / nx, ch = ph / ny;
  const vals = [];
  for (let j = 0; j < ny; ++j) for (let i = 0; i < nx; ++i) vals.push(cell(i, j).value);
  let [lo, hi] = extent([vals]);
  if (lo === hi) hi = lo + 1;
  for (let j = 0; j < ny; ++j) {
    for (let i = 0; i < nx; ++i) {
      const { value, job, state } = cell(i, j);
      const finite = Number.isFinite(value);
      const r = svg("rect", {
        x: m.l + i * cw, y: m.t + ph - (j + 1) * ch, width: cw - 1, height: ch - 1,
        fill: finite ? css(colormap((value - lo) / (hi - lo))) : "#ddd", class: "cell",
        "data-job-id": job, "data-value": finite ? value : "NaN", "data-state": state,
        tabindex: 0,
      }, root);
      svg("title", {}, r).textContent =
        `${xAxis.name} = ${fmt(xAxis.values[i])}, ${yAxis.name} = ${fmt(yAxis.values[j])}: ` +
        `${fmt(value)} (${state}, job ${job})`;
      if (onClick && job) {
        r.addEventListener("click", () => onClick(job));
        r.addEventListener("keydown", (e) => { if (e.key === "Enter") onClick(job); });
      }
      if (cw > 46 && ch > 18) {
        // Light text on the dark lower half of the colour map, dark text on the rest.
        const dark = finite && (value - lo) / (hi - lo) < 0.5;
        svg("text", { x: m.l + (i + 0.5) * cw, y: m.t + ph - (j + 0.5) * ch + 4,
                      "text-anchor": "middle", class: dark ? "cell-text light" : "cell-text" },
            root).textContent = fmt(value);
      }
    }
  }
  for (let i = 0; i < nx; ++i) {
    svg("text", { x: m.l + (i + 0.5) * cw, y: m.t + ph + 16, "text-anchor": "middle" },
        root).textContent = fmt(xAxis.values[i]);
  }
  for (let j = 0; j < ny; ++j) {
    svg("text", { x: m.l - 6, y: m.t + ph - (j + 0.5) * ch + 4, "text-anchor": "end" },
        root).textContent = fmt(yAxis.values[j]);
  }
  svg("text", { x: m.l + pw / 2, y: height - 8, "text-anchor": "middle", class: "label" },
      root).textContent = xAxis.name;
  svg("text", { x: 14, y: m.t + ph / 2, "text-anchor": "middle", class: "label",
                transform: `rotate(-90 14 ${m.t + ph / 2})` }, root).textContent = yAxis.name;
  colorBar(root, width - m.r + 16, m.t + 14, 14, ph - 14, lo, hi, barLabel);
  Object.assign(root.dataset, { cells: nx * ny, vmin: lo, vmax: hi });
  return root;
}
