// One job: its state (polled every second until it is terminal), spec and summary, then its
// results drawn from the data: Ā(t) and the filtered Ā(t) as lines, the rim-mode amplitudes as
// a time x mode heat map, and a field on a canvas with a slider over the result's frames.

import { api, ApiError, TERMINAL, num } from "./api.js";
import { duration, el, elapsed, labelsText, localTime, message, percent, progressBar,
         setProgress, stateBadge } from "./dom.js";
import { fieldImage, fmt, heatMap, linePlot } from "./plots.js";

const POLL_MS = 1000;
export const FIELDS = ["J", "mean_stress", "radial_stress", "hoop_stress", "von_mises",
                       "aspect_ratio", "displacement", "velocity"];
// The summary's figures shown, with units (docs/api.md, JobSummary).
export const SUMMARY_FIGURES = [
  ["elements", ""], ["nodes", ""], ["steps", ""], ["end_time_s", "s"], ["wall_time_s", "s"],
  ["energy_injected_J_per_m", "J/m"], ["energy_after_pulse_J_per_m", "J/m"],
  ["max_abar_first_cycle", ""], ["max_abar", ""], ["max_abar_filtered", ""],
  ["abar_end", ""], ["dominant_mode_end", ""], ["shock_at_center_s", "s"], ["min_dt_s", "s"],
  ["grind_ns", "ns"], ["max_aspect_ratio", ""],
];

// `every` that leaves about `target` samples of a series sampled every `interval` to `end`.
export function decimation(end, interval, target) {
  const samples = num(end) / num(interval);
  return Number.isFinite(samples) && samples > target ? Math.ceil(samples / target) : 1;
}

// Ā(t) (and the filtered Ā where the result has it) of a finished job, as series in ns.
export async function abarSeries(job) {
  const every = decimation(job.spec.run.end_time, job.spec.run.history_interval, 1500);
  const id = encodeURIComponent(job.id);
  let ts;
  try {
    ts = await api(`api/jobs/${id}/timeseries`, { params: { names: "abar,abar_filtered", every } });
  } catch (e) {
    if (!(e instanceof ApiError) || e.status !== 400) throw e;
    ts = await api(`api/jobs/${id}/timeseries`, { params: { names: "abar", every } });  // older
  }
  const t = ts.time.map((v) => num(v) * 1e9);
  return ts.series.map((s) => ({ name: s.name === "abar" ? "Ā" : "Ā filtered", x: t,
                                 y: s.values.map(num) }));
}

export function jobPage(root, ctx, id) {
  const st = { job: null, stopped: false, timer: 0, results: false, frame: -1, frames: 0,
               fieldTimer: 0, fieldSeq: 0 };
  const msg = el("p", { id: "job-message", class: "message", role: "alert" });
  const badge = el("span", { id: "job-state" });
  const bar = progressBar(0);
  const pct = el("span", { id: "job-progress", class: "muted" });
  const cancelBtn = el("button", { id: "job-cancel", type: "button", hidden: true }, "Cancel");
  const facts = el("dl", { class: "facts" });
  const specPre = el("pre", { id: "job-spec" });
  const summary = el("table", { id: "job-summary", class: "summary" });
  const abarBox = el("div", { id: "abar-box", class: "panel" }, el("h2", {}, "Ā(t)"));
  const modesCanvas = el("canvas", { id: "modes-map", width: 720, height: 300 });
  const modesBox = el("div", { class: "panel" }, el("h2", {}, "Rim modes"), modesCanvas);
  const fieldSel = el("select", { id: "field-name", "aria-label": "field" },
                      FIELDS.map((f) => el("option", { value: f }, f)));
  const slider = el("input", { id: "frame-slider", type: "range", min: 0, max: 0, value: 0,
                               "aria-label": "frame" });
  const caption = el("span", { id: "field-caption", class: "muted" });
  const fieldCanvas = el("canvas", { id: "field-canvas", width: 560, height: 470 });
  const fieldBox = el("div", { class: "panel" }, el("h2", {}, "Field"),
                      el("div", { class: "controls" }, fieldSel, slider, caption), fieldCanvas);
  const results = el("section", { id: "job-results", class: "results", hidden: true },
                     abarBox, modesBox, fieldBox);
  const pending = el("p", { id: "job-pending", class: "muted" },
                     "Results appear here when the job has finished.");

  root.append(
    el("p", {}, el("a", { href: "#/jobs" }, "← Jobs")),
    el("h1", {}, "Job ", el("code", {}, id), " ", badge),
    el("div", { class: "progress-line" }, bar, pct, cancelBtn),
    msg, facts,
    el("details", {}, el("summary", {}, "Spec"), specPre),
    el("h2", {}, "Summary"), summary, pending, results);

  function showFacts(job) {
    const rows = [
      ["Owner", job.owner], ["Labels", labelsText(job.labels) || "—"],
      ["Created", localTime(job.create_time)], ["Started", localTime(job.start_time)],
      ["Finished", localTime(job.finish_time)], ["Elapsed", duration(elapsed(job))],
      ["Attempt", job.attempt], ["Reason", job.reason || "—"], ["Error", job.error || "—"],
      ["Grid", job.grid_id ? `${job.grid_id} #${job.grid_index}` : "—"],
      ["Reused from", job.reused_from || "—"],
    ];
    facts.replaceChildren(...rows.flatMap(([k, v]) => [el("dt", {}, k), el("dd", {}, String(v))]));
  }

  async function poll() {
    try {
      const job = await api(`api/jobs/${encodeURIComponent(id)}`);
      st.job = job;
      if (badge.textContent !== job.state) badge.replaceChildren(stateBadge(job.state));
      badge.dataset.state = job.state;
      const f = job.state === "SUCCEEDED" ? 1 : num(job.progress && job.progress.fraction);
      setProgress(bar, f);
      pct.textContent = `${percent(f)} · t = ${fmt(num(job.progress && job.progress.simulated_time) * 1e9)} ns` +
                        ` · ${num(job.progress && job.progress.steps) || 0} steps`;
      cancelBtn.hidden = TERMINAL.has(job.state);
      showFacts(job);
      if (!specPre.textContent) specPre.textContent = JSON.stringify(job.spec, null, 2);
      if (TERMINAL.has(job.state) && !st.results) {
        st.results = true;
        loadResults(job);
      }
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `${e.code}: ${e.message}`);
    }
    if (!st.stopped && !(st.job && TERMINAL.has(st.job.state))) {
      st.timer = setTimeout(poll, POLL_MS);
    }
  }

  async function loadResults(job) {
    pending.hidden = true;
    try {
      const s = await api(`api/jobs/${encodeURIComponent(id)}/summary`);
      summary.replaceChildren(
        el("tr", {}, el("th", {}, "figure"), el("th", {}, "value"), el("th", {}, "units")),
        ...SUMMARY_FIGURES.map(([k, u]) => el("tr", { dataset: { figure: k } },
                                              el("td", {}, k), el("td", {}, fmt(num(s[k]))),
                                              el("td", {}, u))));
    } catch (e) {
      summary.replaceChildren(el("tr", {}, el("td", {}, `No summary: ${e.message}`)));
    }
    results.hidden = false;
    drawAbar(job);
    drawModes(job);
    drawField();
  }

  async function drawAbar(job) {
    try {
      const series = await abarSeries(job);
      abarBox.append(linePlot(series, { id: "abar-plot", xLabel: "t (ns)", yLabel: "Ā" }));
    } catch (e) {
      abarBox.append(el("p", { class: "error" }, `Ā(t): ${e.message}`));
    }
  }

  async function drawModes(job) {
    try {
      const every = decimation(job.spec.run.end_time, job.spec.run.history_interval, 400);
      const m = await api(`api/jobs/${encodeURIComponent(id)}/modes`, { params: { every } });
      const rows = m.time.length, cols = m.mode_count;
      const amp = m.amplitude.map(num);
      // Rows of the canvas are modes, columns times: transpose T x C into C x T.
      const grid = new Float64Array(rows * cols);
      for (let t = 0; t < rows; ++t) for (let c = 0; c < cols; ++c) grid[c * rows + t] = amp[t * cols + c];
      const t0 = num(m.time[0]) * 1e9, t1 = num(m.time[rows - 1]) * 1e9;
      heatMap(modesCanvas, grid, cols, rows, {
        xRange: [t0, t1], yRange: [m.mode_min, m.mode_min + cols], xLabel: "t (ns)",
        yLabel: "mode n", barLabel: "log10 a/R0", log: true, decades: 4 });
    } catch (e) {
      modesBox.append(el("p", { class: "error" }, `Rim modes: ${e.message}`));
    }
  }

  async function drawField() {
    clearTimeout(st.fieldTimer);
    const seq = ++st.fieldSeq;
    const params = { name: fieldSel.value, nx: 200, ny: 200 };
    if (st.frame >= 0) params.frame = st.frame;
    try {
      const f = await api(`api/jobs/${encodeURIComponent(id)}/field`, { params });
      if (seq !== st.fieldSeq) return;  // a later request superseded this one
      st.frames = f.frame_count;
      st.frame = f.frame;
      slider.max = Math.max(0, f.frame_count - 1);
      slider.value = f.frame;
      caption.textContent = `frame ${f.frame + 1} of ${f.frame_count}, t = ${fmt(f.time * 1e9)} ns`;
      fieldImage(fieldCanvas, f);
    } catch (e) {
      if (seq === st.fieldSeq) caption.textContent = `Field: ${e.code}: ${e.message}`;
    }
  }

  slider.addEventListener("input", () => {
    st.frame = Number(slider.value);
    clearTimeout(st.fieldTimer);
    st.fieldTimer = setTimeout(drawField, 120);
  });
  fieldSel.addEventListener("change", drawField);
  cancelBtn.addEventListener("click", async () => {
    try {
      await api(`api/jobs/${encodeURIComponent(id)}/cancel`, { method: "POST" });
      message(msg, "Cancel requested.", "notice");
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `Cannot cancel: ${e.code}: ${e.message}`);
    }
  });
  poll();
  return () => { st.stopped = true; clearTimeout(st.timer); clearTimeout(st.fieldTimer); };
}
