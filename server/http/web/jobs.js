// The jobs table: newest first as the daemon lists them, filtered by state, label and owner on
// the server (ListJobs) and by a parameter condition on the loaded rows ("load.pressure>=1e9"),
// sortable by any column, refreshed every second while the page is open (live progress and
// states). Select two or more rows to compare them.

import { api, ApiError, TERMINAL, num } from "./api.js";
import { at, duration, el, elapsed, labelsText, localTime, message, percent, progressBar,
         setProgress, stateBadge } from "./dom.js";
import { fmt } from "./plots.js";

const POLL_MS = 1000;
const STATES = ["", "QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED"];

// A parameter condition: PATH OP VALUE with OP one of = != < <= > >= ~ (contains). PATH is a
// job field (owner, state, reason) or a spec field (load.pressure, geometry.target_elements).
export function parseCondition(text) {
  const m = /^\s*([A-Za-z_][\w.]*)\s*(<=|>=|!=|=|<|>|~)\s*(.+?)\s*$/.exec(text);
  if (!m) throw new Error("write PATH OP VALUE, e.g. load.pressure>=1e9 (OP: = != < <= > >= ~)");
  return { path: m[1], op: m[2], value: m[3] };
}

export function matches(job, cond) {
  let v = cond.path in job ? job[cond.path] : at(job.spec, cond.path);
  if (v === undefined || v === null || typeof v === "object") return false;
  const a = Number(v), b = Number(cond.value);
  const numeric = v !== "" && cond.value !== "" && Number.isFinite(a) && Number.isFinite(b);
  const [x, y] = numeric ? [a, b] : [String(v), cond.value];
  switch (cond.op) {
    case "=": return x === y;
    case "!=": return x !== y;
    case "<": return x < y;
    case "<=": return x <= y;
    case ">": return x > y;
    case ">=": return x >= y;
    case "~": return String(v).includes(cond.value);
  }
  return false;
}

const COLUMNS = [
  { key: "select", title: "", sort: null },
  { key: "id", title: "Job", sort: (j) => j.id },
  { key: "state", title: "State", sort: (j) => j.state },
  { key: "progress", title: "Progress", sort: (j) => num(j.progress && j.progress.fraction) },
  { key: "owner", title: "Owner", sort: (j) => j.owner },
  { key: "labels", title: "Labels", sort: (j) => labelsText(j.labels) },
  { key: "created", title: "Created", sort: (j) => Date.parse(j.create_time) || 0 },
  { key: "elapsed", title: "Elapsed", sort: (j) => elapsed(j) },
  { key: "pressure", title: "Pressure (Pa)", sort: (j) => num(at(j.spec, "load.pressure")) },
  { key: "elements", title: "Elements", sort: (j) => num(at(j.spec, "geometry.target_elements")) },
  { key: "end_time", title: "End time (ns)", sort: (j) => num(at(j.spec, "run.end_time")) },
  { key: "action", title: "", sort: null },
];

function compare(a, b) {
  const na = typeof a === "number" && Number.isNaN(a), nb = typeof b === "number" && Number.isNaN(b);
  if (na || nb) return na === nb ? 0 : na ? 1 : -1;  // unknowns last
  return a < b ? -1 : a > b ? 1 : 0;
}

export function jobsPage(root, ctx) {
  const state = { jobs: [], next: "", condition: null, sort: { key: "created", dir: -1 },
                  selected: new Set(), timer: 0, stopped: false, pages: 1 };
  const stateSel = el("select", { id: "filter-state", "aria-label": "state" },
                      STATES.map((s) => el("option", { value: s }, s || "any state")));
  const labelIn = el("input", { id: "filter-label", placeholder: "label key=value" });
  const ownerIn = el("input", { id: "filter-owner", placeholder: "owner" });
  const paramIn = el("input", { id: "filter-param", placeholder: "parameter, e.g. load.pressure>=1e9" });
  const apply = el("button", { id: "filter-apply", type: "submit" }, "Filter");
  const compareBtn = el("button", { id: "compare-selected", type: "button", disabled: true },
                        "Compare selected");
  const msg = el("p", { id: "jobs-message", class: "message", role: "alert" });
  const count = el("p", { id: "jobs-count", class: "muted" });
  const more = el("button", { id: "jobs-more", type: "button", hidden: true }, "Load more");
  const head = el("tr", {}, COLUMNS.map((c) => el("th", {
    dataset: { key: c.key }, class: c.sort ? "sortable" : "",
    onclick: c.sort ? () => sortBy(c.key) : null,
  }, c.title)));
  const tbody = el("tbody");
  const table = el("table", { id: "jobs-table", class: "jobs" }, el("thead", {}, head), tbody);
  const rows = new Map();  // job id -> <tr>

  root.append(
    el("h1", {}, "Jobs"),
    el("form", { class: "filters", onsubmit: (e) => { e.preventDefault(); refilter(); } },
       stateSel, labelIn, ownerIn, paramIn, apply, compareBtn),
    msg, count, table, more);

  function sortBy(key) {
    state.sort = state.sort.key === key ? { key, dir: -state.sort.dir } : { key, dir: 1 };
    render();
  }

  function refilter() {
    try {
      state.condition = paramIn.value.trim() ? parseCondition(paramIn.value) : null;
      message(msg, "");
    } catch (e) {
      message(msg, "Parameter filter: " + e.message);
      return;
    }
    state.pages = 1;
    load();
  }

  function params(token) {
    return { state: stateSel.value, label: labelIn.value.trim(), owner: ownerIn.value.trim(),
             page_size: Math.min(200, 50 * state.pages), page_token: token };
  }

  // Reloads the pages shown so far (one call of up to 200 jobs), then schedules the next poll.
  async function load() {
    clearTimeout(state.timer);
    try {
      const page = await api("api/jobs", { params: params("") });
      state.jobs = page.jobs || [];
      state.next = page.next_page_token || "";
      render();
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, e instanceof ApiError ? `${e.code}: ${e.message}` : String(e));
    }
    if (!state.stopped) state.timer = setTimeout(load, POLL_MS);
  }

  function cell(job, key) {
    switch (key) {
      case "select": {
        const box = el("input", { type: "checkbox", class: "select", "aria-label": "select " + job.id });
        box.checked = state.selected.has(job.id);
        box.addEventListener("change", () => {
          if (box.checked) state.selected.add(job.id); else state.selected.delete(job.id);
          compareBtn.disabled = state.selected.size < 2;
        });
        return box;
      }
      case "id": return el("a", { href: "#/jobs/" + job.id }, job.id);
      case "progress": return progressBar(num(job.progress && job.progress.fraction));
      case "action": return el("button", { type: "button", class: "cancel",
                                           onclick: () => cancel(job.id) }, "Cancel");
      default: return null;
    }
  }

  function text(job, key) {
    switch (key) {
      case "state": return job.state;
      case "owner": return job.owner;
      case "labels": return labelsText(job.labels);
      case "created": return localTime(job.create_time);
      case "elapsed": return duration(elapsed(job));
      case "pressure": return fmt(num(at(job.spec, "load.pressure")));
      case "elements": return fmt(num(at(job.spec, "geometry.target_elements")));
      case "end_time": return fmt(num(at(job.spec, "run.end_time")) * 1e9);
      default: return "";
    }
  }

  function row(job) {
    let tr = rows.get(job.id);
    if (!tr) {
      tr = el("tr", { dataset: { jobId: job.id } },
              COLUMNS.map((c) => el("td", { class: c.key }, cell(job, c.key))));
      rows.set(job.id, tr);
    }
    const tds = tr.children;
    COLUMNS.forEach((c, i) => {
      if (c.key === "state") {
        if (tds[i].textContent !== job.state) tds[i].replaceChildren(stateBadge(job.state));
      } else if (c.key === "progress") {
        const f = job.state === "SUCCEEDED" ? 1 : num(job.progress && job.progress.fraction);
        setProgress(tds[i].firstChild, f);
        tds[i].dataset.percent = percent(f);
        tds[i].title = percent(f);
      } else if (c.key === "action") {
        tds[i].firstChild.hidden = TERMINAL.has(job.state);
      } else if (!["select", "id"].includes(c.key)) {
        const t = text(job, c.key);
        if (tds[i].textContent !== t) tds[i].textContent = t;
      }
    });
    tr.dataset.state = job.state;
    return tr;
  }

  function render() {
    const shown = state.jobs.filter((j) => !state.condition || matches(j, state.condition));
    const col = COLUMNS.find((c) => c.key === state.sort.key);
    shown.sort((a, b) => state.sort.dir * compare(col.sort(a), col.sort(b)));
    const keep = new Set(shown.map((j) => j.id));
    for (const [id, tr] of rows) {
      if (!keep.has(id)) { tr.remove(); rows.delete(id); }
    }
    shown.forEach((job, i) => {
      const tr = row(job);
      if (tbody.children[i] !== tr) tbody.insertBefore(tr, tbody.children[i] || null);
    });
    for (const th of head.children) {
      th.setAttribute("aria-sort", th.dataset.key !== state.sort.key ? "none"
                      : state.sort.dir > 0 ? "ascending" : "descending");
    }
    count.textContent = `${shown.length} job(s) shown of ${state.jobs.length} loaded` +
                        (state.next ? " (more on the server)" : "");
    more.hidden = !state.next || state.pages >= 4;
  }

  async function cancel(id) {
    try {
      const job = await api(`api/jobs/${encodeURIComponent(id)}/cancel`, { method: "POST" });
      message(msg, `Job ${id} is ${job.state}.`, "notice");
      load();
    } catch (e) {
      if (ctx.authFailed(e)) return;
      message(msg, `Cannot cancel ${id}: ${e.code}: ${e.message}`);
    }
  }

  more.addEventListener("click", () => { state.pages += 1; load(); });
  compareBtn.addEventListener("click", () => {
    location.hash = "#/compare/" + [...state.selected].join(",");
  });
  load();
  return () => { state.stopped = true; clearTimeout(state.timer); };
}
