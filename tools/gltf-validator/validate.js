// Validates a glTF file with the Khronos glTF validator (npm `gltf-validator`); prints every
// issue and exits 1 when there are errors. Used by kage's pack tests: `node validate.js FILE`.
const fs = require('fs');
const validator = require('gltf-validator');
const file = process.argv[2];
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {maxIssues: 100})
  .then((r) => {
    const i = r.issues;
    console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos`);
    for (const m of i.messages) console.log(`  [${m.severity}] ${m.code}: ${m.message} ${m.pointer || ''}`);
    process.exit(i.numErrors > 0 ? 1 : 0);
  })
  .catch((e) => { console.error(e); process.exit(2); });
