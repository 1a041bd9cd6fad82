// solidsynth viewer: talks to the server's HTTP API (documented in the README).
// Four plain scripts share one global scope, loaded in this order: viewer.js (this one: the page
// state, the API, solids and jobs), cuts.js (the free cut and the slices, synthesized by the
// server on demand), view3d.js (the WebGL2 object view) and meshes.js (meshes, uploads, surface
// bakes and their .glb). Startup waits for DOMContentLoaded, when all four have run.
"use strict";

const $ = (id) => document.getElementById(id);
const view = {
  solid: null,        // {id, name, seed, preview_size, params}
  volume: null,       // the preview volume: Uint8Array RGBA, x fastest
  n: 0,               // preview edge
  solids: [],         // the server's solids, from /api/state
  limits: null,       // the server's request limits, from /api/state
};
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function api(path, options) {
  const r = await fetch(path, options);
  if (!r.ok) {
    let message = r.status + " " + r.statusText;
    try { message = (await r.json()).error || message; } catch (_) { /* not JSON */ }
    throw new Error(message);
  }
  return r;
}

// The page's status line (in the header): the latest message of any part, errors in red.
function say(text, error) {
  const s = $("status");
  s.textContent = text;
  s.className = error ? "error" : "muted";
}

// The solid job's line in the solid panel; errors also go to the page's status line.
function setJobStatus(text, error) {
  const s = $("job-status");
  s.textContent = text;
  s.className = error ? "error" : "muted";
  if (error) say(text, true);
}

const ended = (job) => job.state === "done" || job.state === "failed" || job.state === "cancelled";
const percent = (job) => `${Math.round(job.progress * 100)}%`;

// ---- startup ----

async function init() {
  const [state, exemplars] = await Promise.all([
    api("/api/state").then((r) => r.json()),
    api("/api/exemplars").then((r) => r.json()),
  ]);
  $("backend").textContent = "backend: " + state.backend;
  view.limits = state.limits;
  for (const e of exemplars) {
    const o = document.createElement("option");
    o.value = e.name;
    o.textContent = e.name;
    o.title = e.description;
    $("exemplar").appendChild(o);
  }
  showThumb();
  applyState(state);
  await loadMeshList();
  // A reload finds the server's jobs where they are: the list shows them all (from /api/state),
  // and the page follows the newest running solid job and bake as if it had started them.
  const running = state.jobs.filter((j) => !ended(j));
  const solidJob = running.filter((j) => j.kind === "solid").pop();
  const bakeJob = running.filter((j) => j.kind === "surface").pop();
  if (solidJob) followSolidJob(solidJob.id);
  if (state.solids.length && !solidJob) await loadSolid(state.solids[state.solids.length - 1]);
  if (bakeJob) followBake(bakeJob, null);
  watchJobs();
}

function showThumb() {
  $("exemplar-thumb").src = "/api/exemplars/" + encodeURIComponent($("exemplar").value) + ".png";
}

// ---- new solids ----

// The query of a new solid: the seed, and each parameter the page sets (empty: the server's).
function solidQuery() {
  const q = new URLSearchParams();
  q.set("seed", String(Math.max(0, Math.floor(+$("seed").value || 0))));
  for (const [key, id] of [["jitter", "p-jitter"], ["color", "p-color"], ["passes", "p-passes"],
    ["feature", "p-feature"], ["coarse_cache", "p-cache"]]) {
    const value = $(id).value.trim();
    if (value !== "") q.set(key, value);
  }
  return q;
}

async function startSolidJob(query, body, contentType) {
  try {
    const options = { method: "POST" };
    if (body) {
      options.body = body;
      options.headers = { "Content-Type": contentType || "application/octet-stream" };
    }
    const job = await (await api("/api/solids?" + query, options)).json();
    say(`started job ${job.id}: a solid from ${job.name}`);
    followSolidJob(job.id);
  } catch (e) {
    setJobStatus(e.message, true);
  }
}

function followSolidJob(id) {
  document.body.dataset.job = "running";
  follow(id, {
    update(job) {
      $("job-progress").value = job.progress;
      setJobStatus(`${job.name}: ${job.stage} (${percent(job)}, ${job.seconds.toFixed(1)} s)`);
    },
    async end(job) {
      $("job-progress").value = job.progress;
      document.body.dataset.job = job.state;
      if (job.state === "done") {
        setJobStatus(`${job.name}: ready in ${job.seconds.toFixed(1)} s`);
        say(`solid ${job.solid} (${job.name}) is ready`);
        const solid = await (await api("/api/solids/" + job.solid)).json();
        await loadSolid(solid);
      } else if (job.state === "cancelled") {
        setJobStatus(`${job.name}: cancelled`);
      } else {
        setJobStatus(`${job.name}: failed: ${job.error}`, true);
      }
    },
  });
}

// "jitter 1 · colour average · passes 2 · coarse cache 64": what a solid was made with.
function describeParams(p) {
  if (!p) return "";
  return `jitter ${p.jitter} · colour ${p.color} · passes ${p.passes} · coarse cache ${p.coarse_cache || "none"}`;
}

async function loadSolid(solid) {
  try {
    const r = await api(`/api/solids/${solid.id}/volume?format=raw`);
    view.volume = new Uint8Array(await r.arrayBuffer());
  } catch (e) {
    say(`solid ${solid.id}: ${e.message}`, true);
    return;
  }
  view.n = solid.preview_size;
  view.solid = solid;
  $("solid-info").textContent =
    `solid ${solid.id}: ${solid.name}, seed ${solid.seed}, preview ${view.n}^3; ${describeParams(solid.params)}`;
  renderSolids(view.solids);
  updateDownloads();
  uploadVolumeTexture();
  document.body.dataset.solid = String(solid.id);
  surfaceContextChanged(); // meshes.js: a baked surface belongs to its solid
  solidChanged();          // cuts.js: every cut is of the new solid
}

function updateDownloads() {
  const id = view.solid && view.solid.id;
  const size = $("dl-size").value;
  for (const [format, ext] of [["nrrd", "nrrd"], ["nrrd-gzip", "nrrd"], ["vti", "vti"], ["vdb", "vdb"],
    ["flipbook", "png"], ["npy", "npy"], ["tiff", "tif"], ["ktx2", "ktx2"], ["raw", "rgba"]]) {
    const a = $("dl-" + format);
    a.href = id ? `/api/solids/${id}/volume?format=${format}&size=${size}` : "#";
    a.download = id ? `solid-${id}-${size}${format === "nrrd-gzip" ? "-gzip" : ""}.${ext}` : "";
    a.setAttribute("aria-disabled", id ? "false" : "true");
  }
  $("dl-cut").setAttribute("aria-disabled", freeCut.url ? "false" : "true");
}

// ---- jobs: one poll of /api/state drives the solid list, the job list and every followed job ----

const watch = {
  followers: new Map(), // job id -> {update(job), end(job)}
  polling: false,
  rows: new Map(),      // job id -> its <li> in the job list
};

// Call handlers.update(job) while job `id` runs and handlers.end(job) once when it has ended.
function follow(id, handlers) {
  watch.followers.set(id, handlers);
  watchJobs();
}

// Polls while a job is queued or running or a followed job has not been seen to end.
async function watchJobs() {
  if (watch.polling) return;
  watch.polling = true;
  try {
    for (;;) {
      let state = null;
      try {
        state = await (await api("/api/state")).json();
      } catch (e) {
        say("the server does not answer: " + e.message, true);
      }
      if (state) {
        applyState(state);
        await notifyFollowers(state.jobs);
      }
      const active = state ? state.jobs.some((j) => !ended(j)) : true;
      if (!active && watch.followers.size === 0) break;
      await sleep(state ? 300 : 2000);
    }
  } finally {
    watch.polling = false;
  }
}

async function notifyFollowers(jobs) {
  for (const [id, handlers] of [...watch.followers]) {
    const job = jobs.find((j) => j.id === id);
    if (!job) {
      // The server keeps the newest finished jobs only.
      watch.followers.delete(id);
      say(`job ${id} is no longer on the server`, true);
      continue;
    }
    if (!ended(job)) { handlers.update(job); continue; }
    watch.followers.delete(id);
    try { await handlers.end(job); } catch (e) { say(e.message, true); }
  }
}

function applyState(state) {
  view.solids = state.solids;
  renderSolids(state.solids);
  renderJobs(state.jobs);
}

// The solid list: each with what it was made with, the shown one marked; a click shows it.
function renderSolids(solids) {
  const ul = $("solids");
  const shown = view.solid && view.solid.id;
  const items = solids.map((s) => {
    const li = document.createElement("li");
    li.dataset.solid = String(s.id);
    if (s.id === shown) li.className = "current";
    const b = document.createElement("button");
    b.textContent = s.id === shown ? "shown" : "show";
    b.disabled = s.id === shown;
    b.addEventListener("click", () => loadSolid(s));
    const text = document.createElement("span");
    text.innerHTML = `<b>${s.id}</b> ${escapeHtml(s.name)}, seed ${s.seed} <span class="muted">${describeParams(s.params)}</span>`;
    li.append(b, " ", text);
    return li;
  });
  // Rebuilt only when something changed: a rebuild between a press and a release would eat a click.
  const key = JSON.stringify([shown, solids]);
  if (ul.dataset.key !== key) {
    ul.dataset.key = key;
    ul.replaceChildren(...items.reverse());
  }
}

// The job list, newest first; rows are updated in place (their buttons stay clickable).
function renderJobs(jobs) {
  const ul = $("jobs");
  const seen = new Set();
  for (const job of jobs) {
    seen.add(job.id);
    let li = watch.rows.get(job.id);
    if (!li) {
      li = document.createElement("li");
      li.dataset.job = String(job.id);
      li.innerHTML = `<span class="job-text"></span> <progress max="1"></progress> <span class="job-actions"></span>`;
      watch.rows.set(job.id, li);
      ul.prepend(li);
    }
    const key = job.state + (job.surface || "");
    li.dataset.state = job.state;
    li.querySelector("progress").value = job.progress;
    li.querySelector("progress").hidden = ended(job);
    const detail = job.state === "failed" ? ` · ${job.error}` : ended(job) ? "" : ` · ${job.stage} ${percent(job)}`;
    li.querySelector(".job-text").innerHTML = `<b>${job.id}</b> ${job.kind === "surface" ? "bake" : "solid"}: ` +
      `${escapeHtml(job.name)} · <span class="state-${job.state}">${job.state}</span>${escapeHtml(detail)} · ${job.seconds.toFixed(1)} s`;
    if (li.dataset.key === key) continue;
    li.dataset.key = key;
    const actions = li.querySelector(".job-actions");
    actions.replaceChildren();
    if (!ended(job)) {
      const b = document.createElement("button");
      b.textContent = "Cancel";
      b.className = "cancel";
      b.addEventListener("click", () => cancelJob(job.id));
      actions.append(b);
    } else if (job.state === "done" && job.surface) {
      const b = document.createElement("button");
      b.textContent = "show";
      b.addEventListener("click", () => showSurfaceById(job.surface));
      const a = document.createElement("a");
      a.href = `/api/surfaces/${job.surface}.glb`;
      a.download = "";
      a.textContent = ".glb";
      actions.append(b, " ", a);
    }
  }
  for (const [id, li] of watch.rows) {
    if (!seen.has(id)) { li.remove(); watch.rows.delete(id); }
  }
}

async function cancelJob(id) {
  try {
    const job = await (await api(`/api/jobs/${id}/cancel`, { method: "POST" })).json();
    say(`job ${id} (${job.name}): cancelling`);
    watchJobs();
  } catch (e) {
    say(`cancel job ${id}: ${e.message}`, true);
  }
}

function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

// ---- wiring ----

function wireSolids() {
  $("exemplar").addEventListener("change", showThumb);
  $("synthesize").addEventListener("click", () => {
    const q = solidQuery();
    q.set("exemplar", $("exemplar").value);
    startSolidJob(q);
  });
  $("upload-go").addEventListener("click", () => {
    const f = $("upload").files[0];
    if (!f) { setJobStatus("choose an image first", true); return; }
    const q = solidQuery();
    q.set("periodic", $("periodic").checked ? "1" : "0");
    startSolidJob(q, f, f.type);
  });
  $("dl-size").addEventListener("change", updateDownloads);
}

window.addEventListener("DOMContentLoaded", () => {
  wireSolids();
  wireCuts();
  wireView();
  wireMeshes();
  updateDownloads();
  init().catch((e) => say(e.message, true));
});
