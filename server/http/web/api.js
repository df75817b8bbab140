// The daemon's JSON API (docs/api.md, "HTTP: dashboard and metrics") as the pages use it. The
// bearer token lives in this tab's sessionStorage and travels only in the Authorization header,
// never in a URL.

const TOKEN_KEY = "softshock.token";

export class ApiError extends Error {
  constructor(status, code, message) {
    super(message);
    this.status = status;
    this.code = code;
  }
}

export function token() {
  return sessionStorage.getItem(TOKEN_KEY) || "";
}

export function setToken(value) {
  sessionStorage.setItem(TOKEN_KEY, value.trim());
}

export function clearToken() {
  sessionStorage.removeItem(TOKEN_KEY);
}

// GET (or POST) `path` relative to the page, with query `params` (empty values left out);
// resolves to the parsed JSON, rejects with an ApiError carrying the server's code and message.
export async function api(path, { method = "GET", params = {} } = {}) {
  const url = new URL(path, document.baseURI);
  for (const [k, v] of Object.entries(params)) {
    if (v !== undefined && v !== null && v !== "") url.searchParams.set(k, String(v));
  }
  const headers = {};
  const t = token();
  if (t) headers.Authorization = "Bearer " + t;
  let res;
  try {
    res = await fetch(url, { method, headers, cache: "no-store", credentials: "omit" });
  } catch (e) {
    throw new ApiError(0, "UNAVAILABLE", "the daemon cannot be reached (" + e.message + ")");
  }
  let body = null;
  try {
    body = await res.json();
  } catch (e) {
    body = null;
  }
  if (!res.ok) {
    const err = (body && body.error) || {};
    throw new ApiError(res.status, err.code || String(res.status), err.message || res.statusText);
  }
  return body;
}

// Numbers as protobuf's JSON mapping writes them: 64-bit integers as strings, NaN as "NaN".
export function num(v) {
  if (v === null || v === undefined || v === "") return NaN;
  return Number(v);
}

export const TERMINAL = new Set(["SUCCEEDED", "FAILED", "CANCELLED"]);
