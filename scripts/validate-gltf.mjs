#!/usr/bin/env node
// Validates a .glb/.gltf file with the Khronos glTF validator.
//
//   node scripts/validate-gltf.mjs FILE
//
// Prints the report's `issues` object (numErrors, numWarnings, numInfos, numHints, messages)
// as JSON on stdout. Exit status: 0 when numErrors == 0, 1 when there are errors, 2 when the
// file or the validator cannot be read. The validator is loaded from
// $GLTF_VALIDATOR_DIR/node_modules/gltf-validator, GLTF_VALIDATOR_DIR defaulting to
// <repo>/target/test-assets/gltf-validator.
import { createRequire } from 'node:module';
import { readFileSync, existsSync } from 'node:fs';
import { dirname, join, resolve, basename } from 'node:path';
import { fileURLToPath } from 'node:url';

// `snerf export-gltf --validate` pipes this script to node on stdin and always sets
// GLTF_VALIDATOR_DIR; run from a checkout, the default is beside the script.
const dir = resolve(process.env.GLTF_VALIDATOR_DIR
  || join(resolve(dirname(fileURLToPath(import.meta.url)), '..'), 'target', 'test-assets', 'gltf-validator'));
const file = process.argv[2];
if (!file) {
  console.error('usage: node scripts/validate-gltf.mjs FILE.glb');
  process.exit(2);
}
const pkg = join(dir, 'node_modules', 'gltf-validator');
if (!existsSync(pkg)) {
  console.error(`glTF validator not found at ${pkg} (set GLTF_VALIDATOR_DIR)`);
  process.exit(2);
}
let validator, bytes;
try {
  validator = createRequire(join(dir, 'package.json'))('gltf-validator');
  bytes = new Uint8Array(readFileSync(file));
} catch (e) {
  console.error(String(e));
  process.exit(2);
}
try {
  const report = await validator.validateBytes(bytes, { uri: basename(file), maxIssues: 1000 });
  console.log(JSON.stringify(report.issues, null, 2));
  process.exit(report.issues.numErrors === 0 ? 0 : 1);
} catch (e) {
  console.error(`validation failed: ${e}`);
  process.exit(2);
}
