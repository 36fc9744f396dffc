// Validate glTF 2.0 files with the Khronos glTF-Validator (npm gltf-validator). Prints the report summary as
// JSON on stdout; exit code 0 when no errors, 1 when the asset has errors, 2 on usage or I/O errors.
import { readFileSync } from "node:fs";
import validator from "gltf-validator";

const files = process.argv.slice(2);
if (!files.length) {
  console.error("usage: node validate-gltf.mjs FILE.glb|FILE.gltf ...");
  process.exit(2);
}
let failed = false;
for (const file of files) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), { maxIssues: 50 });
  const { numErrors, numWarnings } = report.issues;
  if (numErrors > 0) failed = true;
  console.log(JSON.stringify({ file, numErrors, numWarnings, messages: report.issues.messages.slice(0, 20),
    info: report.info }));
}
process.exit(failed ? 1 : 0);
