// solidsynth viewer: talks to the server's HTTP API (documented in the README).
// State: the current solid (id, preview volume), the free cut plane, the 3D view.
"use strict";

const $ = (id) => document.getElementById(id);
const view = {
  solid: null,        // {id, name, seed, preview_size}
  volume: null,       // Uint8Array RGBA, x fastest
  n: 0,               // preview edge
  cut: null,          // {origin, frame: {u, v, n}, size, spacing, bitmap}
  cutBusy: false,     // a cut request is in flight
  cutAgain: false,    // the plane moved while it was: ask again when it returns
  cutCount: 0,
  cutUrl: null,
  rot: { yaw: 0.6, pitch: 0.35 },
};

async function api(path, options) {
  const r = await fetch(path, options);
  if (!r.ok) {
    let message = r.status + " " + r.statusText;
    try { message = (await r.json()).error || message; } catch (_) { /* not JSON */ }
    throw new Error(message);
  }
  return r;
}

function setStatus(text, error) {
  const s = $("job-status");
  s.textContent = text;
  s.className = error ? "error" : "muted";
}

// ---- solids and jobs ----

async function init() {
  const [state, exemplars] = await Promise.all([
    api("/api/state").then((r) => r.json()),
    api("/api/exemplars").then((r) => r.json()),
  ]);
  $("backend").textContent = "backend: " + state.backend;
  for (const e of exemplars) {
    const o = document.createElement("option");
    o.value = e.name;
    o.textContent = e.name;
    o.title = e.description;
    $("exemplar").appendChild(o);
  }
  showThumb();
  const running = state.jobs.filter((j) => j.state === "running" || j.state === "queued");
  if (running.length) {
    pollJob(running[running.length - 1].id);
  } else if (state.solids.length) {
    await loadSolid(state.solids[state.solids.length - 1]);
  }
}

function showThumb() {
  $("exemplar-thumb").src = "/api/exemplars/" + encodeURIComponent($("exemplar").value) + ".png";
}

async function startJob(url, body, contentType) {
  try {
    const options = { method: "POST" };
    if (body) {
      options.body = body;
      options.headers = { "Content-Type": contentType || "application/octet-stream" };
    }
    const job = await (await api(url, options)).json();
    pollJob(job.id);
  } catch (e) {
    setStatus(e.message, true);
  }
}

async function pollJob(id) {
  document.body.dataset.job = "running";
  for (;;) {
    let job;
    try {
      job = await (await api("/api/jobs/" + id)).json();
    } catch (e) {
      setStatus(e.message, true);
      document.body.dataset.job = "failed";
      return;
    }
    $("job-progress").value = job.progress;
    if (job.state === "done") {
      setStatus(`${job.name}: ready in ${job.seconds.toFixed(1)} s`);
      document.body.dataset.job = "done";
      const solid = await (await api("/api/solids/" + job.solid)).json();
      await loadSolid(solid);
      return;
    }
    if (job.state === "failed") {
      setStatus(`${job.name}: failed: ${job.error}`, true);
      document.body.dataset.job = "failed";
      return;
    }
    setStatus(`${job.name}: ${job.stage} (${Math.round(job.progress * 100)}%, ${job.seconds.toFixed(1)} s)`);
    await new Promise((r) => setTimeout(r, 250));
  }
}

async function loadSolid(solid) {
  const r = await api(`/api/solids/${solid.id}/volume?format=raw`);
  view.volume = new Uint8Array(await r.arrayBuffer());
  view.n = solid.preview_size;
  view.solid = solid;
  $("solid-info").textContent =
    `solid ${solid.id}: ${solid.name}, seed ${solid.seed}, preview ${view.n}^3`;
  for (const a of ["x", "y", "z"]) {
    const s = $(`slice-${a}-pos`);
    s.max = view.n - 1;
    if (+s.value > view.n - 1) s.value = view.n >> 1;
  }
  updateDownloads();
  drawSlices();
  uploadVolumeTexture();
  document.body.dataset.solid = String(solid.id);
  requestCut();
}

function updateDownloads() {
  const id = view.solid && view.solid.id;
  const size = $("dl-size").value;
  for (const [el, format, ext] of [["dl-nrrd", "nrrd", "nrrd"], ["dl-vti", "vti", "vti"], ["dl-flipbook", "flipbook", "png"]]) {
    const a = $(el);
    a.href = id ? `/api/solids/${id}/volume?format=${format}&size=${size}` : "#";
    a.download = id ? `solid-${id}-${size}.${ext}` : "";
    a.setAttribute("aria-disabled", id ? "false" : "true");
  }
  $("dl-cut").setAttribute("aria-disabled", view.cutUrl ? "false" : "true");
}

// ---- orthogonal slices (from the preview volume: instant) ----

function drawSlices() {
  if (!view.volume) return;
  const n = view.n, vol = view.volume;
  for (const axis of ["x", "y", "z"]) {
    const k = +$(`slice-${axis}-pos`).value;
    $(`slice-${axis}-v`).textContent = k;
    const c = $(`slice-${axis}`);
    c.width = n; c.height = n;
    const ctx = c.getContext("2d");
    const img = ctx.createImageData(n, n);
    for (let b = 0; b < n; b++) {
      for (let a = 0; a < n; a++) {
        // x slice: (y, z); y slice: (x, z); z slice: (x, y) -- rows run along the second.
        const [x, y, z] = axis === "x" ? [k, a, b] : axis === "y" ? [a, k, b] : [a, b, k];
        const src = 4 * ((z * n + y) * n + x), dst = 4 * (b * n + a);
        img.data[dst] = vol[src]; img.data[dst + 1] = vol[src + 1];
        img.data[dst + 2] = vol[src + 2]; img.data[dst + 3] = 255;
      }
    }
    ctx.putImageData(img, 0, 0);
  }
}

// ---- the free cut (server-side, on demand) ----

function planeNormal() {
  const az = (+$("cut-azimuth").value) * Math.PI / 180;
  const el = (+$("cut-elevation").value) * Math.PI / 180;
  return [Math.cos(el) * Math.cos(az), Math.cos(el) * Math.sin(az), Math.sin(el)];
}

function planeOrigin() {
  const n = planeNormal(), off = +$("cut-offset").value, c = view.n / 2;
  return [c + off * n[0], c + off * n[1], c + off * n[2]];
}

function requestCut() {
  for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}-v`).textContent = $(`cut-${k}`).value;
  drawView();
  if (!view.solid) return;
  // One request at a time: moves during a request coalesce into one follow-up.
  if (view.cutBusy) { view.cutAgain = true; return; }
  doCut();
}

async function doCut() {
  view.cutBusy = true;
  view.cutAgain = false;
  const n = planeNormal(), o = planeOrigin(), size = +$("cut-size").value;
  const fmt = (v) => v.map((x) => x.toFixed(6)).join(",");
  const url = `/api/solids/${view.solid.id}/cut?origin=${fmt(o)}&normal=${fmt(n)}&size=${size}`;
  const t0 = performance.now();
  try {
    const r = await api(url);
    const blob = await r.blob();
    const roundTrip = performance.now() - t0;
    const frame = JSON.parse(r.headers.get("X-Cut-Frame"));
    const synth = parseFloat(r.headers.get("X-Synthesis-Ms"));
    const queue = parseFloat(r.headers.get("X-Queue-Ms"));
    const bitmap = await createImageBitmap(blob);
    if (view.cutUrl) URL.revokeObjectURL(view.cutUrl);
    view.cutUrl = URL.createObjectURL(blob);
    const img = $("cut-image");
    img.src = view.cutUrl;
    view.cutCount += 1;
    img.dataset.count = String(view.cutCount);
    $("dl-cut").href = view.cutUrl;
    $("dl-cut").download = `cut-${view.solid.id}.png`;
    view.cut = { origin: o, frame, size, spacing: 1, bitmap };
    $("cut-latency").textContent =
      `cut ${view.cutCount}: ${size}x${size} synthesized in ${synth.toFixed(1)} ms` +
      ` (queued ${queue.toFixed(1)} ms), round trip ${roundTrip.toFixed(1)} ms`;
    $("cut-latency").className = "latency";
    uploadCutTexture();
    updateDownloads();
  } catch (e) {
    $("cut-latency").textContent = "cut failed: " + e.message;
    $("cut-latency").className = "latency error";
  }
  view.cutBusy = false;
  if (view.cutAgain) doCut();
  drawView();
}

// Drag on the cut image: tilt the plane (horizontal: azimuth, vertical: elevation).
function dragger(el, onMove) {
  let last = null;
  el.addEventListener("pointerdown", (e) => { last = [e.clientX, e.clientY]; el.setPointerCapture(e.pointerId); e.preventDefault(); });
  el.addEventListener("pointermove", (e) => {
    if (!last) return;
    onMove(e.clientX - last[0], e.clientY - last[1]);
    last = [e.clientX, e.clientY];
  });
  el.addEventListener("pointerup", () => { last = null; });
}

// ---- the 3D view: WebGL2, ray-marched implicit shapes textured by the solid ----

const VS = `#version 300 es
in vec2 p; out vec2 q;
void main() { q = p; gl_Position = vec4(p, 0.0, 1.0); }`;

// Object space is [-1, 1]^3, the preview box [0, n)^3 of the solid (voxel = (p + 1) n / 2).
// The surface samples the 3D texture (the preview volume); where the free plane cuts the shape
// the cap shows the server's on-demand cut image at that point.
const FS = `#version 300 es
precision highp float; precision highp sampler3D;
in vec2 q; out vec4 color;
uniform sampler3D vol; uniform sampler2D cutTex;
uniform mat3 rot; uniform int shape; uniform bool clip; uniform bool haveCut;
uniform vec3 pn; uniform float pd;
uniform vec3 cutO, cutU, cutV; uniform float cutSize, volN;
float ell(vec3 p, vec3 r) { float k0 = length(p / r), k1 = length(p / (r * r)); return k0 * (k0 - 1.0) / k1; }
float smin(float a, float b, float k) { float h = clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0); return mix(b, a, h) - k * h * (1.0 - h); }
float body(vec3 p) {
  if (shape == 0) return length(p) - 0.85;
  // A bunny of smoothly joined ellipsoids: body, head, ears, tail, feet.
  float d = ell(p - vec3(0.0, -0.3, -0.15), vec3(0.5, 0.45, 0.6));
  d = smin(d, ell(p - vec3(0.0, 0.15, 0.42), vec3(0.3, 0.28, 0.3)), 0.15);
  vec3 e = p - vec3(0.12, 0.6, 0.38); e.xy = mat2(0.96, -0.28, 0.28, 0.96) * e.xy;
  d = smin(d, ell(e, vec3(0.08, 0.35, 0.06)), 0.06);
  e = p - vec3(-0.12, 0.6, 0.38); e.xy = mat2(0.96, 0.28, -0.28, 0.96) * e.xy;
  d = smin(d, ell(e, vec3(0.08, 0.35, 0.06)), 0.06);
  d = smin(d, length(p - vec3(0.0, -0.2, -0.78)) - 0.13, 0.05);
  d = smin(d, ell(p - vec3(0.25, -0.72, 0.1), vec3(0.14, 0.08, 0.3)), 0.08);
  d = smin(d, ell(p - vec3(-0.25, -0.72, 0.1), vec3(0.14, 0.08, 0.3)), 0.08);
  return d;
}
float plane(vec3 p) { return clip ? dot(p, pn) - pd : -1e9; }
float sdf(vec3 p) { return max(body(p), plane(p)); }
vec3 normalAt(vec3 p) {
  vec2 h = vec2(1e-3, 0.0);
  return normalize(vec3(sdf(p + h.xyy) - sdf(p - h.xyy), sdf(p + h.yxy) - sdf(p - h.yxy), sdf(p + h.yyx) - sdf(p - h.yyx)));
}
void main() {
  vec3 ro = rot * vec3(0.0, 0.0, 3.2), rd = rot * normalize(vec3(q, -2.2));
  float t = 1.0; bool hit = false; vec3 p;
  for (int i = 0; i < 128; i++) {
    p = ro + t * rd;
    float d = sdf(p);
    if (d < 1e-3) { hit = true; break; }
    t += d;
    if (t > 6.0) break;
  }
  if (!hit) { color = vec4(0.07, 0.07, 0.08, 1.0); return; }
  vec3 voxel = (clamp(p, -1.0, 0.9999) + 1.0) * 0.5 * volN;
  vec3 albedo = texture(vol, voxel / volN).rgb;
  vec3 nrm = normalAt(p);
  bool cap = clip && abs(plane(p)) < 2e-3;
  if (cap) {
    nrm = pn;
    if (haveCut) {
      vec3 r = voxel - cutO;
      vec2 ij = vec2(dot(r, cutU), dot(r, cutV)) + 0.5 * cutSize;
      albedo = texture(cutTex, ij / cutSize).rgb;
    }
  }
  vec3 l = normalize(rot * vec3(0.4, 0.7, 0.6));
  float diffuse = max(dot(nrm, l), 0.0), fill = max(dot(nrm, -rd), 0.0);
  color = vec4(albedo * (0.35 + 0.45 * diffuse + 0.3 * fill), 1.0);
}`;

const gl3 = { gl: null, prog: null, volTex: null, cutTex: null, haveCut: false, loc: {} };

function initGL() {
  const canvas = $("view3d");
  // preserveDrawingBuffer: the frame stays readable (tests read it back) between redraws.
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true });
  if (!gl) { $("view-status").textContent = "WebGL2 is not available in this browser"; return; }
  const compile = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, compile(gl.VERTEX_SHADER, VS));
  gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  const buf = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const at = gl.getAttribLocation(prog, "p");
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 2, gl.FLOAT, false, 0, 0);
  for (const u of ["vol", "cutTex", "rot", "shape", "clip", "haveCut", "pn", "pd", "cutO", "cutU", "cutV", "cutSize", "volN"]) {
    gl3.loc[u] = gl.getUniformLocation(prog, u);
  }
  gl.uniform1i(gl3.loc.vol, 0);
  gl.uniform1i(gl3.loc.cutTex, 1);
  gl3.gl = gl;
  gl3.prog = prog;
  gl3.volTex = gl.createTexture();
  gl3.cutTex = gl.createTexture();
}

function uploadVolumeTexture() {
  const gl = gl3.gl;
  if (!gl || !view.volume) return;
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_3D, gl3.volTex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage3D(gl.TEXTURE_3D, 0, gl.RGBA8, view.n, view.n, view.n, 0, gl.RGBA, gl.UNSIGNED_BYTE, view.volume);
  // Nearest: a point shows the voxel containing it, as the server's cuts do.
  for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST],
    [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_R, gl.CLAMP_TO_EDGE]]) {
    gl.texParameteri(gl.TEXTURE_3D, k, v);
  }
  drawView();
}

function uploadCutTexture() {
  const gl = gl3.gl;
  if (!gl || !view.cut) return;
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, gl3.cutTex);
  // Row 0 of the cut image is its first row (v = 0): no flip, so t = j / size.
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, view.cut.bitmap);
  for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST],
    [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) {
    gl.texParameteri(gl.TEXTURE_2D, k, v);
  }
  gl3.haveCut = true;
}

function rotation() {
  const { yaw, pitch } = view.rot;
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  // Column-major: yaw about y, then pitch about x (camera orbits the object).
  const ry = [cy, 0, -sy, 0, 1, 0, sy, 0, cy];
  const rx = [1, 0, 0, 0, cp, sp, 0, -sp, cp];
  const m = new Array(9).fill(0);
  for (let c = 0; c < 3; c++) for (let r = 0; r < 3; r++) for (let k = 0; k < 3; k++) m[c * 3 + r] += ry[k * 3 + r] * rx[c * 3 + k];
  return m;
}

let drawQueued = false;
function drawView() {
  if (!gl3.gl || drawQueued) return;
  drawQueued = true;
  requestAnimationFrame(() => {
    drawQueued = false;
    const gl = gl3.gl, L = gl3.loc;
    gl.viewport(0, 0, gl.canvas.width, gl.canvas.height);
    gl.uniformMatrix3fv(L.rot, false, rotation());
    gl.uniform1i(L.shape, +$("shape").value);
    gl.uniform1i(L.clip, $("clip").checked ? 1 : 0);
    const n = planeNormal(), o = planeOrigin(), N = view.n || 64;
    gl.uniform3fv(L.pn, n);
    // Plane through the origin's object-space point: p . n = d.
    gl.uniform1f(L.pd, o.reduce((s, x, i) => s + (x / (N / 2) - 1) * n[i], 0));
    gl.uniform1f(L.volN, N);
    // The cap uses the last cut only while it shows the current plane.
    const c = view.cut;
    const current = c && c.origin.every((x, i) => Math.abs(x - o[i]) < 1e-6);
    gl.uniform1i(L.haveCut, gl3.haveCut && current ? 1 : 0);
    if (c) {
      gl.uniform3fv(L.cutO, c.origin);
      gl.uniform3fv(L.cutU, c.frame.u.map((x) => x / c.spacing));
      gl.uniform3fv(L.cutV, c.frame.v.map((x) => x / c.spacing));
      gl.uniform1f(L.cutSize, c.size);
    }
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  });
}

// ---- wiring ----

function wire() {
  $("exemplar").addEventListener("change", showThumb);
  $("synthesize").addEventListener("click", () => {
    const seed = Math.max(0, Math.floor(+$("seed").value || 0));
    startJob(`/api/solids?exemplar=${encodeURIComponent($("exemplar").value)}&seed=${seed}`);
  });
  $("upload-go").addEventListener("click", () => {
    const f = $("upload").files[0];
    if (!f) { setStatus("choose an image first", true); return; }
    const seed = Math.max(0, Math.floor(+$("seed").value || 0));
    startJob(`/api/solids?seed=${seed}&periodic=${$("periodic").checked ? 1 : 0}`, f, f.type);
  });
  for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}`).addEventListener("input", requestCut);
  $("cut-size").addEventListener("change", requestCut);
  for (const a of ["x", "y", "z"]) $(`slice-${a}-pos`).addEventListener("input", drawSlices);
  $("dl-size").addEventListener("change", updateDownloads);
  $("shape").addEventListener("change", drawView);
  $("clip").addEventListener("change", drawView);
  dragger($("cut-image"), (dx, dy) => {
    const az = $("cut-azimuth"), el = $("cut-elevation");
    az.value = ((+az.value + dx * 0.5) % 360 + 360) % 360;
    el.value = Math.max(-90, Math.min(90, +el.value - dy * 0.5));
    requestCut();
  });
  dragger($("view3d"), (dx, dy) => {
    view.rot.yaw -= dx * 0.01;
    view.rot.pitch = Math.max(-1.5, Math.min(1.5, view.rot.pitch + dy * 0.01));
    drawView();
  });
}

wire();
try { initGL(); } catch (e) { $("view-status").textContent = "WebGL error: " + e.message; }
updateDownloads();
for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}-v`).textContent = $(`cut-${k}`).value;
init().catch((e) => setStatus(e.message, true));
