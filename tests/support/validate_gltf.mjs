// Runs the Khronos glTF validator (npm package gltf-validator) on .gltf/.glb files.
//
//   node tests/support/validate_gltf.mjs [--baseline SOURCE] FILE...
//
// Prints, per file, the error/warning/info counts and every error and warning, and exits 0 iff no file has an
// error (1 when some file has errors, 2 when a file or the validator cannot be loaded).
//
// External resources (buffers, images) are read relative to each file's folder; a missing one is an error.
//
// --baseline SOURCE: errors that SOURCE itself already has (same code and JSON pointer) are reported as
// "inherited" and not counted, so a round trip can be checked for "no new errors" when its source is not clean:
// two corpus assets list a child node as a scene root, and three reference texture files that were dropped from
// the corpus (lodforge carries both unchanged). Without --baseline every error counts.
//
// The validator module is looked up in $LODFORGE_GLTF_VALIDATOR (a folder), else in
// <repo>/tools/node/node_modules/gltf-validator (where scripts/test.sh installs it).

import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const moduleDir = process.env.LODFORGE_GLTF_VALIDATOR ||
    path.resolve(here, '..', '..', 'tools', 'node', 'node_modules', 'gltf-validator');

const args = process.argv.slice(2);
let baseline = null;
if (args[0] === '--baseline') {
  baseline = args[1];
  args.splice(0, 2);
}
if (args.length === 0 || (baseline !== null && !baseline)) {
  console.error('usage: node validate_gltf.mjs [--baseline SOURCE] FILE...');
  process.exit(2);
}

let validator;
try {
  validator = createRequire(import.meta.url)(moduleDir);
} catch (e) {
  console.error(`cannot load gltf-validator from ${moduleDir}: ${e.message}`);
  process.exit(2);
}

// Validates one file; returns its messages.
async function validate(file) {
  const bytes = fs.readFileSync(file);
  const folder = path.dirname(path.resolve(file));
  const report = await validator.validateBytes(new Uint8Array(bytes), {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
      fs.readFile(path.resolve(folder, decodeURIComponent(uri)), (err, data) => {
        if (err) reject(err.toString());
        else resolve(new Uint8Array(data));
      });
    }),
  });
  return report.issues.messages;
}

const key = (m) => `${m.code} ${m.pointer || ''}`;
let inheritedKeys = new Set();
try {
  if (baseline) inheritedKeys = new Set((await validate(baseline)).filter((m) => m.severity === 0).map(key));
} catch (e) {
  console.error(`cannot validate baseline ${baseline}: ${e.message || e}`);
  process.exit(2);
}

const severityName = ['error', 'warning', 'info', 'hint'];
let failed = false;
for (const file of args) {
  let messages;
  try {
    messages = await validate(file);
  } catch (e) {
    console.error(`cannot validate ${file}: ${e.message || e}`);
    process.exit(2);
  }
  let errors = 0, inherited = 0, warnings = 0, infos = 0;
  const lines = [];
  for (const m of messages) {
    let label = severityName[m.severity] || 'info';
    if (m.severity === 0 && inheritedKeys.has(key(m))) {
      ++inherited;
      label = 'inherited-error';
    } else if (m.severity === 0) {
      ++errors;
    } else if (m.severity === 1) {
      ++warnings;
    } else {
      ++infos;
    }
    if (m.severity <= 1) lines.push(`  ${label} ${m.code} ${m.pointer || ''}: ${m.message}`);
  }
  console.log(`${file}: ${errors} errors, ${inherited} inherited errors, ${warnings} warnings, ` +
              `${infos} infos/hints`);
  for (const l of lines) console.log(l);
  if (errors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
