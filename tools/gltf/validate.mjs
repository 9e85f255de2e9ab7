// Validates .glb files with the Khronos glTF-Validator (npm `gltf-validator`) and exits 1 if
// any file has an error. Usage: node tools/gltf/validate.mjs FILE.glb... (install the validator
// first: npm install --prefix tools/gltf).
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error("usage: node tools/gltf/validate.mjs FILE.glb...");
  process.exit(2);
}
let failed = 0;
for (const file of files) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file,
    maxIssues: 50,
  });
  const i = report.issues;
  console.log(
    `${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints` +
      ` (${report.info?.drawCallCount ?? "?"} draw calls, ${report.info?.totalVertexCount ?? "?"} vertices, validator ${report.validatorVersion})`,
  );
  for (const m of i.messages.filter((m) => m.severity <= 1)) {
    console.log(`  ${m.severity === 0 ? "error" : "warning"} ${m.code} at ${m.pointer ?? "-"}: ${m.message}`);
  }
  if (i.numErrors > 0) failed += 1;
}
process.exit(failed > 0 ? 1 : 0);
