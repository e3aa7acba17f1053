#!/usr/bin/env node
// Runs the Khronos glTF validator (npm package `gltf-validator`, pinned in package.json)
// on glTF / GLB files and prints a summary plus every issue.
//
//   (cd tools && npm install --no-audit --no-fund)   # once
//   node tools/validate_gltf.mjs FILE.glb [FILE.gltf ...]
//
// Exit status: 0 when no file has an error (warnings, infos and hints are printed but
// do not fail), 1 when some file has errors, 2 on a usage error, an unreadable file, or
// a file the validator cannot even parse as glTF/GLB. External resources of a .gltf
// (buffers, images) are loaded relative to the file and validated too.

import { readFile } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

const SEVERITY = ['error', 'warning', 'info', 'hint'];
// Enough to see what is wrong without flooding a test log with thousands of repeats.
const MAX_PRINTED = 100;

async function validateFile(file) {
  let bytes;
  try {
    bytes = new Uint8Array(await readFile(file));
  } catch (e) {
    console.error(`${file}: cannot read: ${e.message}`);
    return 2;
  }
  const dir = path.dirname(path.resolve(file));
  let report;
  try {
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0, // unlimited: the counts must be exact
      writeTimestamp: false,
      externalResourceFunction: async (uri) =>
        new Uint8Array(await readFile(path.resolve(dir, decodeURIComponent(uri)))),
    });
  } catch (e) {
    console.error(`${file}: the validator could not process it: ${e}`);
    return 2;
  }

  const issues = report.issues;
  console.log(
    `${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
      `${issues.numInfos} infos, ${issues.numHints} hints` +
      (report.validatorVersion ? ` (gltf-validator ${report.validatorVersion})` : ''),
  );
  const messages = issues.messages ?? [];
  for (const m of messages.slice(0, MAX_PRINTED)) {
    const where = m.pointer ?? (m.offset !== undefined ? `byte ${m.offset}` : '');
    const sev = SEVERITY[m.severity] ?? `severity ${m.severity}`;
    console.log(`  ${sev} ${m.code}${where ? ` at ${where}` : ''}: ${m.message}`);
  }
  if (messages.length > MAX_PRINTED) {
    console.log(`  ... and ${messages.length - MAX_PRINTED} more`);
  }
  return issues.numErrors === 0 ? 0 : 1;
}

const files = process.argv.slice(2);
if (files.length === 0 || files.some((f) => f === '-h' || f === '--help')) {
  console.error('usage: node tools/validate_gltf.mjs FILE.glb|FILE.gltf [...]');
  console.error('exit 0 iff no file has validation errors');
  process.exit(2);
}
let status = 0;
for (const f of files) {
  status = Math.max(status, await validateFile(f));
}
process.exit(status);
