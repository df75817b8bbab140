// Small DOM helpers shared by the pages.

import { num } from "./api.js";

// el("td", {class: "state", dataset: {jobId: id}}, "text", child, ...)
export function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k === "class") e.className = v;
    else if (k === "dataset") Object.assign(e.dataset, v);
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children.flat()) {
    if (c === undefined || c === null || c === false) continue;
    e.appendChild(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}

export function stateBadge(state) {
  return el("span", { class: "badge state-" + String(state).toLowerCase() }, state);
}

// A progress bar whose fill is set through the CSSOM (the page's CSP allows no style attributes).
export function progressBar(fraction) {
  const fill = el("span", { class: "fill" });
  const bar = el("span", { class: "bar" }, fill);
  setProgress(bar, fraction);
  return bar;
}

export function setProgress(bar, fraction) {
  const f = Math.min(1, Math.max(0, Number(fraction) || 0));
  bar.firstChild.style.width = (100 * f).toFixed(1) + "%";
  bar.dataset.fraction = f.toFixed(4);
}

export function percent(fraction) {
  return Math.round(100 * Math.min(1, Math.max(0, Number(fraction) || 0))) + "%";
}

export function seconds(t) {
  return t ? Date.parse(t) / 1000 : NaN;
}

// "3.2 s", "4 min 10 s", "2 h 05 min"
export function duration(s) {
  if (!Number.isFinite(s) || s < 0) return "—";
  if (s < 60) return s.toFixed(s < 10 ? 1 : 0) + " s";
  if (s < 3600) return `${Math.floor(s / 60)} min ${String(Math.round(s % 60)).padStart(2, "0")} s`;
  return `${Math.floor(s / 3600)} h ${String(Math.round((s % 3600) / 60)).padStart(2, "0")} min`;
}

// Wall time of a job so far: from its start to its finish (or now).
export function elapsed(job) {
  const start = seconds(job.start_time);
  if (!Number.isFinite(start) || start <= 0) return NaN;
  const end = seconds(job.finish_time);
  return (Number.isFinite(end) && end > 0 ? end : Date.now() / 1000) - start;
}

export function localTime(t) {
  const s = seconds(t);
  return Number.isFinite(s) && s > 0 ? new Date(s * 1000).toLocaleString() : "—";
}

// The value at a dotted path of an object ("load.pressure"), or undefined.
export function at(obj, path) {
  let v = obj;
  for (const part of path.split(".")) {
    if (v === null || typeof v !== "object") return undefined;
    v = v[part];
  }
  return v;
}

export function labelsText(labels) {
  return Object.entries(labels || {}).map(([k, v]) => `${k}=${v}`).join(", ");
}

// A message line that pages reuse for errors and notices.
export function message(node, text, kind = "error") {
  node.textContent = text || "";
  node.className = "message " + kind;
}

export { num };
