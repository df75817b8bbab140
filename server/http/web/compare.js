// Two or more jobs side by side: the spec fields in which they differ, their summary figures,
// and Ā(t) of each overlaid on one plot.

import { api, TERMINAL, num } from "./api.js";
import { el, message, stateBadge } from "./dom.js";
import { abarSeries, SUMMARY_FIGURES } from "./job.js";
import { PALETTE, fmt, linePlot } from "./plots.js";

const MAX_JOBS = 8;

// {"load.pressure": 2e9, "geometry.disk.radius": 9e-5, ...}: every leaf of a spec.
export function flatten(obj, prefix = "", out = {}) {
  for (const [k, v] of Object.entries(obj || {})) {
    const path = prefix ? `${prefix}.${k}` : k;
    if (v !== null && typeof v === "object" && !Array.isArray(v)) flatten(v, path, out);
    else out[path] = Array.isArray(v) ? JSON.stringify(v) : v;
  }
  return out;
}

// The paths whose values are not the same in every one of `flats` (a path missing in one counts
// as different), sorted.
export function differingPaths(flats) {
  const paths = new Set(flats.flatMap((f) => Object.keys(f)));
  return [...paths].filter((p) => new Set(flats.map((f) => JSON.stringify(f[p]))).size > 1).sort();
}

export function comparePage(root, ctx, ids) {
  const msg = el("p", { id: "compare-message", class: "message", role: "alert" });
  const specTable = el("table", { id: "compare-spec", class: "summary" });
  const summaryTable = el("table", { id: "compare-summary", class: "summary" });
  const plotBox = el("div", { id: "compare-plot-box", class: "panel" }, el("h2", {}, "Ā(t)"));
  root.append(el("p", {}, el("a", { href: "#/jobs" }, "← Jobs")),
              el("h1", {}, `Compare ${ids.length} jobs`), msg,
              el("h2", {}, "Spec fields that differ"), specTable,
              el("h2", {}, "Summary"), summaryTable, plotBox);
  if (ids.length < 2 || ids.length > MAX_JOBS) {
    message(msg, `Choose 2 to ${MAX_JOBS} jobs (from the jobs table).`);
    return () => {};
  }
  let stopped = false;
  (async () => {
    let jobs;
    try {
      jobs = await Promise.all(ids.map((id) => api(`api/jobs/${encodeURIComponent(id)}`)));
    } catch (e) {
      if (!ctx.authFailed(e)) message(msg, `${e.code}: ${e.message}`);
      return;
    }
    if (stopped) return;
    const head = el("tr", {}, el("th", {}, ""), jobs.map((j, k) => el("th", {},
      el("a", { href: "#/jobs/" + j.id, class: "swatch-" + k }, j.id), " ", stateBadge(j.state))));
    const flats = jobs.map((j) => flatten(j.spec));
    const paths = differingPaths(flats);
    specTable.replaceChildren(head.cloneNode(true), ...paths.map((p) => el("tr",
      { dataset: { path: p } }, el("td", {}, p),
      flats.map((f) => el("td", {}, f[p] === undefined ? "—" : String(f[p]))))));
    if (!paths.length) specTable.append(el("tr", {}, el("td", {}, "The specs are the same.")));

    const summaries = await Promise.all(jobs.map((j) => TERMINAL.has(j.state)
      ? api(`api/jobs/${encodeURIComponent(j.id)}/summary`).catch(() => null)
      : Promise.resolve(null)));
    if (stopped) return;
    summaryTable.replaceChildren(head, ...SUMMARY_FIGURES.map(([k, u]) => el("tr",
      { dataset: { figure: k } }, el("td", {}, u ? `${k} (${u})` : k),
      summaries.map((s) => el("td", {}, s ? fmt(num(s[k])) : "—")))));

    const series = [];
    for (const [k, j] of jobs.entries()) {
      if (!TERMINAL.has(j.state)) continue;
      try {
        const s = (await abarSeries(j)).find((x) => x.name === "Ā");
        if (s) series.push({ ...s, name: j.id, color: PALETTE[k % PALETTE.length] });
      } catch (e) {
        plotBox.append(el("p", { class: "error" }, `${j.id}: ${e.message}`));
      }
    }
    if (stopped) return;
    if (series.length) {
      plotBox.append(linePlot(series, { id: "compare-plot", xLabel: "t (ns)", yLabel: "Ā" }));
    } else {
      plotBox.append(el("p", { class: "muted" }, "No finished job to plot yet."));
    }
  })();
  return () => { stopped = true; };
}
