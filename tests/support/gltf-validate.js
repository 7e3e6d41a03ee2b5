// Validates a glTF or GLB file with the Khronos glTF validator (npm package gltf-validator)
// and prints its report as JSON.
// Usage: node gltf-validate.js VALIDATOR_DIR FILE
//   VALIDATOR_DIR: a directory with node_modules/gltf-validator (`npm install --prefix DIR gltf-validator`)
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require(path.join(path.resolve(process.argv[2]), "node_modules", "gltf-validator"));
const bytes = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(bytes, { maxIssues: 200 }).then(
  (report) => process.stdout.write(JSON.stringify(report)),
  (error) => { console.error(String(error)); process.exit(1); });
