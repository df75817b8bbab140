// Grids: the list, and one grid's reduction (GetGridReduction: one figure per point) as a map
// over two of its axes -- the first axis up, the second across; a third axis is chosen by a
// slider -- refreshed while points are still running. A cell links to its job.

import { api, TERMINAL, num } from "./api.js";
import { el, labelsText, localTime, message, percent, progressBar, setProgress,
         stateBadge } from "./dom.js";
import { fmt, gridMap } from "./plots.js";

const POLL_MS = 2000;
export const DEFAULT_QUANTITY = "max_abar_first_cycle";

// GetGridReduction's quantities: the daemon's grid figures (api/figures: its one table of
// summary figures) and A-bar at a t-bar, the default first.
export async function gridQuantities() {
  const r = await api("api/figures");
  const names = (r.figures || []).filter((f) => f.grid_quantity).map((f) => f.name);
  return [DEFAULT_QUANTITY, ...names.filter((n) => n !== DEFAULT_QUANTITY), "abar_at"];
}

export function gridsPage(root, ctx) {
  const msg = el("p", { class: "message", role: "alert" });
  const tbody = el("tbody");
  root.append(el("h1", {}, "Grids"), msg,
              el("table", { id: "grids-table", class: "jobs" },
                 el("thead", {}, el("tr", {}, ["Grid", "State", "Progress", "Shape", "Axes",
                                               "Owner", "Labels", "Created"].map((t) => el("th", {}, t)))),
                 tbody));
  let stopped = false, timer = 0;
  async function load() {
    try {
      const page = await api("api/grids", { params: { page_size: 100 } });
      tbody.replaceChildren(...(page.grids || []).map((g) => el("tr", { dataset: { gridId: g.id } },
        el("td", {}, el("a", { href: "#/grids/" + g.id }, g.id)),
        el("td", {}, stateBadge(g.state)),
        el("td", {}, progressBar(num(g.progress)), " ", percent(num(g.progress))),
        el("td", {}, (g.shape || []).join(" × ")),
        el("td", {}, (g.axes || []).map((a) => a.name).join(", ")),
        el("td", {}, g.owner), el("td", {}, labelsText(g.labels)),
        el("td", {}, localTime(g.create_time)))));
      message(msg, page.grids && page.grids.length ? "" : "No grids yet.", "notice");
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `${e.code}: ${e.message}`);
    }
    if (!stopped) timer = setTimeout(load, POLL_MS);
  }
  load();
  return () => { stopped = true; clearTimeout(timer); };
}

export function gridPage(root, ctx, id) {
  const st = { grid: null, stopped: false, timer: 0 };
  const msg = el("p", { id: "grid-message", class: "message", role: "alert" });
  const badge = el("span", { id: "grid-state" });
  const bar = progressBar(0);
  const counts = el("span", { id: "grid-counts", class: "muted" });
  const quantity = el("select", { id: "grid-quantity", "aria-label": "quantity" },
                      el("option", { value: DEFAULT_QUANTITY }, DEFAULT_QUANTITY));
  gridQuantities().then((names) => {
    const chosen = quantity.value;
    quantity.replaceChildren(...names.map((q) => el("option", { value: q }, q)));
    quantity.value = chosen;
  }).catch((e) => { if (!ctx.authFailed(e)) message(msg, `${e.code}: ${e.message}`); });
  const tbar = el("input", { id: "grid-tbar", type: "number", step: "any", value: "4",
                             "aria-label": "t-bar", hidden: true });
  const third = el("input", { id: "grid-third", type: "range", min: 0, max: 0, value: 0,
                              hidden: true, "aria-label": "third axis" });
  const thirdCaption = el("span", { class: "muted" });
  const mapBox = el("div", { id: "grid-map-box", class: "panel" });
  root.append(el("p", {}, el("a", { href: "#/grids" }, "← Grids")),
              el("h1", {}, "Grid ", el("code", {}, id), " ", badge),
              el("div", { class: "progress-line" }, bar, counts), msg,
              el("div", { class: "controls" }, quantity, tbar, third, thirdCaption), mapBox);

  async function poll() {
    try {
      const g = await api(`api/grids/${encodeURIComponent(id)}`);
      st.grid = g;
      badge.replaceChildren(stateBadge(g.state));
      badge.dataset.state = g.state;
      setProgress(bar, num(g.progress));
      const c = g.counts || {};
      counts.textContent = `${percent(num(g.progress))} · ${g.point_count} points: ` +
        `${c.succeeded} succeeded, ${c.running} running, ${c.queued} queued, ${c.failed} failed,` +
        ` ${c.cancelled} cancelled`;
      if ((g.shape || []).length === 3) {
        third.hidden = false;
        third.max = g.shape[2] - 1;
      }
      await draw();
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `${e.code}: ${e.message}`);
    }
    if (!st.stopped && !(st.grid && TERMINAL.has(st.grid.state))) {
      st.timer = setTimeout(poll, POLL_MS);
    }
  }

  async function draw() {
    const g = st.grid;
    if (!g) return;
    tbar.hidden = quantity.value !== "abar_at";
    let r;
    try {
      r = await api(`api/grids/${encodeURIComponent(id)}/reduction`, {
        params: { quantity: quantity.value, tbar: quantity.value === "abar_at" ? tbar.value : "" } });
      message(msg, "");
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `${e.code}: ${e.message}`);
      return;
    }
    const axes = r.axes.map((a) => ({ name: a.name, values: a.values.map(num) }));
    const shape = r.shape.map(Number);
    // Axis 0 up, axis 1 across (a single axis: one row); a third axis fixed by the slider.
    const k = Number(third.value);
    if (shape.length === 3) {
      thirdCaption.textContent = `${axes[2].name} = ${fmt(axes[2].values[k])}`;
    }
    const across = shape.length >= 2 ? axes[1] : axes[0];
    const up = shape.length >= 2 ? axes[0] : { name: "", values: [NaN] };
    const index = (i, j) => {
      if (shape.length === 1) return i;
      if (shape.length === 2) return j * shape[1] + i;
      return (j * shape[1] + i) * shape[2] + k;
    };
    const svgMap = gridMap(across, up, (i, j) => {
      const n = index(i, j);
      return { value: num(r.values[n]), job: r.job_ids[n], state: r.states[n] };
    }, { id: "grid-map", barLabel: `${r.quantity}${r.units && r.units !== "1" ? " (" + r.units + ")" : ""}`,
         onClick: (job) => { location.hash = "#/jobs/" + job; } });
    mapBox.replaceChildren(svgMap);
  }

  quantity.addEventListener("change", draw);
  tbar.addEventListener("change", draw);
  third.addEventListener("input", draw);
  poll();
  return () => { st.stopped = true; clearTimeout(st.timer); };
}
