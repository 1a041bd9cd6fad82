// End-to-end test of `solidsynth serve`, driven as a person would use it, in headless Chromium
// (Debian's /usr/bin/chromium through playwright-core; no browser download).
//
// Uses the binary SOLIDSYNTH_BIN (.ci/run passes the one `cargo test` built), else builds it with
// `cargo build` (dev profile); starts the server on a free loopback port, then:
// loads the page, runs a synthesis (picks an exemplar and seed, clicks Synthesize, sees progress),
// moves the cut slider with the keyboard, checks that a new cut image arrived from the server and
// that its latency is shown, checks the WebGL view rendered, and saves a screenshot; then switches
// the 3D view to the bunny (a triangle mesh), checks it drew, that the cut removes part of it and
// that moving the plane changes it, and saves screenshots of it.
// Prints "e2e: N passed, N failed" and exits non-zero on failure.

import { chromium } from "playwright-core";
import { spawn, execFileSync } from "node:child_process";
import { mkdirSync, mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const repo = join(here, "..");
const outDir = join(here, "out");
const CHROMIUM = process.env.CHROMIUM || "/usr/bin/chromium";
const TIMEOUT_MS = 240_000;

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
  try {
    const page = await browser.newPage({ viewport: { width: 1280, height: 980 } });
    const pageErrors = [];
    page.on("pageerror", (e) => pageErrors.push(e.message));
    page.on("console", (m) => { if (m.type() === "error") pageErrors.push(m.text()); });
    const cuts = [];
    page.on("response", (r) => { if (r.url().includes("/cut?")) cuts.push(r); });
    page.setDefaultTimeout(120_000);

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
    const before = Number(await page.getAttribute("#cut-image", "data-count"));
    const srcBefore = await page.getAttribute("#cut-image", "src");

    // 4. Move the cut slider as a person would: focus it, arrow keys.
    await page.focus("#cut-offset");
    for (let i = 0; i < 6; i++) await page.keyboard.press("ArrowRight");
    check((await page.inputValue("#cut-offset")) === "6", "the offset slider moved to 6");
    // Moves made while a cut was in flight coalesce into one follow-up request: wait until the
    // page has no cut in flight or pending, and a newer image is shown.
    await page.waitForFunction((n) => !view.cutBusy && !view.cutAgain
      && Number(document.getElementById("cut-image").dataset.count) > n, before);
    const last = cuts[cuts.length - 1];
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

    await page.screenshot({ path: join(outDir, "viewer.png"), fullPage: true });
    check(true, "screenshot saved to viewer-test/out/viewer.png");

    // 7. The bunny: a triangle mesh (/bunny.bin) drawn with WebGL2, textured by the solid and cut
    // by the free plane.
    const mesh = await page.request.get(new URL("/bunny.bin", url).toString());
    const meshBytes = await mesh.body();
    const [nv, nt] = [meshBytes.readUInt32LE(0), meshBytes.readUInt32LE(4)];
    check(mesh.status() === 200 && meshBytes.length === 8 + 12 * nv + 6 * nt && nt > 1000,
      `the bunny mesh is served (${nv} vertices, ${nt} triangles)`);
    // Reads the 3D view back: the share of the centre region (the middle half on each axis) that
    // is not background, and the share of all pixels that changed since the previous call.
    const viewStats = () => page.$eval("#view3d", (c) => {
      const gl = c.getContext("webgl2");
      const w = c.width, h = c.height, px = new Uint8Array(4 * w * h);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
      const bg = [18, 18, 20];
      let centre = 0, inCentre = 0, changed = 0;
      const prev = window.lastView;
      for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
        const i = 4 * (y * w + x);
        if (x >= w / 4 && x < 3 * w / 4 && y >= h / 4 && y < 3 * h / 4) {
          inCentre++;
          if ([0, 1, 2].some((k) => Math.abs(px[i + k] - bg[k]) > 6)) centre++;
        }
        if (prev && [0, 1, 2].some((k) => Math.abs(px[i + k] - prev[i + k]) > 12)) changed++;
      }
      window.lastView = px;
      return { centre: centre / inCentre, changed: prev ? changed / (w * h) : null };
    });
    const settle = () => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    await page.selectOption("#shape", "1");
    await page.waitForFunction(() => document.getElementById("view3d").dataset.shape === "bunny");
    await settle();
    const bunny = await viewStats();
    check(bunny.centre > 0.3, `the bunny covers ${(100 * bunny.centre).toFixed(0)}% of the view's centre`);
    await page.locator("#view3d").screenshot({ path: join(outDir, "bunny.png") });
    check(true, "screenshot saved to viewer-test/out/bunny.png");
    // Without the cut the picture differs (the plane removes part of the bunny)...
    await page.uncheck("#clip");
    await settle();
    const whole = await viewStats();
    check(whole.changed > 0.02, `unchecking the cut changes ${(100 * whole.changed).toFixed(0)}% of the view`);
    await page.locator("#view3d").screenshot({ path: join(outDir, "bunny-whole.png") });
    await page.check("#clip");
    await settle();
    await viewStats();
    // ...and moving the plane moves the cut.
    const beforeMove = Number(await page.getAttribute("#cut-image", "data-count"));
    await page.focus("#cut-offset");
    for (let i = 0; i < 12; i++) await page.keyboard.press("ArrowLeft");
    check((await page.inputValue("#cut-offset")) === "-6", "the offset slider moved to -6");
    await page.waitForFunction((n) => !view.cutBusy && !view.cutAgain
      && Number(document.getElementById("cut-image").dataset.count) > n, beforeMove);
    await settle();
    const moved = await viewStats();
    check(moved.changed > 0.02, `moving the cut changes ${(100 * moved.changed).toFixed(0)}% of the bunny view`);
    check(moved.centre > 0.3, `the cut bunny still covers ${(100 * moved.centre).toFixed(0)}% of the view's centre`);
    await page.locator("#view3d").screenshot({ path: join(outDir, "bunny-cut.png") });
    // Dragging turns it.
    const box = await page.locator("#view3d").boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.mouse.down();
    await page.mouse.move(box.x + box.width / 2 + 70, box.y + box.height / 2, { steps: 5 });
    await page.mouse.up();
    await settle();
    const turned = await viewStats();
    check(turned.changed > 0.02, `dragging turns the bunny (${(100 * turned.changed).toFixed(0)}% of the view changed)`);
    await page.locator("#view3d").screenshot({ path: join(outDir, "bunny-turned.png") });
    await page.screenshot({ path: join(outDir, "viewer-bunny.png"), fullPage: true });
    check(true, "screenshots saved to viewer-test/out/bunny-{whole,cut,turned}.png, viewer-bunny.png");
    check(pageErrors.length === 0, "no errors in the page" + (pageErrors.length ? ": " + pageErrors.join("; ") : ""));
  } finally {
    await browser.close();
    child.kill("SIGTERM");
    rmSync(cacheDir, { recursive: true, force: true });
  }
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
