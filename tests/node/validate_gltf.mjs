// Runs the Khronos glTF validator on each file named on the command line (GLB or glTF): prints every
// error and warning with its JSON pointer, and counts of the informations and hints, which pass. Exits 1
// when any file has an error or a warning, 2 when a file cannot be read or the validator is missing.
// Usage: node tests/node/validate_gltf.mjs FILE...  (the validator: npm ci in tests/node, as
// scripts/install-deps.sh does)
import { readFile } from 'node:fs/promises';
import { basename } from 'node:path';

let validator;
try {
  validator = (await import('gltf-validator')).default;
} catch {
  console.error('validate_gltf: gltf-validator is not installed (bash scripts/install-deps.sh)');
  process.exit(2);
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate_gltf.mjs FILE...');
  process.exit(2);
}

const severities = ['error', 'warning', 'information', 'hint'];
let failed = false;
for (const file of files) {
  let report;
  try {
    const bytes = new Uint8Array(await readFile(file));
    report = await validator.validateBytes(bytes, { uri: basename(file), maxIssues: 0, writeTimestamp: false });
  } catch (error) {
    console.error(`${file}: ${error}`);
    process.exit(2);
  }
  const issues = report.issues;
  const quiet = {};  // informations and hints, counted by code
  for (const m of issues.messages) {
    if (m.severity <= 1) {
      console.log(`${file}: ${severities[m.severity]} ${m.code} at ${m.pointer ?? m.offset ?? ''}: ${m.message}`);
    } else {
      quiet[m.code] = (quiet[m.code] ?? 0) + 1;
    }
  }
  const counts = Object.entries(quiet).map(([code, n]) => `${code} x${n}`).join(', ');
  console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
    `${issues.numInfos} informations, ${issues.numHints} hints${counts ? ` (${counts})` : ''}`);
  if (issues.numErrors > 0 || issues.numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
