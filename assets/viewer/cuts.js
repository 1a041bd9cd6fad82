// solidsynth viewer, part 2 of 4 (see viewer.js): the free cut and the three orthogonal slices.
// Every image is a cut synthesized by the server on demand (GET /api/solids/ID/cut), so both can
// go anywhere in the solid's infinite space, not only into the preview box [0, n)^3, and at any
// zoom (voxels per pixel). A slice is an axis-aligned cut. Until its cut arrives, a slice shows
// what the preview volume knows of it (the voxels inside the box).
"use strict";

// Voxels per pixel offered for zooming; a cut may span at most 512 voxels a side.
const SPACINGS = [1 / 8, 1 / 4, 1 / 2, 1, 2, 4];
const spacingLabel = (s) => (s < 1 ? `1/${Math.round(1 / s)}` : String(s));
const fmt = (v, digits = 6) => v.map((x) => x.toFixed(digits)).join(",");
const round1 = (x) => Math.round(x * 10) / 10;
const point = (v) => `(${v.map(round1).join(", ")})`;

function cutUrl(spec) {
  let url = `/api/solids/${spec.solid}/cut?origin=${fmt(spec.origin)}&normal=${fmt(spec.normal)}`;
  if (spec.up) url += `&up=${fmt(spec.up)}`;
  return url + `&size=${spec.size}&spacing=${spec.spacing}`;
}

// One stream of server cuts for one picture: at most one request in flight; whatever changes
// while it is coalesces into one follow-up, asked for the newest spec when the first returns.
class CutStream {
  // specOf(): the spec to ask for now, or null (nothing to show); onCut(result) shows a result;
  // onError(error) says why a request failed.
  constructor(specOf, onCut, onError) {
    this.specOf = specOf;
    this.onCut = onCut;
    this.onError = onError;
    this.busy = false;
    this.again = false;
  }

  get idle() { return !this.busy && !this.again; }

  request() {
    if (this.busy) { this.again = true; return; }
    this.run();
  }

  async run() {
    this.busy = true;
    do {
      this.again = false;
      const spec = this.specOf();
      if (!spec) break;
      const t0 = performance.now();
      try {
        const r = await api(cutUrl(spec));
        const blob = await r.blob();
        const bitmap = await createImageBitmap(blob);
        this.onCut({
          spec, blob, bitmap,
          roundTripMs: performance.now() - t0,
          frame: JSON.parse(r.headers.get("X-Cut-Frame")),
          synthMs: parseFloat(r.headers.get("X-Synthesis-Ms")),
          queueMs: parseFloat(r.headers.get("X-Queue-Ms")),
        });
      } catch (e) {
        this.onError(e);
      }
    } while (this.again);
    this.busy = false;
  }
}

const sameSpec = (a, b) => !!a && !!b && cutUrl(a) === cutUrl(b);
const latencyText = (r) => `${r.spec.size}x${r.spec.size} synthesized in ${r.synthMs.toFixed(1)} ms` +
  ` (queued ${r.queueMs.toFixed(1)} ms), round trip ${r.roundTripMs.toFixed(1)} ms`;

function fillSpacingSelect(select, value) {
  for (const s of SPACINGS) {
    const o = document.createElement("option");
    o.value = String(s);
    o.textContent = spacingLabel(s);
    o.selected = s === value;
    select.appendChild(o);
  }
}

// A zoom step from the wheel: one SPACINGS entry finer (wheel up) or coarser, within `maxSpan`
// voxels a side for an image of `size` pixels.
function zoomSpacing(spacing, deltaY, size, maxSpan) {
  let i = SPACINGS.indexOf(spacing) + (deltaY > 0 ? 1 : -1);
  i = Math.max(0, Math.min(SPACINGS.length - 1, i));
  while (i > 0 && SPACINGS[i] * size > maxSpan) i--;
  return SPACINGS[i];
}

const maxCutSpan = () => (view.limits ? view.limits.max_cut_size : 512);

// Drag on an element: onMove(dx, dy, event) with the pointer's movement in CSS pixels.
function dragger(el, onMove) {
  let last = null;
  el.addEventListener("pointerdown", (e) => {
    last = [e.clientX, e.clientY];
    try { el.setPointerCapture(e.pointerId); } catch (_) { /* a synthetic pointer */ }
    e.preventDefault();
  });
  el.addEventListener("pointermove", (e) => {
    if (!last) return;
    onMove(e.clientX - last[0], e.clientY - last[1], e);
    last = [e.clientX, e.clientY];
  });
  for (const end of ["pointerup", "pointercancel"]) el.addEventListener(end, () => { last = null; });
}

// ---- the free cut ----

const freeCut = {
  cut: null,   // the last cut shown: {origin, frame, size, spacing, bitmap}
  url: null,   // its PNG as an object URL (shown, and the "cut PNG" download)
  count: 0,
  stream: null,
};

function planeNormal() {
  const az = (+$("cut-azimuth").value) * Math.PI / 180;
  const el = (+$("cut-elevation").value) * Math.PI / 180;
  return [Math.cos(el) * Math.cos(az), Math.cos(el) * Math.sin(az), Math.sin(el)];
}

const cutCentre = () => ["cut-cx", "cut-cy", "cut-cz"].map((id) => +$(id).value || 0);

// The plane's origin: the centre moved `offset` voxels along the normal.
function planeOrigin() {
  const n = planeNormal(), off = +$("cut-offset").value, c = cutCentre();
  return c.map((x, i) => x + off * n[i]);
}

function freeCutSpec() {
  if (!view.solid) return null;
  return { solid: view.solid.id, origin: planeOrigin(), normal: planeNormal(), up: null,
    size: +$("cut-size").value, spacing: +$("cut-spacing").value };
}

const inBox = (p) => p.every((x) => x >= 0 && x < (view.n || 64));

function requestCut() {
  for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}-v`).textContent = $(`cut-${k}`).value;
  const spec = freeCutSpec();
  if (spec) {
    const span = spec.size * spec.spacing;
    $("cut-where").textContent = `origin ${point(spec.origin)}${inBox(spec.origin) ? "" : " (outside the preview box)"}` +
      ` · normal (${spec.normal.map((x) => x.toFixed(2)).join(", ")})` +
      ` · ${spec.size} px x ${spacingLabel(spec.spacing)} = ${round1(span)} voxels a side`;
  }
  drawView();      // view3d.js: the object is cut by this plane
  planeChanged();  // meshes.js: a baked surface's cap
  if (spec) freeCut.stream.request();
}

function showFreeCut(r) {
  if (freeCut.url) URL.revokeObjectURL(freeCut.url);
  freeCut.url = URL.createObjectURL(r.blob);
  const img = $("cut-image");
  img.src = freeCut.url;
  freeCut.count += 1;
  img.dataset.count = String(freeCut.count);
  $("dl-cut").href = freeCut.url;
  $("dl-cut").download = `cut-${r.spec.solid}.png`;
  freeCut.cut = { solid: r.spec.solid, origin: r.spec.origin, frame: r.frame, size: r.spec.size, spacing: r.spec.spacing, bitmap: r.bitmap };
  $("cut-latency").textContent = `cut ${freeCut.count}: ${latencyText(r)}`;
  $("cut-latency").className = "latency";
  uploadCutTexture();
  updateDownloads();
  drawView();
}

function freeCutFailed(e) {
  $("cut-latency").textContent = "cut failed: " + e.message;
  $("cut-latency").className = "latency error";
  say("cut: " + e.message, true);
}

// ---- the orthogonal slices ----

// Each slice's plane and image axes: columns run along `u`, rows along `v` (the frame the server
// makes of `normal` and `up`: v = up, u = v x normal).
const SLICE_AXES = {
  x: { axis: 0, normal: [1, 0, 0], up: [0, 0, 1], u: 1, v: 2 },  // columns y, rows z
  y: { axis: 1, normal: [0, -1, 0], up: [0, 0, 1], u: 0, v: 2 }, // columns x, rows z
  z: { axis: 2, normal: [0, 0, 1], up: [0, 1, 0], u: 0, v: 1 },  // columns x, rows y
};
const AXIS_NAMES = ["x", "y", "z"];
const AXIS_COLOURS = ["#f28b82", "#81c995", "#8ab4f8"];
const SLICE_SIZE = 128;

const slices = {
  centre: [32, 32, 32], // the point the three images are centred on (in-plane)
  spacing: 1,
  shown: { x: null, y: null, z: null },  // spec and source ("server" or "preview") of each picture
  streams: {},
  count: 0,
};

const slicePos = (a) => Math.round(+$(`slice-${a}-pos`).value || 0);

// An axis-aligned cut: through the middle of voxel layer `pos` (pixel centres sit on
// voxel centres' planes), centred in-plane on the shared centre.
function sliceSpec(a) {
  if (!view.solid) return null;
  const ax = SLICE_AXES[a];
  const origin = slices.centre.slice();
  origin[ax.axis] = slicePos(a) + 0.5;
  return { solid: view.solid.id, origin, normal: ax.normal, up: ax.up, size: SLICE_SIZE, spacing: slices.spacing };
}

// The voxel coordinate pixel index i samples along an image axis centred on c.
const pixelVoxel = (c, i, spec) => Math.floor(c + (i + 0.5 - spec.size / 2) * spec.spacing);
// The (fractional) pixel position of voxel coordinate x along that axis.
const voxelPixel = (c, x, spec) => (x - c) / spec.spacing + spec.size / 2;

function requestSlices() {
  $("slice-centre").textContent = point(slices.centre);
  for (const a of AXIS_NAMES) {
    const spec = sliceSpec(a);
    $(`slice-${a}-range`).value = String(Math.max(0, Math.min((view.n || 64) - 1, slicePos(a))));
    if (!spec) continue;
    const ax = SLICE_AXES[a], span = (i) => {
      const lo = pixelVoxel(spec.origin[i], 0, spec), hi = pixelVoxel(spec.origin[i], spec.size - 1, spec);
      return `${AXIS_NAMES[i]} ${lo}…${hi}`;
    };
    const inside = slicePos(a) >= 0 && slicePos(a) < view.n;
    $(`slice-${a}-span`).textContent = `${span(ax.u)}, ${span(ax.v)}${inside ? "" : " · outside the preview box"}`;
    const shown = slices.shown[a];
    if (shown && sameSpec(shown.spec, spec)) continue;
    drawSlicePreview(a, spec);
    slices.streams[a].request();
  }
}

// What the preview volume knows of the slice at once: its voxels inside the box; the rest dark
// until the server's cut arrives.
function drawSlicePreview(a, spec) {
  if (!view.volume) return;
  const n = view.n, vol = view.volume, ax = SLICE_AXES[a], size = spec.size;
  const c = $(`slice-${a}`);
  c.width = size; c.height = size;
  const ctx = c.getContext("2d");
  const img = ctx.createImageData(size, size);
  const p = [0, 0, 0];
  p[ax.axis] = slicePos(a);
  for (let j = 0; j < size; j++) {
    p[ax.v] = pixelVoxel(spec.origin[ax.v], j, spec);
    for (let i = 0; i < size; i++) {
      p[ax.u] = pixelVoxel(spec.origin[ax.u], i, spec);
      const dst = 4 * (j * size + i);
      if (inBox(p)) {
        const src = 4 * ((p[2] * n + p[1]) * n + p[0]);
        img.data[dst] = vol[src]; img.data[dst + 1] = vol[src + 1]; img.data[dst + 2] = vol[src + 2];
      } else {
        img.data[dst] = 40; img.data[dst + 1] = 42; img.data[dst + 2] = 46;
      }
      img.data[dst + 3] = 255;
    }
  }
  ctx.putImageData(img, 0, 0);
  slices.shown[a] = { spec, source: "preview" };
  c.dataset.source = "preview";
  drawSliceOverlay(a, spec);
}

function showSlice(a, r) {
  // A cut for a spec already left behind is not shown: the follow-up for the current one comes.
  if (!sameSpec(r.spec, sliceSpec(a))) return;
  const c = $(`slice-${a}`);
  c.width = r.spec.size; c.height = r.spec.size;
  c.getContext("2d").drawImage(r.bitmap, 0, 0);
  slices.shown[a] = { spec: r.spec, source: "server" };
  slices.count += 1;
  c.dataset.count = String(+c.dataset.count + 1);
  c.dataset.source = "server";
  c.dataset.origin = r.spec.origin.join(",");
  drawSliceOverlay(a, r.spec);
  $("slice-latency").textContent = `${a} = ${slicePos(a)}: ${latencyText(r)}`;
  $("slice-latency").className = "latency";
}

// The preview box's outline (dashed, where the slice passes through it) and the other two
// slices' planes (lines in their axis colour).
function drawSliceOverlay(a, spec) {
  const ctx = $(`slice-${a}`).getContext("2d"), ax = SLICE_AXES[a], n = view.n || 64;
  const px = (i, x) => voxelPixel(spec.origin[i], x, spec);
  ctx.save();
  ctx.lineWidth = 1;
  if (slicePos(a) >= 0 && slicePos(a) < n) {
    // Light dashes on a dark line: visible on light and dark solids alike.
    const [i0, i1, j0, j1] = [px(ax.u, 0), px(ax.u, n), px(ax.v, 0), px(ax.v, n)];
    ctx.strokeStyle = "rgba(0, 0, 0, 0.6)";
    ctx.strokeRect(i0, j0, i1 - i0, j1 - j0);
    ctx.setLineDash([3, 3]);
    ctx.strokeStyle = "rgba(255, 255, 255, 0.9)";
    ctx.strokeRect(i0, j0, i1 - i0, j1 - j0);
  }
  ctx.setLineDash([]);
  ctx.globalAlpha = 0.6;
  for (const [other, vertical] of [[ax.u, true], [ax.v, false]]) {
    const at = Math.round(px(other, slicePos(AXIS_NAMES[other]) + 0.5)) + 0.5;
    if (at < 0 || at > spec.size) continue;
    ctx.strokeStyle = AXIS_COLOURS[other];
    ctx.beginPath();
    if (vertical) { ctx.moveTo(at, 0); ctx.lineTo(at, spec.size); } else { ctx.moveTo(0, at); ctx.lineTo(spec.size, at); }
    ctx.stroke();
  }
  ctx.restore();
}

function sliceFailed(a, e) {
  $("slice-latency").textContent = `${a} slice failed: ${e.message}`;
  $("slice-latency").className = "latency error";
  say(`${a} slice: ${e.message}`, true);
}

function resetSlices() {
  const c = (view.n || 64) / 2;
  slices.centre = [c, c, c];
  for (const a of AXIS_NAMES) $(`slice-${a}-pos`).value = String(c);
  slices.spacing = 1;
  $("slice-spacing").value = "1";
  requestSlices();
}

// Every cut is of the shown solid: a new one asks for them all again.
function solidChanged() {
  for (const a of AXIS_NAMES) {
    $(`slice-${a}-range`).max = String(view.n - 1);
    slices.shown[a] = null;
  }
  requestSlices();
  requestCut();
}

// Whether no cut is in flight or waiting to be asked for (the tests wait for this).
function cutsIdle() {
  return freeCut.stream.idle && AXIS_NAMES.every((a) => slices.streams[a].idle);
}

function wireCuts() {
  fillSpacingSelect($("cut-spacing"), 1);
  fillSpacingSelect($("slice-spacing"), 1);
  freeCut.stream = new CutStream(freeCutSpec, showFreeCut, freeCutFailed);
  for (const a of AXIS_NAMES) {
    slices.streams[a] = new CutStream(() => sliceSpec(a), (r) => showSlice(a, r), (e) => sliceFailed(a, e));
  }
  for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}`).addEventListener("input", requestCut);
  for (const id of ["cut-size", "cut-spacing", "cut-cx", "cut-cy", "cut-cz"]) $(id).addEventListener("change", requestCut);
  const cutImage = $("cut-image");
  // Drag tilts the plane (horizontal: azimuth, vertical: elevation); shift-drag moves its
  // centre along the plane, as the picture moves under the pointer.
  dragger(cutImage, (dx, dy, e) => {
    if (e.shiftKey && freeCut.cut) {
      const c = freeCut.cut, k = c.size * c.spacing / cutImage.clientWidth;
      ["cut-cx", "cut-cy", "cut-cz"].forEach((id, i) => {
        $(id).value = String(round1(+$(id).value - k * (dx * c.frame.u[i] + dy * c.frame.v[i])));
      });
    } else {
      const az = $("cut-azimuth"), el = $("cut-elevation");
      az.value = ((+az.value + dx * 0.5) % 360 + 360) % 360;
      el.value = Math.max(-90, Math.min(90, +el.value - dy * 0.5));
    }
    requestCut();
  });
  cutImage.addEventListener("wheel", (e) => {
    e.preventDefault();
    $("cut-spacing").value = String(zoomSpacing(+$("cut-spacing").value, e.deltaY, +$("cut-size").value, maxCutSpan()));
    requestCut();
  }, { passive: false });

  for (const a of AXIS_NAMES) {
    const pos = $(`slice-${a}-pos`), range = $(`slice-${a}-range`), canvas = $(`slice-${a}`);
    range.addEventListener("input", () => { pos.value = range.value; requestSlices(); });
    pos.addEventListener("change", () => {
      pos.value = String(Math.max(-1e6, Math.min(1e6 - 1, slicePos(a))));
      requestSlices();
    });
    // Drag moves the shared centre so that the picture follows the pointer.
    dragger(canvas, (dx, dy) => {
      const ax = SLICE_AXES[a], k = slices.spacing * SLICE_SIZE / canvas.clientWidth;
      slices.centre[ax.u] = round1(slices.centre[ax.u] - dx * k);
      slices.centre[ax.v] = round1(slices.centre[ax.v] - dy * k);
      requestSlices();
    });
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      slices.spacing = zoomSpacing(slices.spacing, e.deltaY, SLICE_SIZE, maxCutSpan());
      $("slice-spacing").value = String(slices.spacing);
      requestSlices();
    }, { passive: false });
  }
  $("slice-spacing").addEventListener("change", () => { slices.spacing = +$("slice-spacing").value; requestSlices(); });
  $("slice-reset").addEventListener("click", resetSlices);
  for (const k of ["azimuth", "elevation", "offset"]) $(`cut-${k}-v`).textContent = $(`cut-${k}`).value;
}
