// solidsynth viewer, part 4 of 4 (see viewer.js): meshes and surface bakes for the object view.
// A mesh (the bunny or an upload, POST /api/meshes) is shown at once from its geometry
// (/api/meshes/ID/geometry), textured by the preview volume. A bake (POST
// /api/solids/ID/surface) runs as a job; when it is done the page fetches the textured model
// (/api/surfaces/S.glb), parses the binary glTF itself and swaps it in. The bake places the
// mesh's box with its longest side spanning `resolution` voxels from voxel 0, so the baked
// surface shows the solid at a much finer scale than the preview. The cap of a cut baked model
// shows the free cut (the preview's scale) or, when asked for, a cut at the bake's scale (in
// tiles: a cut spans at most 512 voxels; slow, as its pixels lie voxels apart).
"use strict";

const meshes = {
  list: [],            // /api/meshes
  geometry: new Map(), // mesh id -> its model (preview-textured)
  bake: null,          // the bake the page follows: {job, t0 (click time, or null)}
};

const UPLOAD_TYPES = {
  obj: "model/obj", ply: "model/ply", glb: "model/gltf-binary", gltf: "model/gltf+json",
};

async function loadMeshList() {
  try {
    meshes.list = await (await api("/api/meshes")).json();
  } catch (e) {
    say("meshes: " + e.message, true);
    return;
  }
  const select = $("shape"), shown = select.value;
  const options = [new Option("sphere", "sphere")];
  for (const m of meshes.list) {
    const label = m.id === "bunny" ? "bunny" : `${m.name} (upload ${m.id})`;
    options.push(new Option(label, m.id));
  }
  select.replaceChildren(...options);
  select.value = options.some((o) => o.value === shown) ? shown : "sphere";
}

// ---- geometry: u32 V, u32 T (little endian), V x 3 f32 positions, T x 3 u32 indices ----

async function loadGeometry(id) {
  if (meshes.geometry.has(id)) return meshes.geometry.get(id);
  const buf = await (await api(`/api/meshes/${encodeURIComponent(id)}/geometry`)).arrayBuffer();
  const [nv, nt] = new Uint32Array(buf, 0, 2);
  if (buf.byteLength !== 8 + 12 * nv + 12 * nt) throw new Error(`mesh ${id}: the geometry has ${buf.byteLength} bytes`);
  const positions = new Float32Array(buf, 8, 3 * nv);
  const indices = new Uint32Array(buf, 8 + 12 * nv, 3 * nt);
  const model = createModel({ positions, normals: vertexNormals(positions, indices), uvs: null, indices, ...bounds(positions) });
  meshes.geometry.set(id, model);
  return model;
}

// Vertex normals: the area-weighted sum of the adjacent faces' normals.
function vertexNormals(pos, idx) {
  const nrm = new Float32Array(pos.length);
  for (let t = 0; t < idx.length; t += 3) {
    const [a, b, c] = [idx[t], idx[t + 1], idx[t + 2]];
    const e1 = [0, 1, 2].map((k) => pos[3 * b + k] - pos[3 * a + k]);
    const e2 = [0, 1, 2].map((k) => pos[3 * c + k] - pos[3 * a + k]);
    const f = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    for (const v of [a, b, c]) for (let k = 0; k < 3; k++) nrm[3 * v + k] += f[k];
  }
  for (let v = 0; v < nrm.length; v += 3) {
    const l = Math.hypot(nrm[v], nrm[v + 1], nrm[v + 2]) || 1;
    for (let k = 0; k < 3; k++) nrm[v + k] /= l;
  }
  return nrm;
}

function bounds(pos) {
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < pos.length; i++) {
    lo[i % 3] = Math.min(lo[i % 3], pos[i]);
    hi[i % 3] = Math.max(hi[i % 3], pos[i]);
  }
  return { lo, hi };
}

// The shape select changed (or a solid did): show the shape's geometry, preview-textured.
async function shapeChanged() {
  const id = $("shape").value;
  surfaceContextChanged();
  if (id === "sphere") { objectView.geometry = null; drawView(); return; }
  objectView.geometry = null;
  drawView();
  try {
    const model = await loadGeometry(id);
    if ($("shape").value === id) objectView.geometry = model;
  } catch (e) {
    say(`mesh ${id}: ${e.message}`, true);
  }
  drawView();
}

// ---- uploads ----

async function uploadMesh(file) {
  const ext = (file.name.split(".").pop() || "").toLowerCase();
  if (!UPLOAD_TYPES[ext]) {
    say(`${file.name}: choose an .obj, .ply, .glb or .gltf file`, true);
    return;
  }
  say(`uploading ${file.name} (${file.size} bytes)`);
  try {
    const name = file.name.slice(0, 128);
    const r = await api(`/api/meshes?format=${ext}&name=${encodeURIComponent(name)}`, {
      method: "POST", body: file, headers: { "Content-Type": UPLOAD_TYPES[ext] },
    });
    const mesh = await r.json();
    await loadMeshList();
    $("shape").value = mesh.id;
    await shapeChanged();
    say(`mesh ${mesh.id} (${mesh.name}): ${mesh.vertices} vertices, ${mesh.triangles} triangles; bake to texture it at a finer scale`);
  } catch (e) {
    say(`${file.name}: ${e.message}`, true);
    $("view-status").textContent = `upload refused: ${e.message}`;
    $("view-status").className = "error";
  }
}

// ---- bakes ----

async function startBake() {
  const mesh = $("shape").value;
  if (mesh === "sphere") { say("bake onto a mesh: choose the bunny or upload one", true); return; }
  if (!view.solid) { say("no solid to bake yet", true); return; }
  const t0 = performance.now(), solid = view.solid.id;
  const resolution = $("bake-resolution").value, fast = $("bake-fast").checked ? 1 : 0;
  try {
    const r = await api(`/api/solids/${solid}/surface?mesh=${encodeURIComponent(mesh)}&resolution=${resolution}&fast=${fast}`,
      { method: "POST" });
    const job = await r.json();
    say(`started job ${job.id}: ${job.name}`);
    followBake(job, { t0, solid, mesh });
  } catch (e) {
    bakeStatus(`bake: ${e.message}`, true);
  }
}

function bakeStatus(text, error) {
  $("bake-status").textContent = text;
  $("bake-status").className = error ? "error" : "muted";
  if (error) say(text, true);
}

// Follow bake job `job`. started: {t0 (when its Bake button was clicked), solid, mesh} for a bake
// this page started, null for one found running after a reload.
function followBake(job, started) {
  meshes.bake = { job: job.id };
  $("bake-cancel").disabled = false;
  document.body.dataset.bake = "running";
  follow(job.id, {
    update(j) {
      $("bake-progress").value = j.progress;
      bakeStatus(`${j.name}: ${j.stage} (${percent(j)}, ${j.seconds.toFixed(1)} s)`);
    },
    async end(j) {
      if (meshes.bake && meshes.bake.job === j.id) $("bake-cancel").disabled = true;
      $("bake-progress").value = j.state === "done" ? 1 : 0;
      document.body.dataset.bake = j.state;
      if (j.state === "cancelled") { bakeStatus(`${j.name}: cancelled after ${j.seconds.toFixed(1)} s`); return; }
      if (j.state === "failed") { bakeStatus(`${j.name}: failed: ${j.error}`, true); return; }
      // Swapped in while the view still shows what was baked; else it waits in the job list.
      if (started && (!view.solid || view.solid.id !== started.solid || $("shape").value !== started.mesh)) {
        bakeStatus(`${j.name}: baked in ${j.seconds.toFixed(1)} s; the view has moved on: "show" it from the job list`);
        return;
      }
      bakeStatus(`${j.name}: baked in ${j.seconds.toFixed(1)} s; fetching the model`);
      await showSurfaceById(j.surface, started && { t0: started.t0, bakeSeconds: j.seconds, name: j.name });
    },
  });
}

// Show baked surface `id` (its solid and mesh too); timing: {t0, bakeSeconds, name} of a bake
// the page started, to report how long the click took to reach the screen.
async function showSurfaceById(id, timing) {
  try {
    const info = await (await api(`/api/surfaces/${id}`)).json();
    if (!view.solid || view.solid.id !== info.solid) {
      const solid = view.solids.find((s) => s.id === info.solid) || await (await api(`/api/solids/${info.solid}`)).json();
      await loadSolid(solid);
    }
    if ($("shape").value !== info.mesh) {
      if (![...$("shape").options].some((o) => o.value === info.mesh)) $("shape").add(new Option(`mesh ${info.mesh}`, info.mesh));
      $("shape").value = info.mesh;
      shapeChanged();  // the preview geometry meanwhile (not awaited: the .glb replaces it)
    }
    const t1 = performance.now();
    const bytes = await (await api(info.glb)).arrayBuffer();
    const glb = await parseGlb(bytes);
    const max = gl3.gl ? gl3.gl.getParameter(gl3.gl.MAX_TEXTURE_SIZE) : 0;
    if (Math.max(glb.bitmap.width, glb.bitmap.height) > max) {
      throw new Error(`its ${glb.bitmap.width}x${glb.bitmap.height} texture is larger than this browser's WebGL allows (${max}): bake at a lower resolution`);
    }
    const model = createModel({ ...glb, texture: texture2D(glb.bitmap, glb.filter) });
    glb.bitmap.close();
    model.info = info;
    model.timing = timing && { ...timing, fetchMs: performance.now() - t1, bytes: bytes.byteLength };
    if (view.solid.id !== info.solid || $("shape").value !== info.mesh) { deleteModel(model); return; }
    deleteModel(objectView.baked);
    objectView.baked = model;
    showTextureLabel();
    showGlbDownload(info);
    planeChanged();
    drawView();
  } catch (e) {
    bakeStatus(`surface ${id}: ${e.message}`, true);
  }
}

// Called by the view once a baked model has been drawn: how long from the click to the screen.
function bakedOnScreen(model) {
  const t = model.timing;
  say(`showing surface ${model.info.id}: solid ${model.info.solid} baked onto ${model.info.mesh} at ${model.info.resolution}`);
  if (!t) return;
  const ms = model.drawnAt - t.t0;
  $("view3d").dataset.bakeMs = ms.toFixed(0);
  bakeStatus(`${t.name}: on screen ${(ms / 1000).toFixed(1)} s after the click ` +
    `(bake ${t.bakeSeconds.toFixed(1)} s; ${(t.bytes / 1e6).toFixed(1)} MB .glb fetched and decoded in ${t.fetchMs.toFixed(0)} ms)`);
}

function showTextureLabel() {
  const b = objectView.baked, label = $("texture-label");
  if (!b) {
    label.textContent = `texture: the preview volume (${view.n || 64}³ voxels stretched over the mesh's box)`;
    label.className = "label";
    return;
  }
  const i = b.info;
  label.textContent = `texture: baked at ${i.resolution} voxels across (atlas ${i.atlas[0]}x${i.atlas[1]}; ` +
    `the cut face at ${$("cap-baked").checked ? "the bake's scale" : "the preview's"})` +
    (i.fast ? " · FAST bake: a slightly different solid (fewer correction passes, coarse cache)" : "");
  label.className = i.fast ? "label baked fast" : "label baked";
}

function showGlbDownload(info) {
  const a = $("dl-glb");
  a.href = info.glb;
  a.download = `solid-${info.solid}-${info.mesh}-${info.resolution}${info.fast ? "-fast" : ""}.glb`;
  a.setAttribute("aria-disabled", "false");
  $("dl-glb-what").textContent = `surface ${info.id}: solid ${info.solid} on ${info.mesh} at ${info.resolution}` +
    `${info.fast ? " (fast: a slightly different solid)" : ""}, ${(info.bytes / 1e6).toFixed(1)} MB`;
}

// The baked model belongs to one solid and one mesh: shown only while both are.
function surfaceContextChanged() {
  const b = objectView.baked;
  if (b && (!view.solid || b.info.solid !== view.solid.id || b.info.mesh !== $("shape").value)) {
    deleteModel(b);
    objectView.baked = null;
    planeChanged();
    drawView();
  }
  showTextureLabel();
}

// ---- the .glb: a 12-byte header, a JSON chunk, a BIN chunk ----

async function parseGlb(buf) {
  const dv = new DataView(buf);
  if (buf.byteLength < 20 || dv.getUint32(0, true) !== 0x46546c67) throw new Error("not a binary glTF file");
  if (dv.getUint32(4, true) !== 2) throw new Error(`glTF version ${dv.getUint32(4, true)}, not 2`);
  const length = Math.min(dv.getUint32(8, true), buf.byteLength);
  let json = null, bin = null;
  for (let at = 12; at + 8 <= length;) {
    const size = dv.getUint32(at, true), type = dv.getUint32(at + 4, true);
    if (type === 0x4e4f534a) json = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, at + 8, size)));
    else if (type === 0x004e4942) bin = { offset: at + 8, size };
    at += 8 + size;
  }
  if (!json || !bin) throw new Error("the .glb lacks its JSON or BIN chunk");
  const prim = json.meshes[0].primitives[0];
  if ((prim.mode ?? 4) !== 4) throw new Error("the .glb's primitive is not triangles");
  // A view's bytes (copied: typed arrays need aligned offsets); interleaved views de-interleaved.
  const viewBytes = (index) => {
    const v = json.bufferViews[index];
    return { start: bin.offset + (v.byteOffset || 0), length: v.byteLength, stride: v.byteStride || 0 };
  };
  const TYPES = { 5126: Float32Array, 5125: Uint32Array, 5123: Uint16Array, 5121: Uint8Array };
  const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };
  const accessor = (index) => {
    const a = json.accessors[index], Type = TYPES[a.componentType], n = COMPONENTS[a.type];
    if (!Type || !n) throw new Error(`accessor ${index}: unsupported type`);
    const v = viewBytes(a.bufferView), item = n * Type.BYTES_PER_ELEMENT;
    const start = v.start + (a.byteOffset || 0), stride = v.stride || item;
    let out;
    if (stride === item) {
      out = new Type(buf.slice(start, start + a.count * item));
    } else {
      out = new Type(a.count * n);
      for (let i = 0; i < a.count; i++) out.set(new Type(buf.slice(start + i * stride, start + i * stride + item)), i * n);
    }
    return { data: out, min: a.min, max: a.max };
  };
  const positions = accessor(prim.attributes.POSITION);
  const normals = prim.attributes.NORMAL !== undefined ? accessor(prim.attributes.NORMAL).data : null;
  const uvs = prim.attributes.TEXCOORD_0 !== undefined ? accessor(prim.attributes.TEXCOORD_0).data : null;
  let indices = accessor(prim.indices).data;
  if (indices instanceof Uint8Array) indices = Uint16Array.from(indices);
  const material = json.materials[prim.material];
  const textureIndex = material.pbrMetallicRoughness.baseColorTexture.index;
  const tex = json.textures[textureIndex], image = json.images[tex.source];
  const iv = viewBytes(image.bufferView);
  const bitmap = await createImageBitmap(new Blob([new Uint8Array(buf, iv.start, iv.length)], { type: image.mimeType || "image/png" }),
    { premultiplyAlpha: "none", colorSpaceConversion: "none" });
  // The file's own sampler (the baked atlas asks for linear filtering, no mipmaps).
  const sampler = tex.sampler !== undefined ? json.samplers[tex.sampler] : {};
  const filter = sampler.minFilter === 9728 ? WebGL2RenderingContext.NEAREST : WebGL2RenderingContext.LINEAR;
  const box = positions.min && positions.max ? { lo: positions.min, hi: positions.max } : bounds(positions.data);
  return {
    positions: positions.data, normals: normals || vertexNormals(positions.data, indices), uvs, indices,
    ...box, bitmap, filter,
  };
}

// ---- the baked model's cap at the bake's scale (on request): the free plane cut from the solid ----

const CAP_TILE = 128;
const capTiles = {
  cap: null,     // what the shader samples: {key, texture, origin, u, v, size, voxScale, voxOffset}
  want: null,    // the plan to fetch next
  gen: 0,        // counts changes of plan: tiles of an older one are not fetched
  running: false,
  texture: null, // reused while its size stays
  textureSize: 0,
};

// Where the free plane meets the baked mesh's box, in the bake's voxels, as a k x k grid of
// square tiles of CAP_TILE pixels each spanning at most a cut's 512 voxels; null when the plane
// misses the box or there is no cut at the bake's scale to show.
function capPlan() {
  const b = objectView.baked;
  if (!b || !$("clip").checked || !$("cap-baked").checked || !view.solid) return null;
  const plane = objectPlane(), res = b.info.resolution;
  // Object space -> the bake's voxels: the mesh's box corner `lo` is voxel 0 and its longest
  // side spans `res` voxels (object space has it MESH_SCALE long, centred).
  const voxScale = res / MESH_SCALE;
  const voxOffset = b.centre.map((c, i) => (c - b.lo[i]) * res / b.extent);
  const radius = 0.5 * MESH_SCALE * Math.hypot(...b.hi.map((h, i) => h - b.lo[i])) / b.extent;
  if (Math.abs(plane.d) >= radius) return null;
  const span = 2 * Math.sqrt(radius * radius - plane.d * plane.d) * voxScale + 2;
  const k = Math.ceil(span / maxCutSpan());
  const spacing = Math.max(1 / 64, span / (k * CAP_TILE));
  const n = plane.n, up = Math.abs(n[1]) > 0.9 ? [0, 0, 1] : [0, 1, 0];
  // The server's frame for (n, up): v = up without its normal part, u = v x n.
  const un = up.reduce((s, x, i) => s + x * n[i], 0);
  let v = up.map((x, i) => x - un * n[i]);
  const lv = Math.hypot(...v);
  v = v.map((x) => x / lv);
  const u = [v[1] * n[2] - v[2] * n[1], v[2] * n[0] - v[0] * n[2], v[0] * n[1] - v[1] * n[0]];
  const origin = n.map((x, i) => x * plane.d * voxScale + voxOffset[i]);
  const size = k * CAP_TILE, tiles = [];
  for (let a = 0; a < k; a++) for (let c = 0; c < k; c++) {
    const du = ((a + 0.5) * CAP_TILE - size / 2) * spacing, dv = ((c + 0.5) * CAP_TILE - size / 2) * spacing;
    tiles.push({ x: a * CAP_TILE, y: c * CAP_TILE, d: Math.hypot(du, dv),
      spec: { solid: view.solid.id, origin: origin.map((o, i) => o + du * u[i] + dv * v[i]), normal: n, up,
        size: CAP_TILE, spacing } });
  }
  tiles.sort((p, q) => p.d - q.d); // the middle first
  const key = JSON.stringify([b.info.id, n, plane.d]);
  return { key, tiles, origin, u: u.map((x) => x / spacing), v: v.map((x) => x / spacing), size, voxScale, voxOffset };
}

// The free plane moved (or the baked model or the clip changed): cut the cap again.
function planeChanged() {
  const plan = capPlan();
  const key = plan && plan.key;
  if (key && ((capTiles.cap && capTiles.cap.key === key) || (capTiles.want && capTiles.want.key === key))) return;
  capTiles.gen += 1;
  capTiles.want = plan;
  if (!plan) capTiles.cap = null;
  if (plan) fetchCapTiles();
}

// Fetches the wanted plan's tiles one at a time into one texture (alpha 0 until a tile
// arrives: the shader shows the preview there meanwhile); a newer plan stops the older one.
async function fetchCapTiles() {
  if (capTiles.running) return;
  capTiles.running = true;
  const gl = gl3.gl;
  while (capTiles.want && gl) {
    const plan = capTiles.want, gen = capTiles.gen;
    capTiles.want = null;
    if (capTiles.textureSize !== plan.size) {
      if (capTiles.texture) gl.deleteTexture(capTiles.texture);
      capTiles.texture = gl.createTexture();
      capTiles.textureSize = plan.size;
    }
    gl.bindTexture(gl.TEXTURE_2D, capTiles.texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, plan.size, plan.size, 0, gl.RGBA, gl.UNSIGNED_BYTE, null);
    setFilters(gl, gl.TEXTURE_2D, gl.NEAREST, gl.CLAMP_TO_EDGE);
    capTiles.cap = { ...plan, texture: capTiles.texture };
    for (const tile of plan.tiles) {
      if (capTiles.gen !== gen) break;
      try {
        const bitmap = await createImageBitmap(await (await api(cutUrl(tile.spec))).blob());
        if (capTiles.gen !== gen) { bitmap.close(); break; }
        gl.bindTexture(gl.TEXTURE_2D, capTiles.texture);
        gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
        gl.texSubImage2D(gl.TEXTURE_2D, 0, tile.x, tile.y, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
        bitmap.close();
        drawView();
      } catch (e) {
        say("the baked model's cap: " + e.message, true);
        break;
      }
    }
  }
  capTiles.running = false;
}

// The cap's uniforms for the view, while they are of the current plane.
function bakedCap() {
  const c = capTiles.cap, plan = c ? capPlan() : null;
  return c && plan && c.key === plan.key ? c : null;
}

function wireMeshes() {
  $("shape").addEventListener("change", shapeChanged);
  $("bake").addEventListener("click", startBake);
  $("bake-cancel").addEventListener("click", () => { if (meshes.bake) cancelJob(meshes.bake.job); });
  $("cap-baked").addEventListener("change", showTextureLabel);
  $("mesh-file").addEventListener("change", () => {
    const f = $("mesh-file").files[0];
    if (f) uploadMesh(f);
  });
}
