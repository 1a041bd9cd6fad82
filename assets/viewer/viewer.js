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
  for (const [el, format, ext] of [["dl-nrrd", "nrrd", "nrrd"], ["dl-vti", "vti", "vti"], ["dl-flipbook", "flipbook", "png"], ["dl-npy", "npy", "npy"], ["dl-tiff", "tiff", "tif"], ["dl-ktx2", "ktx2", "ktx2"]]) {
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

// ---- the 3D view: WebGL2, textured by the solid ----
// Two shapes: a sphere (ray-marched, an exact implicit surface) and the Stanford bunny (a triangle
// mesh, /bunny.bin). Both live in the same object space, [-1, 1]^3 = the preview box [0, n)^3 of
// the solid (voxel = (p + 1) n / 2), are seen by the same camera (eye at rot * (0, 0, 3.2), focal
// length 2.2), and are textured, clipped and capped the same way: the surface samples the 3D
// texture (the preview volume); the free plane removes the side p . pn > pd; where it cuts the
// shape, the cap shows the server's on-demand cut image at that point (the 3D texture until the
// cut for the current plane has arrived).

const VS = `#version 300 es
in vec2 p; out vec2 q;
void main() { q = p; gl_Position = vec4(p, 0.0, 1.0); }`;

// Shared by both fragment shaders: the solid's colour at an object-space point, the cap's colour
// at a point of the plane, and the shading.
const FS_COMMON = `#version 300 es
precision highp float; precision highp sampler3D;
uniform sampler3D vol; uniform sampler2D cutTex;
uniform mat3 rot; uniform bool clip; uniform bool haveCut;
uniform vec3 pn; uniform float pd;
uniform vec3 cutO, cutU, cutV; uniform float cutSize, volN;
out vec4 color;
float plane(vec3 p) { return clip ? dot(p, pn) - pd : -1e9; }
vec3 voxelAt(vec3 p) { return (clamp(p, -1.0, 0.9999) + 1.0) * 0.5 * volN; }
vec3 solidAt(vec3 p) { return texture(vol, voxelAt(p) / volN).rgb; }
vec3 capAt(vec3 p) {
  if (!haveCut) return solidAt(p);
  vec3 r = voxelAt(p) - cutO;
  vec2 ij = vec2(dot(r, cutU), dot(r, cutV)) + 0.5 * cutSize;
  return texture(cutTex, ij / cutSize).rgb;
}
vec4 shade(vec3 albedo, vec3 nrm, vec3 rd) {
  vec3 l = normalize(rot * vec3(0.4, 0.7, 0.6));
  float diffuse = max(dot(nrm, l), 0.0), fill = max(dot(nrm, -rd), 0.0);
  return vec4(albedo * (0.35 + 0.45 * diffuse + 0.3 * fill), 1.0);
}
`;

// The sphere, ray-marched on a full-screen triangle.
const FS = FS_COMMON + `
in vec2 q;
float sdf(vec3 p) { return max(length(p) - 0.85, plane(p)); }
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
  bool cap = clip && abs(plane(p)) < 2e-3;
  color = cap ? shade(capAt(p), pn, rd) : shade(solidAt(p), normalAt(p), rd);
}`;

// The mesh: object-space positions and vertex normals in, projected by mvp.
const MESH_VS = `#version 300 es
in vec3 pos; in vec3 nrm; uniform mat4 mvp; uniform float scale;
out vec3 P; out vec3 N;
void main() { P = pos * scale; N = nrm; gl_Position = mvp * vec4(P, 1.0); }`;

// Fragments on the removed side are discarded. A view ray that crosses the plane inside the
// (closed) mesh has its entry (a front face) on the removed side, discarded, so the nearest
// fragment left is the back face where it leaves the mesh: that fragment is drawn as the cap, with
// the colour of the point where the ray meets the plane. It keeps its own depth: nothing lies
// between that point and the exit along the ray, and a ray that crosses the plane outside the mesh
// reaches a kept front face first, which hides the back faces behind it.
const MESH_FS = FS_COMMON + `
in vec3 P; in vec3 N;
uniform vec3 eye;
void main() {
  if (plane(P) > 0.0) discard;
  vec3 rd = normalize(P - eye);
  if (gl_FrontFacing) { color = shade(solidAt(P), normalize(N), rd); return; }
  float den = dot(rd, pn), t = (pd - dot(eye, pn)) / den;
  if (clip && abs(den) > 1e-6 && t > 0.0 && t < length(P - eye)) {
    color = shade(capAt(eye + t * rd), pn, rd);
  } else {
    // The inside, seen through a hole in the mesh (this bunny is closed: kept for other meshes).
    color = shade(solidAt(P), -normalize(N), rd) * vec4(vec3(0.6), 1.0);
  }
}`;

// The bunny is scaled so its longest side (left to right) spans 1.7, the sphere's diameter.
const MESH_SCALE = 1.7;
const UNIFORMS = ["vol", "cutTex", "rot", "clip", "haveCut", "pn", "pd", "cutO", "cutU", "cutV", "cutSize", "volN"];
const gl3 = { gl: null, sphere: null, mesh: null, bunny: null, volTex: null, cutTex: null, haveCut: false, frames: 0 };

function program(gl, vs, fs, extra) {
  const compile = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, compile(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  const loc = {};
  for (const u of UNIFORMS.concat(extra)) loc[u] = gl.getUniformLocation(prog, u);
  gl.useProgram(prog);
  gl.uniform1i(loc.vol, 0);
  gl.uniform1i(loc.cutTex, 1);
  return { prog, loc, vao: gl.createVertexArray() };
}

function initGL() {
  const canvas = $("view3d");
  // preserveDrawingBuffer: the frame stays readable (tests read it back) between redraws.
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, depth: true });
  if (!gl) { $("view-status").textContent = "WebGL2 is not available in this browser"; return; }
  const sphere = program(gl, VS, FS, []);
  gl.bindVertexArray(sphere.vao);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const at = gl.getAttribLocation(sphere.prog, "p");
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 2, gl.FLOAT, false, 0, 0);
  gl.bindVertexArray(null);
  gl3.sphere = sphere;
  gl3.mesh = program(gl, MESH_VS, MESH_FS, ["mvp", "scale", "eye"]);
  gl3.gl = gl;
  gl3.volTex = gl.createTexture();
  gl3.cutTex = gl.createTexture();
}

// /bunny.bin: u32 vertex count V, u32 triangle count T, V x 3 f32 positions, T x 3 u16 indices.
async function loadBunny() {
  const buf = await (await api("/bunny.bin")).arrayBuffer();
  const [nv, nt] = new Uint32Array(buf, 0, 2);
  const pos = new Float32Array(buf, 8, 3 * nv);
  const idx = new Uint16Array(buf, 8 + 12 * nv, 3 * nt);
  // Vertex normals: the area-weighted sum of the adjacent faces' normals.
  const nrm = new Float32Array(3 * nv);
  for (let t = 0; t < nt; t++) {
    const [a, b, c] = [idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]];
    const e1 = [0, 1, 2].map((k) => pos[3 * b + k] - pos[3 * a + k]);
    const e2 = [0, 1, 2].map((k) => pos[3 * c + k] - pos[3 * a + k]);
    const f = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    for (const v of [a, b, c]) for (let k = 0; k < 3; k++) nrm[3 * v + k] += f[k];
  }
  for (let v = 0; v < nv; v++) {
    const l = Math.hypot(nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]) || 1;
    for (let k = 0; k < 3; k++) nrm[3 * v + k] /= l;
  }
  const gl = gl3.gl;
  if (!gl) return;
  const m = gl3.mesh;
  gl.bindVertexArray(m.vao);
  for (const [name, data] of [["pos", pos], ["nrm", nrm]]) {
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    const at = gl.getAttribLocation(m.prog, name);
    gl.enableVertexAttribArray(at);
    gl.vertexAttribPointer(at, 3, gl.FLOAT, false, 0, 0);
  }
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  gl3.bunny = { vertices: nv, triangles: nt };
  drawView();
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

// Object space to clip space (column-major) for the mesh, the camera the sphere's rays use: the
// eye at rot * (0, 0, 3.2) looking along rot * (0, 0, -1), image plane at focal length 2.2.
function meshMatrix(R) {
  const near = 0.5, far = 6.0, A = -(far + near) / (far - near), B = -2 * far * near / (far - near);
  // Camera coordinates: c = R^T p - (0, 0, 3.2); row i of R^T is column i of R.
  const viewRows = [0, 1, 2].map((i) => [R[3 * i], R[3 * i + 1], R[3 * i + 2], i === 2 ? -3.2 : 0]);
  viewRows.push([0, 0, 0, 1]);
  const proj = [[2.2, 0, 0, 0], [0, 2.2, 0, 0], [0, 0, A, B], [0, 0, -1, 0]];
  const m = new Float32Array(16);
  for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += proj[r][k] * viewRows[k][c];
    m[c * 4 + r] = s;
  }
  return m;
}

let drawQueued = false;
function drawView() {
  if (!gl3.gl || drawQueued) return;
  drawQueued = true;
  requestAnimationFrame(() => {
    drawQueued = false;
    const gl = gl3.gl;
    const bunny = $("shape").value === "1";
    const p = bunny ? gl3.mesh : gl3.sphere, L = p.loc;
    gl.useProgram(p.prog);
    gl.viewport(0, 0, gl.canvas.width, gl.canvas.height);
    const R = rotation();
    gl.uniformMatrix3fv(L.rot, false, R);
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
    if (bunny) {
      gl.clearColor(0.07, 0.07, 0.08, 1.0);
      gl.clearDepth(1.0);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      if (gl3.bunny) {
        gl.enable(gl.DEPTH_TEST);
        gl.depthFunc(gl.LESS);
        gl.disable(gl.CULL_FACE); // back faces are the cap
        gl.uniformMatrix4fv(L.mvp, false, meshMatrix(R));
        gl.uniform1f(L.scale, MESH_SCALE);
        gl.uniform3fv(L.eye, [3.2 * R[6], 3.2 * R[7], 3.2 * R[8]]);
        gl.bindVertexArray(p.vao);
        gl.drawElements(gl.TRIANGLES, 3 * gl3.bunny.triangles, gl.UNSIGNED_SHORT, 0);
      }
    } else {
      gl.disable(gl.DEPTH_TEST);
      gl.bindVertexArray(p.vao);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
    gl.bindVertexArray(null);
    gl3.frames += 1;
    gl.canvas.dataset.shape = bunny && gl3.bunny ? "bunny" : bunny ? "loading" : "sphere";
    gl.canvas.dataset.frames = String(gl3.frames);
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
loadBunny().catch((e) => { $("view-status").textContent = "bunny mesh: " + e.message; });
updateDownloads();
for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}-v`).textContent = $(`cut-${k}`).value;
init().catch((e) => setStatus(e.message, true));
