#!/usr/bin/env node
// Validate a glTF 2.0 file (.glb or .gltf) with the official Khronos glTF validator.
//
// Usage: node tools/gltf_validate.mjs FILE.glb [--full]
//
// Prints one JSON object on stdout: the validator's issue summary (numErrors, numWarnings,
// numInfos, numHints), the error and warning messages, and the asset info. With --full it
// prints the complete validator report instead. Exit status: 0 when numErrors == 0,
// 1 when the file has validation errors, 2 when it cannot be read or validated.
//
// Install the validator once with:  npm ci --prefix tools   (see tools/package.json)
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");

const args = process.argv.slice(2);
const full = args.includes("--full");
const files = args.filter((a) => !a.startsWith("--"));
if (files.length !== 1) {
  console.error("usage: node tools/gltf_validate.mjs FILE.glb [--full]");
  process.exit(2);
}
const file = files[0];

let bytes;
try {
  bytes = new Uint8Array(readFileSync(file));
} catch (err) {
  console.error(`${file}: cannot read (${err.code || err.message})`);
  process.exit(2);
}

const dir = path.dirname(path.resolve(file));
try {
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // 0 = unlimited
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        try {
          resolve(new Uint8Array(readFileSync(path.resolve(dir, decodeURIComponent(uri)))));
        } catch (err) {
          reject(err.toString());
        }
      }),
  });
  const issues = report.issues;
  const summary = full
    ? report
    : {
        validator: `${report.validatorVersion}`,
        uri: report.uri,
        mimeType: report.mimeType,
        numErrors: issues.numErrors,
        numWarnings: issues.numWarnings,
        numInfos: issues.numInfos,
        numHints: issues.numHints,
        truncated: issues.truncated,
        messages: issues.messages
          .filter((m) => m.severity <= 1)
          .map((m) => ({ code: m.code, severity: m.severity === 0 ? "error" : "warning", pointer: m.pointer, message: m.message })),
        infoCodes: [...new Set(issues.messages.filter((m) => m.severity > 1).map((m) => m.code))],
        info: report.info,
      };
  console.log(JSON.stringify(summary, null, 2));
  process.exit(issues.numErrors > 0 ? 1 : 0);
} catch (err) {
  console.error(`${file}: validation failed (${err})`);
  process.exit(2);
}
