// Validates binary glTF files with the Khronos glTF validator: every file given must have zero
// errors and zero warnings (infos and hints are printed, not failed on).
// Usage: node validate-gltf.mjs FILE.glb...
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

let failed = false;
for (const path of process.argv.slice(2)) {
  const data = new Uint8Array(await readFile(path));
  const report = await validator.validateBytes(data, { uri: path, maxIssues: 100 });
  const { numErrors, numWarnings, numInfos, numHints } = report.issues;
  console.log(`${path}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos, ${numHints} hints`);
  for (const m of report.issues.messages) {
    console.log(`  [${["error", "warning", "info", "hint"][m.severity]}] ${m.code}: ${m.message} (${m.pointer ?? ""})`);
  }
  if (numErrors > 0 || numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
