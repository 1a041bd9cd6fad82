// solidsynth viewer, part 3 of 4 (see viewer.js): the object view, WebGL2, textured by the solid.
// Shapes: a sphere (ray-marched, an exact implicit surface) and triangle meshes (the bunny and
// uploads, from /api/meshes/ID/geometry; a baked surface, from its .glb). All live in the same
// object space, where [-1, 1]^3 is the preview box [0, n)^3 of the solid (voxel = (p + 1) n / 2),
// seen by the same orbiting camera (eye at target + rot * (0, 0, dist), focal length 2.2), and
// are clipped and capped the same way: the free plane removes the side p . pn > pd; where it cuts
// the shape, the cap shows a server cut at that point (the free cut; for a baked model, on request,
// one at the bake's scale). A mesh is textured either by the preview
// volume (a 3D texture stretched over the mesh's box: immediate) or, once baked, by the baked
// texture atlas of its .glb (the solid at the bake's much finer scale).
"use strict";

const VS = `#version 300 es
in vec2 p; out vec2 q;
void main() { q = p; gl_Position = vec4(p, 0.0, 1.0); }`;

// Shared by both fragment shaders: the solid's colour at an object-space point (the preview
// volume), the cap's colour at a point of the plane, and the shading. The cap is a server cut
// centred at capO (voxels) with axes capU, capV (scaled to pixels per voxel) and capSize pixels a
// side; an object-space point is at voxel p * voxScale + voxOffset of it (the preview's scale or
// the bake's). Where the cut has no pixel (outside it, or a tile not yet arrived: alpha 0) the
// preview volume stands in.
const FS_COMMON = `#version 300 es
precision highp float; precision highp sampler3D;
uniform sampler3D vol; uniform sampler2D capTex;
uniform mat3 rot; uniform bool clip; uniform bool haveCap;
uniform vec3 pn; uniform float pd;
uniform vec3 capO, capU, capV, voxOffset; uniform float capSize, voxScale, volN;
out vec4 color;
float plane(vec3 p) { return clip ? dot(p, pn) - pd : -1e9; }
vec3 solidAt(vec3 p) { return texture(vol, (clamp(p, -1.0, 0.9999) + 1.0) * 0.5).rgb; }
vec3 capAt(vec3 p) {
  if (!haveCap) return solidAt(p);
  vec3 r = p * voxScale + voxOffset - capO;
  vec2 st = (vec2(dot(r, capU), dot(r, capV)) + 0.5 * capSize) / capSize;
  if (any(lessThan(st, vec2(0.0))) || any(greaterThan(st, vec2(1.0)))) return solidAt(p);
  vec4 c = texture(capTex, st);
  return c.a < 0.5 ? solidAt(p) : c.rgb;
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
uniform vec3 target; uniform float dist;
float sdf(vec3 p) { return max(length(p) - 0.85, plane(p)); }
vec3 normalAt(vec3 p) {
  vec2 h = vec2(1e-3, 0.0);
  return normalize(vec3(sdf(p + h.xyy) - sdf(p - h.xyy), sdf(p + h.yxy) - sdf(p - h.yxy), sdf(p + h.yyx) - sdf(p - h.yyx)));
}
void main() {
  vec3 ro = target + rot * vec3(0.0, 0.0, dist), rd = rot * normalize(vec3(q, -2.2));
  float t = 0.0; bool hit = false; vec3 p;
  for (int i = 0; i < 160; i++) {
    p = ro + t * rd;
    float d = sdf(p);
    if (d < 1e-3) { hit = true; break; }
    t += d;
    if (t > dist + length(target) + 2.0) break;
  }
  if (!hit) { color = vec4(0.07, 0.07, 0.08, 1.0); return; }
  bool cap = clip && abs(plane(p)) < 2e-3;
  color = cap ? shade(capAt(p), pn, rd) : shade(solidAt(p), normalAt(p), rd);
}`;

// A mesh: its own coordinates in, placed in object space by (pos - meshCentre) * meshScale
// (the mesh's box centred, its longest side 1.7 long), projected by mvp.
const MESH_VS = `#version 300 es
layout(location = 0) in vec3 pos; layout(location = 1) in vec3 nrm; layout(location = 2) in vec2 uv;
uniform mat4 mvp; uniform vec3 meshCentre; uniform float meshScale;
out vec3 P; out vec3 N; out vec2 UV;
void main() { P = (pos - meshCentre) * meshScale; N = nrm; UV = uv; gl_Position = mvp * vec4(P, 1.0); }`;

// Fragments on the removed side are discarded. A view ray that crosses the plane inside the
// (closed) mesh has its entry (a front face) on the removed side, discarded, so the nearest
// fragment left is the back face where it leaves the mesh: that fragment is drawn as the cap, with
// the colour of the point where the ray meets the plane. It keeps its own depth: nothing lies
// between that point and the exit along the ray, and a ray that crosses the plane outside the mesh
// reaches a kept front face first, which hides the back faces behind it.
const MESH_FS = FS_COMMON + `
in vec3 P; in vec3 N; in vec2 UV;
uniform vec3 eye; uniform bool baked; uniform sampler2D bakedTex;
vec3 albedo() { return baked ? texture(bakedTex, UV).rgb : solidAt(P); }
void main() {
  if (plane(P) > 0.0) discard;
  vec3 rd = normalize(P - eye);
  if (gl_FrontFacing) { color = shade(albedo(), normalize(N), rd); return; }
  float den = dot(rd, pn), t = (pd - dot(eye, pn)) / den;
  if (clip && abs(den) > 1e-6 && t > 0.0 && t < length(P - eye)) {
    color = shade(capAt(eye + t * rd), pn, rd);
  } else {
    // The inside, seen through a hole in the mesh (an open upload).
    color = shade(albedo(), -normalize(N), rd) * vec4(vec3(0.6), 1.0);
  }
}`;

// A mesh's longest side spans 1.7 in object space, the sphere's diameter.
const MESH_SCALE = 1.7;
const UNIFORMS = ["vol", "capTex", "rot", "clip", "haveCap", "pn", "pd", "capO", "capU", "capV",
  "capSize", "voxScale", "voxOffset", "volN"];
const gl3 = { gl: null, sphere: null, mesh: null, volTex: null, cutTex: null, haveCut: false, frames: 0 };
// What the view shows besides the sphere: the shape's geometry (textured by the preview volume)
// and, once baked, the baked model that replaces it (meshes.js sets both).
const objectView = { geometry: null, baked: null };
const CAMERA_HOME = { yaw: 0.6, pitch: 0.35, dist: 3.2, target: [0, 0, 0] };
const camera = structuredClone(CAMERA_HOME);

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
  gl.uniform1i(loc.capTex, 1);
  if (loc.bakedTex) gl.uniform1i(loc.bakedTex, 2);
  return { prog, loc, vao: gl.createVertexArray() };
}

function initGL() {
  const canvas = $("view3d");
  // preserveDrawingBuffer: the frame stays readable (tests read it back) between redraws.
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, depth: true });
  if (!gl) { $("view-status").textContent = "WebGL2 is not available in this browser"; return; }
  const sphere = program(gl, VS, FS, ["target", "dist"]);
  gl.bindVertexArray(sphere.vao);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const at = gl.getAttribLocation(sphere.prog, "p");
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 2, gl.FLOAT, false, 0, 0);
  gl.bindVertexArray(null);
  gl3.sphere = sphere;
  gl3.mesh = program(gl, MESH_VS, MESH_FS, ["mvp", "meshCentre", "meshScale", "eye", "baked", "bakedTex"]);
  gl3.gl = gl;
  gl3.volTex = gl.createTexture();
  gl3.cutTex = gl.createTexture();
}

function setFilters(gl, target, filter, wrap) {
  gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, filter);
  gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, filter === gl.LINEAR_MIPMAP_LINEAR ? gl.LINEAR : filter);
  for (const k of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T, gl.TEXTURE_WRAP_R]) gl.texParameteri(target, k, wrap);
}

// A triangle mesh on the GPU: {positions, normals, uvs (or null), indices (Uint32Array or
// Uint16Array), lo, hi (its box, in its own coordinates), texture (or null)}. Placed in object
// space by its box: centred, the longest side MESH_SCALE long.
function createModel(m) {
  const gl = gl3.gl;
  if (!gl) return null;
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buffers = [];
  for (const [loc, data, n] of [[0, m.positions, 3], [1, m.normals, 3], [2, m.uvs, 2]]) {
    if (!data) { gl.disableVertexAttribArray(loc); continue; }
    const b = gl.createBuffer();
    buffers.push(b);
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, n, gl.FLOAT, false, 0, 0);
  }
  const ib = gl.createBuffer();
  buffers.push(ib);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, m.indices, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  const extent = Math.max(...m.hi.map((h, i) => h - m.lo[i])) || 1;
  return {
    vao, buffers, texture: m.texture || null,
    count: m.indices.length,
    indexType: m.indices instanceof Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT,
    centre: m.hi.map((h, i) => (h + m.lo[i]) / 2),
    scale: MESH_SCALE / extent,
    lo: m.lo, hi: m.hi, extent,
  };
}

function deleteModel(model) {
  const gl = gl3.gl;
  if (!gl || !model) return;
  gl.deleteVertexArray(model.vao);
  for (const b of model.buffers) gl.deleteBuffer(b);
  if (model.texture) gl.deleteTexture(model.texture);
}

// A 2D RGBA texture from an ImageBitmap (row 0 first: glTF's and the cuts' convention).
function texture2D(bitmap, filter) {
  const gl = gl3.gl;
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
  setFilters(gl, gl.TEXTURE_2D, filter, gl.CLAMP_TO_EDGE);
  return tex;
}

function uploadVolumeTexture() {
  const gl = gl3.gl;
  if (!gl || !view.volume) return;
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_3D, gl3.volTex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage3D(gl.TEXTURE_3D, 0, gl.RGBA8, view.n, view.n, view.n, 0, gl.RGBA, gl.UNSIGNED_BYTE, view.volume);
  // Nearest: a point shows the voxel containing it, as the server's cuts do.
  setFilters(gl, gl.TEXTURE_3D, gl.NEAREST, gl.CLAMP_TO_EDGE);
  drawView();
}

function uploadCutTexture() {
  const gl = gl3.gl;
  if (!gl || !freeCut.cut) return;
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, gl3.cutTex);
  // Row 0 of the cut image is its first row (v = 0): no flip, so t = j / size.
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, freeCut.cut.bitmap);
  setFilters(gl, gl.TEXTURE_2D, gl.NEAREST, gl.CLAMP_TO_EDGE);
  gl3.haveCut = true;
}

// The free plane in object space: p . n = d (the preview box [0, n)^3 is [-1, 1]^3).
function objectPlane() {
  const n = planeNormal(), o = planeOrigin(), N = view.n || 64;
  return { n, d: o.reduce((s, x, i) => s + (x / (N / 2) - 1) * n[i], 0) };
}

// The preview's cap: the free cut, while it shows the current plane.
function previewCap() {
  const c = freeCut.cut, o = planeOrigin(), N = view.n || 64;
  const current = c && view.solid && c.solid === view.solid.id && c.origin.every((x, i) => Math.abs(x - o[i]) < 1e-6);
  if (!gl3.haveCut || !current) return null;
  return { texture: gl3.cutTex, origin: c.origin, u: c.frame.u.map((x) => x / c.spacing),
    v: c.frame.v.map((x) => x / c.spacing), size: c.size, voxScale: N / 2, voxOffset: [N / 2, N / 2, N / 2] };
}

function rotation() {
  const { yaw, pitch } = camera;
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  // Column-major: yaw about y, then pitch about x (camera orbits the object).
  const ry = [cy, 0, -sy, 0, 1, 0, sy, 0, cy];
  const rx = [1, 0, 0, 0, cp, sp, 0, -sp, cp];
  const m = new Array(9).fill(0);
  for (let c = 0; c < 3; c++) for (let r = 0; r < 3; r++) for (let k = 0; k < 3; k++) m[c * 3 + r] += ry[k * 3 + r] * rx[c * 3 + k];
  return m;
}

const eyeOf = (R) => [0, 1, 2].map((i) => camera.target[i] + camera.dist * R[6 + i]);

// Object space to clip space (column-major) for meshes, the camera the sphere's rays use: the
// eye at target + rot * (0, 0, dist) looking along rot * (0, 0, -1), image plane at focal
// length 2.2; near and far planes around everything within 2 of the origin.
function meshMatrix(R) {
  const reach = Math.hypot(...camera.target) + 2;
  const near = Math.max(0.02, camera.dist - reach), far = camera.dist + reach;
  const A = -(far + near) / (far - near), B = -2 * far * near / (far - near);
  // Camera coordinates: c = R^T (p - target) - (0, 0, dist); row i of R^T is column i of R.
  const viewRows = [0, 1, 2].map((i) => {
    const row = [R[3 * i], R[3 * i + 1], R[3 * i + 2]];
    return [...row, -row.reduce((s, x, k) => s + x * camera.target[k], 0) - (i === 2 ? camera.dist : 0)];
  });
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
    const sphere = $("shape").value === "sphere";
    const model = sphere ? null : objectView.baked || objectView.geometry;
    const p = sphere ? gl3.sphere : gl3.mesh, L = p.loc;
    gl.useProgram(p.prog);
    gl.viewport(0, 0, gl.canvas.width, gl.canvas.height);
    const R = rotation();
    gl.uniformMatrix3fv(L.rot, false, R);
    gl.uniform1i(L.clip, $("clip").checked ? 1 : 0);
    const plane = objectPlane();
    gl.uniform3fv(L.pn, plane.n);
    gl.uniform1f(L.pd, plane.d);
    gl.uniform1f(L.volN, view.n || 64);
    const cap = (model && model === objectView.baked && bakedCap()) || previewCap();
    gl.uniform1i(L.haveCap, cap ? 1 : 0);
    if (cap) {
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, cap.texture);
      gl.uniform3fv(L.capO, cap.origin);
      gl.uniform3fv(L.capU, cap.u);
      gl.uniform3fv(L.capV, cap.v);
      gl.uniform1f(L.capSize, cap.size);
      gl.uniform1f(L.voxScale, cap.voxScale);
      gl.uniform3fv(L.voxOffset, cap.voxOffset);
    }
    gl.clearColor(0.07, 0.07, 0.08, 1.0);
    gl.clearDepth(1.0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (sphere) {
      gl.disable(gl.DEPTH_TEST);
      gl.uniform3fv(L.target, camera.target);
      gl.uniform1f(L.dist, camera.dist);
      gl.bindVertexArray(p.vao);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    } else if (model) {
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LESS);
      gl.disable(gl.CULL_FACE); // back faces are the cap
      gl.uniformMatrix4fv(L.mvp, false, meshMatrix(R));
      gl.uniform3fv(L.meshCentre, model.centre);
      gl.uniform1f(L.meshScale, model.scale);
      gl.uniform3fv(L.eye, eyeOf(R));
      gl.uniform1i(L.baked, model.texture ? 1 : 0);
      if (model.texture) {
        gl.activeTexture(gl.TEXTURE2);
        gl.bindTexture(gl.TEXTURE_2D, model.texture);
      }
      gl.bindVertexArray(model.vao);
      gl.drawElements(gl.TRIANGLES, model.count, model.indexType, 0);
    }
    gl.bindVertexArray(null);
    gl.activeTexture(gl.TEXTURE0);
    gl3.frames += 1;
    const c = gl.canvas.dataset;
    c.shape = sphere ? "sphere" : model ? $("shape").value : "loading";
    c.texture = model && model.texture ? "baked" : "preview";
    c.frames = String(gl3.frames);
    c.dist = camera.dist.toFixed(3);
    if (model && model.texture && !model.drawnAt) {
      model.drawnAt = performance.now();
      bakedOnScreen(model);  // meshes.js
    }
  });
}

// ---- camera controls: orbit (drag), pan (shift- or right-drag; two fingers), zoom (wheel; pinch) ----

function orbit(dx, dy) {
  camera.yaw -= dx * 0.01;
  camera.pitch = Math.max(-1.5, Math.min(1.5, camera.pitch + dy * 0.01));
}

// Moves the target so that what is under the pointer follows it (at the target's depth).
function pan(dx, dy) {
  const R = rotation(), k = camera.dist / (2.2 * $("view3d").clientWidth / 2);
  for (let i = 0; i < 3; i++) camera.target[i] += k * (-dx * R[i] + dy * R[3 + i]);
}

function zoom(factor) {
  camera.dist = Math.max(1.1, Math.min(12, camera.dist * factor));
}

function cameraControls(canvas) {
  const pointers = new Map(); // pointer id -> {x, y, pan}
  const pair = () => {
    const [a, b] = [...pointers.values()];
    return { x: (a.x + b.x) / 2, y: (a.y + b.y) / 2, d: Math.hypot(a.x - b.x, a.y - b.y) || 1 };
  };
  canvas.addEventListener("pointerdown", (e) => {
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey });
    try { canvas.setPointerCapture(e.pointerId); } catch (_) { /* a synthetic pointer */ }
    e.preventDefault();
  });
  canvas.addEventListener("pointermove", (e) => {
    const p = pointers.get(e.pointerId);
    if (!p) return;
    if (pointers.size === 1) {
      const dx = e.clientX - p.x, dy = e.clientY - p.y;
      if (p.pan || e.shiftKey) pan(dx, dy); else orbit(dx, dy);
      p.x = e.clientX; p.y = e.clientY;
    } else {
      // Two fingers: their spread zooms, their midpoint pans.
      const before = pair();
      p.x = e.clientX; p.y = e.clientY;
      const after = pair();
      zoom(before.d / after.d);
      pan(after.x - before.x, after.y - before.y);
    }
    drawView();
  });
  for (const end of ["pointerup", "pointercancel"]) canvas.addEventListener(end, (e) => pointers.delete(e.pointerId));
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    zoom(Math.exp(e.deltaY * 0.0015));
    drawView();
  }, { passive: false });
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
}

function wireView() {
  try { initGL(); } catch (e) { $("view-status").textContent = "WebGL error: " + e.message; }
  for (const id of ["clip", "cap-baked"]) $(id).addEventListener("change", () => { drawView(); planeChanged(); });
  $("view-reset").addEventListener("click", () => { Object.assign(camera, structuredClone(CAMERA_HOME)); drawView(); });
  cameraControls($("view3d"));
}
