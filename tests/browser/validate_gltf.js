// Validates a .glb with the Khronos glTF validator (npm `gltf-validator`).
// Usage: node validate_gltf.js FILE.glb
// Prints the validator's JSON report on stdout; exits 1 when the report has
// errors (`issues.numErrors > 0`), 2 on a usage or read error.
'use strict';

const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function main() {
  const file = process.argv[2];
  if (!file) {
    console.error('usage: node validate_gltf.js FILE.glb');
    process.exit(2);
  }
  const bytes = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    // A .glb carries its buffers; an external URI is itself an error to report.
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri} not allowed`)),
  });
  console.log(JSON.stringify(report, null, 2));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
}

main().catch((e) => {
  console.error(`validate_gltf: ${e && e.stack ? e.stack : e}`);
  process.exit(2);
});
