// End-to-end test of `solidsynth serve`, driven as a person would use it, in headless Chromium
// (Debian's /usr/bin/chromium through playwright-core; no browser download).
//
// Uses the binary SOLIDSYNTH_BIN (.ci/run passes the one `cargo test` built), else builds it with
// `cargo build` (dev profile); starts the server on a free loopback port, then:
// loads the page, runs a synthesis (picks an exemplar and seed, clicks Synthesize, sees progress),
// moves the cut slider with the keyboard, checks that a new cut image arrived from the server and
// that its latency is shown, checks the WebGL view rendered; switches the 3D view to the bunny
// (a triangle mesh), checks it drew, that the cut removes part of it and that moving the plane
// changes it; turns, zooms (wheel, pinch) and pans it; moves a slice out of the preview box and
// zooms the slices; bakes the bunny's surface at 512 and checks the baked model replaced the
// preview texturing with finer detail (timing the click to the screen, and a cut made during the
// bake); downloads the .glb and validates it (Khronos glTF validator); cancels a bake at 1024;
// makes a solid with other parameters; uploads a good mesh (bakes it fast, and has its cut face
// cut at the bake's scale) and a bad one; reloads the page and finds the job list again.
// Screenshots go to viewer-test/out/.
// Prints "e2e: N passed, N failed" and exits non-zero on failure.
//
// SOLIDSYNTH_VIEWER_DIR=DIR serves the page's own files (/, *.js, *.css) from DIR instead of the
// binary's built-in copies: for editing the page without rebuilding (CI leaves it unset).

import { chromium } from "playwright-core";
import validator from "gltf-validator";
import { spawn, execFileSync } from "node:child_process";
import { mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const repo = join(here, "..");
const outDir = join(here, "out");
const CHROMIUM = process.env.CHROMIUM || "/usr/bin/chromium";
const TIMEOUT_MS = 300_000;

function binary() {
  if (process.env.SOLIDSYNTH_BIN) return process.env.SOLIDSYNTH_BIN;
  execFileSync("cargo", ["build", "--locked", "--bin", "solidsynth"], { cwd: repo, stdio: "inherit" });
  const target = process.env.CARGO_TARGET_DIR || join(repo, "target");
  return join(target, "debug", "solidsynth");
}

function startServer(bin, cacheDir) {
  return new Promise((resolve, reject) => {
    const child = spawn(bin, ["serve", "--port", "0", "--bind", "127.0.0.1"], {
      env: { ...process.env, SOLIDSYNTH_CACHE_DIR: cacheDir, SOLIDSYNTH_LOG: "warn" },
      stdio: ["ignore", "ignore", "pipe"],
    });
    let err = "";
    const timer = setTimeout(() => reject(new Error("server did not start: " + err)), 60_000);
    child.stderr.on("data", (d) => {
      err += d;
      const m = /solidsynth viewer: (http:\/\/127\.0\.0\.1:\d+\/)/.exec(err);
      if (m) { clearTimeout(timer); resolve({ child, url: m[1] }); }
    });
    child.on("exit", (code) => reject(new Error(`server exited ${code}: ${err}`)));
  });
}

function check(cond, what) {
  if (!cond) throw new Error("assertion failed: " + what);
  console.log("  ok: " + what);
}

// The page's own files from a directory (SOLIDSYNTH_VIEWER_DIR), for development.
async function servePageFrom(page, dir) {
  await page.route(/^[^?]*\/([\w-]+\.(js|css|html))?$/, (route) => {
    const path = new URL(route.request().url()).pathname;
    const file = path === "/" ? "index.html" : path.slice(1);
    const type = { js: "text/javascript", css: "text/css", html: "text/html" }[file.split(".").pop()];
    route.fulfill({ body: readFileSync(join(dir, file)), contentType: type + "; charset=utf-8" });
  });
  console.log("  (the page's files come from " + dir + ")");
}

async function main() {
  const started = Date.now();
  const bin = binary();
  const cacheDir = mkdtempSync(join(tmpdir(), "solidsynth-e2e-"));
  mkdirSync(outDir, { recursive: true });
  const { child, url } = await startServer(bin, cacheDir);
  console.log("server at " + url);
  const browser = await chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"],
  });
  const timings = [];
  try {
    const page = await browser.newPage({ viewport: { width: 1280, height: 1100 }, acceptDownloads: true });
    if (process.env.SOLIDSYNTH_VIEWER_DIR) await servePageFrom(page, process.env.SOLIDSYNTH_VIEWER_DIR);
    // Errors in the page; the browser also logs each request answered with an error, and one
    // such is intended (the refused mesh upload).
    const pageErrors = [];
    const refusedUpload = /\/api\/meshes\?format=obj&name=garbage\.obj$/;
    page.on("pageerror", (e) => pageErrors.push(e.message));
    page.on("console", (m) => {
      if (m.type() === "error" && !refusedUpload.test(m.location().url || "")) pageErrors.push(m.text());
    });
    // Every cut the page asks for; the free cut's are those without an `up` (slices and the
    // baked model's cap give one).
    const cuts = [];
    page.on("response", (r) => { if (r.url().includes("/cut?")) cuts.push(r); });
    const freeCuts = () => cuts.filter((r) => !new URL(r.url()).searchParams.has("up"));
    page.setDefaultTimeout(120_000);
    const shot = (name) => page.locator("#view3d").screenshot({ path: join(outDir, name) });
    const settle = () => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    const cutsSettled = () => page.waitForFunction(() => cutsIdle());

    // 1. The page loads; the server's first solid (built-in exemplar) becomes ready.
    await page.goto(url);
    check((await page.title()) === "solidsynth viewer", "the page loads");
    await page.waitForSelector("body[data-solid]");
    const firstSolid = await page.getAttribute("body", "data-solid");
    check(true, `the startup solid ${firstSolid} is shown`);

    // 2. Run a synthesis: another exemplar and seed, progress shown while it runs.
    await page.evaluate(() => {
      window.statusLog = [];
      new MutationObserver(() => window.statusLog.push(document.getElementById("job-status").textContent))
        .observe(document.getElementById("job-status"), { childList: true, characterData: true, subtree: true });
    });
    await page.selectOption("#exemplar", "marble");
    await page.fill("#seed", "7");
    await page.click("#synthesize");
    await page.waitForFunction((old) => document.body.dataset.solid && document.body.dataset.solid !== old, firstSolid);
    const solid = await page.getAttribute("body", "data-solid");
    const log = await page.evaluate(() => window.statusLog);
    const stages = log.filter((t) => /^marble: (analysis|synthesizing).*\(\d+%/.test(t));
    check(stages.length > 0, `progress was shown (${log.length} updates, e.g. "${stages[0]}")`);
    check(/marble: ready/.test(await page.textContent("#job-status")), "the synthesis finished");
    check((await page.textContent("#solid-info")).includes("seed 7"), "the new solid is the one asked for");

    // 3. Its first cut arrives (requested when the solid loads).
    await page.waitForFunction(() => /synthesized in/.test(document.getElementById("cut-latency").textContent)
      && document.getElementById("cut-latency").textContent.startsWith("cut "));
    await cutsSettled();
    const before = Number(await page.getAttribute("#cut-image", "data-count"));
    const srcBefore = await page.getAttribute("#cut-image", "src");

    // 4. Move the cut slider as a person would: focus it, arrow keys.
    await page.focus("#cut-offset");
    for (let i = 0; i < 6; i++) await page.keyboard.press("ArrowRight");
    check((await page.inputValue("#cut-offset")) === "6", "the offset slider moved to 6");
    // Moves made while a cut was in flight coalesce into one follow-up request: wait until the
    // page has no cut in flight or pending, and a newer image is shown.
    await page.waitForFunction((n) => freeCut.stream.idle
      && Number(document.getElementById("cut-image").dataset.count) > n, before);
    const last = freeCuts().pop();
    await last.finished();
    const after = Number(await page.getAttribute("#cut-image", "data-count"));
    const srcAfter = await page.getAttribute("#cut-image", "src");
    check(after > before && srcAfter !== srcBefore, `a new cut image arrived (cut ${before} -> ${after})`);
    check(last.status() === 200 && last.headers()["content-type"] === "image/png", "the cut came from the server as a PNG");
    const lastUrl = new URL(last.url());
    check(lastUrl.pathname === `/api/solids/${solid}/cut`, "the cut is of the new solid");
    const n = lastUrl.searchParams.get("normal").split(",").map(Number);
    const o = lastUrl.searchParams.get("origin").split(",").map(Number);
    const offset = o.reduce((s, x, i) => s + (x - 32) * n[i], 0);
    check(Math.abs(offset - 6) < 1e-3, `the last cut is at the slider's offset (${offset.toFixed(3)})`);
    const latency = await page.textContent("#cut-latency");
    check(/synthesized in \d+(\.\d+)? ms .*round trip \d+(\.\d+)? ms/.test(latency), `latency shown: "${latency}"`);
    const natural = await page.$eval("#cut-image", (img) => [img.complete, img.naturalWidth, img.naturalHeight]);
    check(natural[0] && natural[1] === 128 && natural[2] === 128, "the cut image is a decoded 128x128 image");
    check(/origin \(.*\) · normal/.test(await page.textContent("#cut-where")), "the cut's coordinates are shown");

    // 5. The 3D view rendered the solid (WebGL2): not all background.
    check((await page.textContent("#view-status")) === "", "WebGL2 is available and the shader compiled");
    const lit = await page.$eval("#view3d", (c) => {
      const gl = c.getContext("webgl2");
      const px = new Uint8Array(4 * c.width * c.height);
      gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
      let object = 0;
      for (let i = 0; i < px.length; i += 4) if (px[i] + px[i + 1] + px[i + 2] > 60) object++;
      return object / (c.width * c.height);
    });
    check(lit > 0.1, `the textured object covers ${(100 * lit).toFixed(0)}% of the 3D view`);

    // 6. Downloads point at the API and answer.
    const href = await page.getAttribute("#dl-vti", "href");
    const vti = await page.request.get(new URL(href, url).toString());
    check(vti.status() === 200 && (await vti.body()).subarray(0, 5).toString() === "<?xml", "the VTI download answers");
    const formats = await page.$$eval(".downloads a[href*='/volume?']", (as) => as.map((a) => new URL(a.href).searchParams.get("format")));
    check(["nrrd", "nrrd-gzip", "npy", "tiff", "ktx2", "vdb", "vti", "flipbook", "raw"].every((f) => formats.includes(f)),
      `the volume is offered in ${formats.join(", ")}`);

    await page.screenshot({ path: join(outDir, "viewer.png"), fullPage: true });
    check(true, "screenshot saved to viewer-test/out/viewer.png");

    // 7. The bunny: a triangle mesh (/api/meshes/bunny/geometry) drawn with WebGL2, textured by
    // the solid and cut by the free plane.
    const mesh = await page.request.get(new URL("/api/meshes/bunny/geometry", url).toString());
    const meshBytes = await mesh.body();
    const [nv, nt] = [meshBytes.readUInt32LE(0), meshBytes.readUInt32LE(4)];
    check(mesh.status() === 200 && meshBytes.length === 8 + 12 * nv + 12 * nt && nt > 1000,
      `the bunny mesh is served (${nv} vertices, ${nt} triangles)`);
    // Reads the 3D view back: the share of the centre region (the middle half on each axis) that
    // is not background, the share of all pixels that changed since the previous call, and the
    // object's texture detail: the mean colour step between neighbouring object pixels, and its
    // distinct colours.
    const viewStats = () => page.$eval("#view3d", (c) => {
      const gl = c.getContext("webgl2");
      const w = c.width, h = c.height, px = new Uint8Array(4 * w * h);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
      const bg = [18, 18, 20];
      const isObject = (i) => [0, 1, 2].some((k) => Math.abs(px[i + k] - bg[k]) > 6);
      let centre = 0, inCentre = 0, changed = 0, steps = 0, step = 0;
      const colours = new Set();
      const prev = window.lastView;
      for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
        const i = 4 * (y * w + x);
        if (x >= w / 4 && x < 3 * w / 4 && y >= h / 4 && y < 3 * h / 4) {
          inCentre++;
          if (isObject(i)) centre++;
        }
        if (prev && [0, 1, 2].some((k) => Math.abs(px[i + k] - prev[i + k]) > 12)) changed++;
        if (!isObject(i)) continue;
        colours.add(px[i] << 16 | px[i + 1] << 8 | px[i + 2]);
        for (const j of [i + 4, i + 4 * w]) {
          if (x + 1 >= w || y + 1 >= h || !isObject(j)) continue;
          steps++;
          step += Math.abs(px[i] - px[j]) + Math.abs(px[i + 1] - px[j + 1]) + Math.abs(px[i + 2] - px[j + 2]);
        }
      }
      window.lastView = px;
      return { centre: centre / inCentre, changed: prev ? changed / (w * h) : null, detail: step / Math.max(1, steps), colours: colours.size };
    });
    await page.selectOption("#shape", "bunny");
    await page.waitForFunction(() => document.getElementById("view3d").dataset.shape === "bunny");
    await settle();
    const bunny = await viewStats();
    check(bunny.centre > 0.3, `the bunny covers ${(100 * bunny.centre).toFixed(0)}% of the view's centre`);
    await shot("bunny.png");
    check(true, "screenshot saved to viewer-test/out/bunny.png");
    // Without the cut the picture differs (the plane removes part of the bunny)...
    await page.uncheck("#clip");
    await settle();
    const whole = await viewStats();
    check(whole.changed > 0.02, `unchecking the cut changes ${(100 * whole.changed).toFixed(0)}% of the view`);
    await shot("bunny-whole.png");
    await page.check("#clip");
    await settle();
    await viewStats();
    // ...and moving the plane moves the cut.
    const beforeMove = Number(await page.getAttribute("#cut-image", "data-count"));
    await page.focus("#cut-offset");
    for (let i = 0; i < 12; i++) await page.keyboard.press("ArrowLeft");
    check((await page.inputValue("#cut-offset")) === "-6", "the offset slider moved to -6");
    await page.waitForFunction((n) => freeCut.stream.idle
      && Number(document.getElementById("cut-image").dataset.count) > n, beforeMove);
    await settle();
    const moved = await viewStats();
    check(moved.changed > 0.02, `moving the cut changes ${(100 * moved.changed).toFixed(0)}% of the bunny view`);
    check(moved.centre > 0.3, `the cut bunny still covers ${(100 * moved.centre).toFixed(0)}% of the view's centre`);
    await shot("bunny-cut.png");
    // Dragging turns it.
    const box = await page.locator("#view3d").boundingBox();
    const [cx, cy] = [box.x + box.width / 2, box.y + box.height / 2];
    await page.mouse.move(cx, cy);
    await page.mouse.down();
    await page.mouse.move(cx + 70, cy, { steps: 5 });
    await page.mouse.up();
    await settle();
    const turned = await viewStats();
    check(turned.changed > 0.02, `dragging turns the bunny (${(100 * turned.changed).toFixed(0)}% of the view changed)`);
    await shot("bunny-turned.png");
    await page.screenshot({ path: join(outDir, "viewer-bunny.png"), fullPage: true });
    check(true, "screenshots saved to viewer-test/out/bunny-{whole,cut,turned}.png, viewer-bunny.png");

    // 8. Zoom (wheel, pinch) and pan (shift-drag).
    const dist = async () => Number(await page.getAttribute("#view3d", "data-dist"));
    const d0 = await dist();
    await page.mouse.move(cx, cy);
    await page.mouse.wheel(0, -400);
    await page.waitForFunction((d) => Number(document.getElementById("view3d").dataset.dist) < d, d0);
    await settle();
    const zoomed = await viewStats();
    check(zoomed.changed > 0.05, `the wheel zooms in (distance ${d0} -> ${await dist()}; ${(100 * zoomed.changed).toFixed(0)}% of the view changed)`);
    await shot("bunny-zoomed.png");
    await page.keyboard.down("Shift");
    await page.mouse.move(cx, cy);
    await page.mouse.down();
    await page.mouse.move(cx - 60, cy + 40, { steps: 4 });
    await page.mouse.up();
    await page.keyboard.up("Shift");
    await settle();
    const panned = await viewStats();
    check(panned.changed > 0.05, `shift-drag pans (${(100 * panned.changed).toFixed(0)}% of the view changed)`);
    // Two fingers spreading apart (touch pointers) zoom in: from the home view, twice as near.
    await page.click("#view-reset");
    await settle();
    const d1 = await dist();
    await page.$eval("#view3d", (c, [x, y]) => {
      const send = (type, id, px) => c.dispatchEvent(new PointerEvent(type, {
        pointerId: id, pointerType: "touch", isPrimary: id === 21, clientX: px, clientY: y, bubbles: true, cancelable: true,
      }));
      send("pointerdown", 21, x - 20);
      send("pointerdown", 22, x + 20);
      for (let i = 1; i <= 5; i++) { send("pointermove", 21, x - 20 - 4 * i); send("pointermove", 22, x + 20 + 4 * i); }
      send("pointerup", 21, x - 40);
      send("pointerup", 22, x + 40);
    }, [cx, cy]);
    await settle();
    check(Math.abs(await dist() - d1 / 2) < 0.01, `a pinch zooms in (distance ${d1} -> ${await dist()})`);
    await page.click("#view-reset");
    await settle();

    // 9. The slices go anywhere in the infinite solid: z = -200 is far below the preview box.
    await cutsSettled();
    const zCount = Number(await page.getAttribute("#slice-z", "data-count"));
    await page.fill("#slice-z-pos", "-200");
    await page.press("#slice-z-pos", "Enter");
    await page.waitForFunction((n) => Number(document.getElementById("slice-z").dataset.count) > n
      && document.getElementById("slice-z").dataset.source === "server", zCount);
    const zOrigin = (await page.getAttribute("#slice-z", "data-origin")).split(",").map(Number);
    check(zOrigin[2] === -199.5, `the z slice at z = -200 arrived from the server (origin ${zOrigin.join(", ")})`);
    const zCut = cuts.filter((r) => r.url().includes("/cut?") && new URL(r.url()).searchParams.get("origin").endsWith(",-199.500000")).pop();
    check(zCut && zCut.status() === 200 && new URL(zCut.url()).searchParams.get("normal") === "0.000000,0.000000,1.000000",
      "it is an axis-aligned cut (normal 0,0,1) through z = -199.5");
    check(/outside the preview box/.test(await page.textContent("#slice-z-span")), `its coordinates are shown: "${await page.textContent("#slice-z-span")}"`);
    // The wheel zooms the slices out: a coarser spacing, new cuts of all three.
    const spacingBefore = await page.inputValue("#slice-spacing");
    await page.locator("#slice-z").hover();
    await page.mouse.wheel(0, 200);
    await page.waitForFunction((s) => document.getElementById("slice-spacing").value !== s, spacingBefore);
    await cutsSettled();
    const spacingNow = await page.inputValue("#slice-spacing");
    check(cuts.some((r) => new URL(r.url()).searchParams.get("spacing") === spacingNow) && spacingNow === "2",
      `the wheel zooms the slices out (${spacingBefore} -> ${spacingNow} voxels per pixel)`);
    await page.locator("#slice-panel").screenshot({ path: join(outDir, "slices.png") });
    check(true, "screenshot saved to viewer-test/out/slices.png");

    // 10. Bake the bunny's surface at 512. Before: the preview texturing (the whole bunny, the
    // home camera); after: the baked model, with finer texture detail.
    await page.uncheck("#clip");
    await settle();
    const preview = await viewStats();
    check((await page.getAttribute("#view3d", "data-texture")) === "preview", "the bunny is textured from the preview volume");
    await page.selectOption("#bake-resolution", "512");
    const clicked = Date.now();
    await page.click("#bake");
    await page.waitForFunction(() => document.body.dataset.bake === "running");
    // A 256x256 cut during the bake: bakes do not hold the lock cuts wait on.
    await page.waitForFunction(() => /baking/.test(document.getElementById("bake-status").textContent));
    const beforeBig = freeCuts().length;
    await page.selectOption("#cut-size", "256");
    await page.waitForFunction((k) => freeCut.stream.idle && document.getElementById("cut-latency").textContent.includes("256x256"), beforeBig);
    const bigCut = freeCuts().filter((r) => new URL(r.url()).searchParams.get("size") === "256").pop();
    const stillBaking = await page.evaluate(() => document.body.dataset.bake === "running");
    const cutMs = Number(bigCut.headers()["x-synthesis-ms"]), cutQueue = Number(bigCut.headers()["x-queue-ms"]);
    check(bigCut.status() === 200 && cutMs > 0, `a 256x256 cut during the bake: synthesized in ${cutMs} ms (queued ${cutQueue} ms)` +
      (stillBaking ? ", the bake still running" : ", the bake finished meanwhile"));
    timings.push(`256x256 cut while a bake runs: X-Synthesis-Ms ${cutMs} (X-Queue-Ms ${cutQueue})${stillBaking ? "" : " (the bake had ended)"}`);
    await page.waitForFunction(() => document.getElementById("view3d").dataset.texture === "baked", null, { timeout: 180_000 });
    const wall = (Date.now() - clicked) / 1000;
    const pageMs = Number(await page.getAttribute("#view3d", "data-bake-ms"));
    await settle();
    const baked = await viewStats();
    // (Distinct colours are shown, not checked: the shading alone makes most pixels distinct.)
    check(baked.detail > 1.5 * preview.detail,
      `the baked texture is finer: mean colour step between neighbouring pixels ${preview.detail.toFixed(1)} -> ` +
      `${baked.detail.toFixed(1)} (distinct colours ${preview.colours} -> ${baked.colours})`);
    check(Math.abs(baked.centre - preview.centre) < 0.05, `the same bunny (${(100 * preview.centre).toFixed(0)}% -> ${(100 * baked.centre).toFixed(0)}% of the centre)`);
    check(/baked at 512/.test(await page.textContent("#texture-label")), `labelled: "${await page.textContent("#texture-label")}"`);
    check(/on screen [\d.]+ s after the click/.test(await page.textContent("#bake-status")), `timed: "${await page.textContent("#bake-status")}"`);
    timings.push(`bake the bunny at 512: click -> baked model on screen ${(pageMs / 1000).toFixed(1)} s (page clock), ${wall.toFixed(1)} s (test clock)`);
    // The page's JavaScript heap with the baked model shown (Chromium's performance.memory; the
    // textures live in GPU memory, which no page API reports).
    const heap = await page.evaluate(() => performance.memory ? performance.memory.usedJSHeapSize : null);
    if (heap !== null) timings.push(`page JavaScript heap with the bunny baked at 512: ${(heap / 1048576).toFixed(1)} MiB`);
    await page.locator("#view3d").screenshot({ path: join(outDir, "bunny-baked.png") });
    // Cut, the cut face showing the free cut.
    await page.check("#clip");
    await settle();
    await shot("bunny-baked-cut.png");
    await page.screenshot({ path: join(outDir, "viewer-baked.png"), fullPage: true });
    check(true, "screenshots saved to viewer-test/out/bunny-baked.png, bunny-baked-cut.png, viewer-baked.png");

    // 11. The .glb download validates (Khronos glTF validator: no errors, no warnings).
    const [download] = await Promise.all([page.waitForEvent("download"), page.click("#dl-glb")]);
    const glbPath = join(cacheDir, "download.glb");
    await download.saveAs(glbPath);
    const glb = readFileSync(glbPath);
    const report = await validator.validateBytes(new Uint8Array(glb), { maxIssues: 100 });
    const { numErrors, numWarnings } = report.issues;
    for (const m of report.issues.messages.filter((m) => m.severity < 2)) console.log(`    ${m.code}: ${m.message} (${m.pointer ?? ""})`);
    check(glb.subarray(0, 4).toString() === "glTF" && numErrors === 0 && numWarnings === 0,
      `the downloaded ${download.suggestedFilename()} (${glb.length} bytes) validates: ${numErrors} errors, ${numWarnings} warnings`);

    // 12. Cancel a bake at 1024.
    await page.selectOption("#bake-resolution", "1024");
    await page.click("#bake");
    // Cancelled while it synthesizes (not while it waits to start).
    await page.waitForFunction(() => document.body.dataset.bake === "running" && !document.getElementById("bake-cancel").disabled
      && /at 1024: baking/.test(document.getElementById("bake-status").textContent));
    const cancelled = Date.now();
    await page.click("#bake-cancel");
    await page.waitForFunction(() => document.body.dataset.bake === "cancelled", null, { timeout: 60_000 });
    const cancelledJob = await page.$eval("#jobs li[data-state='cancelled']", (li) => li.textContent);
    check(/bake: .* at 1024 · cancelled/.test(cancelledJob), `the bake at 1024 was cancelled in ${((Date.now() - cancelled) / 1000).toFixed(1)} s: "${cancelledJob}"`);
    check(/cancelled/.test(await page.textContent("#bake-status")), "the bake's status says so");

    // 13. New parameters make a new solid, listed with them.
    await page.selectOption("#exemplar", "cells");
    await page.fill("#p-jitter", "0.5");
    await page.fill("#p-passes", "1");
    const shownSolid = await page.getAttribute("body", "data-solid");
    await page.click("#synthesize");
    await page.waitForFunction((old) => document.body.dataset.solid !== old, shownSolid);
    const paramSolid = await page.getAttribute("body", "data-solid");
    const listed = await page.textContent(`#solids li[data-solid='${paramSolid}']`);
    check(/jitter 0\.5/.test(listed) && /passes 1\b/.test(listed), `the new solid ${paramSolid} is listed with its parameters: "${listed.trim()}"`);
    check((await page.getAttribute("#view3d", "data-texture")) === "preview", "a new solid drops the bake of the old one");
    // The list switches between solids.
    await page.click(`#solids li[data-solid='${solid}'] button`);
    await page.waitForFunction((s) => document.body.dataset.solid === s, solid);
    check(true, `the solid list switches back to solid ${solid}`);

    // 14. Own meshes: a cube (OBJ) is accepted and shown; garbage is refused with the server's message.
    const cubePath = join(cacheDir, "cube.obj");
    writeFileSync(cubePath, "# a unit cube\n" +
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n" +
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 2 3 7 6\nf 1 5 8 4\n");
    await page.setInputFiles("#mesh-file", cubePath);
    await page.waitForFunction(() => /cube\.obj/.test(document.getElementById("shape").selectedOptions[0].textContent)
      && document.getElementById("view3d").dataset.shape === document.getElementById("shape").value);
    await settle();
    const cube = await viewStats();
    check(cube.centre > 0.3, `the uploaded cube is shown (${await page.textContent("#status")}; ${(100 * cube.centre).toFixed(0)}% of the centre)`);
    await shot("cube.png");
    // Baked onto it, fast (labelled as a slightly different solid).
    await page.selectOption("#bake-resolution", "256");
    await page.check("#bake-fast");
    await page.click("#bake");
    await page.waitForFunction(() => document.getElementById("view3d").dataset.texture === "baked");
    const fastLabel = await page.textContent("#texture-label");
    check(/baked at 256/.test(fastLabel) && /FAST bake: a slightly different solid/.test(fastLabel), `the cube, baked fast: "${fastLabel}"`);
    await settle();
    await shot("cube-baked-fast.png");
    // Its cut face at the bake's scale: cut by the server in tiles.
    await viewStats();
    await page.check("#cap-baked");
    await page.waitForFunction(() => !capTiles.running && !capTiles.want && capTiles.cap);
    await settle();
    const capped = await viewStats();
    check(capped.changed > 0.02 && /the cut face at the bake's scale/.test(await page.textContent("#texture-label")),
      `the cube's cut face at the bake's scale (${(100 * capped.changed).toFixed(0)}% of the view changed)`);
    await shot("cube-baked-cap.png");
    const garbagePath = join(cacheDir, "garbage.obj");
    writeFileSync(garbagePath, "this is not a mesh\n\x00\x01\x02");
    await page.setInputFiles("#mesh-file", garbagePath);
    await page.waitForFunction(() => document.getElementById("status").className === "error");
    const refusal = await page.textContent("#status");
    check(/garbage\.obj: .*invalid upload/.test(refusal), `a bad mesh is refused with the server's message: "${refusal}"`);

    // 15. A reload finds the jobs on the server.
    const jobsBefore = await page.$$eval("#jobs li", (lis) => lis.length);
    check(pageErrors.length === 0, "no errors in the page" + (pageErrors.length ? ": " + pageErrors.join("; ") : ""));
    await page.reload();
    await page.waitForSelector("body[data-solid]");
    await page.waitForFunction((k) => document.querySelectorAll("#jobs li").length === k, jobsBefore);
    const states = await page.$$eval("#jobs li", (lis) => lis.map((li) => li.dataset.state));
    await cutsSettled();
    check(states.includes("cancelled") && states.includes("done") && (await page.$$("#jobs li a[href$='.glb']")).length >= 1,
      `after a reload the job list shows the server's ${jobsBefore} jobs (${states.join(", ")})`);
    await page.screenshot({ path: join(outDir, "viewer-reloaded.png"), fullPage: true });
    check(pageErrors.length === 0, "no errors in the page" + (pageErrors.length ? ": " + pageErrors.join("; ") : ""));
  } finally {
    await browser.close();
    child.kill("SIGTERM");
    rmSync(cacheDir, { recursive: true, force: true });
  }
  for (const t of timings) console.log("timing: " + t);
  console.log(`e2e took ${((Date.now() - started) / 1000).toFixed(1)} s`);
}

const watchdog = setTimeout(() => {
  console.error(`e2e: timed out after ${TIMEOUT_MS / 1000} s`);
  console.log("e2e: 0 passed, 1 failed");
  process.exit(1);
}, TIMEOUT_MS);

main().then(
  () => { clearTimeout(watchdog); console.log("e2e: 1 passed, 0 failed"); process.exit(0); },
  (e) => { clearTimeout(watchdog); console.error(e); console.log("e2e: 0 passed, 1 failed"); process.exit(1); },
);
