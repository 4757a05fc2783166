// Validates a glTF file with the Khronos glTF validator (npm `gltf-validator`); prints every
// issue and exits 1 when there are errors. Used by kage's tests: `node validate.js FILE`.
// Buffers and images the file names by relative URI are read from beside it.
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');
const file = process.argv[2];
const beside = (uri) => new Promise((resolve, reject) => {
  fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (e, data) => (e ? reject(e.toString()) : resolve(new Uint8Array(data))));
});
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {maxIssues: 100, externalResourceFunction: beside})
  .then((r) => {
    const i = r.issues;
    console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos`);
    for (const m of i.messages) console.log(`  [${m.severity}] ${m.code}: ${m.message} ${m.pointer || ''}`);
    process.exit(i.numErrors > 0 ? 1 : 0);
  })
  .catch((e) => { console.error(e); process.exit(2); });
