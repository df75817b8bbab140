// The dashboard's shell: sign-in with a bearer token, the caller in the header, and hash routes
//   #/jobs               the jobs table            (jobs.js)
//   #/jobs/ID            one job                   (job.js)
//   #/grids, #/grids/ID  grids and a grid's map    (grids.js)
//   #/compare/ID,ID,...  two or more jobs side by side (compare.js)
// Each page is a function (root, ctx) that renders into root and returns a stop() that ends its
// polling when the route changes.

import { api, ApiError, clearToken, setToken, token } from "./api.js";
import { comparePage } from "./compare.js";
import { gridPage, gridsPage } from "./grids.js";
import { jobPage } from "./job.js";
import { jobsPage } from "./jobs.js";

const app = document.getElementById("app");
const login = document.getElementById("login");
const who = document.getElementById("who");
const logout = document.getElementById("logout");
let stopPage = () => {};
let caller = null;

function showLogin(message) {
  stopPage();
  stopPage = () => {};
  caller = null;
  app.replaceChildren();
  who.textContent = "";
  logout.hidden = true;
  login.hidden = false;
  document.getElementById("login-error").textContent = message || "";
  document.getElementById("token").focus();
}

// Called by pages when a request comes back 401: the token is gone or was never right.
function authFailed(err) {
  if (err instanceof ApiError && err.status === 401) {
    clearToken();
    showLogin("Signed out: " + err.message);
    return true;
  }
  return false;
}

async function signIn() {
  try {
    caller = await api("api/caller");
  } catch (e) {
    if (e instanceof ApiError && e.status === 401) {
      const had = Boolean(token());
      clearToken();
      showLogin(had ? "That token was refused: " + e.message : "");
      return false;
    }
    app.replaceChildren();
    const p = document.createElement("p");
    p.className = "error";
    p.textContent = "Cannot reach softshockd: " + e.message;
    app.appendChild(p);
    return false;
  }
  login.hidden = true;
  who.textContent = `${caller.user} (${caller.role})`;
  logout.hidden = !token();
  route();
  return true;
}

function route() {
  if (!caller) return;
  stopPage();
  stopPage = () => {};
  const hash = decodeURIComponent(location.hash.replace(/^#\/?/, ""));
  const [page, arg] = [hash.split("/")[0] || "jobs", hash.split("/").slice(1).join("/")];
  for (const a of document.querySelectorAll("[data-nav]")) {
    a.classList.toggle("active", a.dataset.nav === page);
  }
  app.replaceChildren();
  const ctx = { caller, authFailed };
  let stop;
  if (page === "jobs" && arg) stop = jobPage(app, ctx, arg);
  else if (page === "jobs") stop = jobsPage(app, ctx);
  else if (page === "grids" && arg) stop = gridPage(app, ctx, arg);
  else if (page === "grids") stop = gridsPage(app, ctx);
  else if (page === "compare") stop = comparePage(app, ctx, arg.split(",").filter(Boolean));
  else {
    const p = document.createElement("p");
    p.className = "error";
    p.textContent = "No such page: #/" + hash;
    app.appendChild(p);
  }
  stopPage = stop || (() => {});
}

document.getElementById("login-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const input = document.getElementById("token");
  if (!input.value.trim()) return;
  setToken(input.value);
  input.value = "";
  document.getElementById("login-error").textContent = "";
  await signIn();
});
logout.addEventListener("click", () => {
  clearToken();
  showLogin("");
});
window.addEventListener("hashchange", route);
signIn();
