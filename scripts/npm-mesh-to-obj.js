// Writes the {positions, cells} mesh exported by an npm mesh package as OBJ.
// Usage: node npm-mesh-to-obj.js PACKAGE_DIR OUT.obj
'use strict';
const fs = require('fs');
const path = require('path');
const [dir, out] = process.argv.slice(2);
const pkg = JSON.parse(fs.readFileSync(path.join(dir, 'package.json'), 'utf8'));
const mesh = require(path.resolve(dir, pkg.main || 'index.js'));
if (!Array.isArray(mesh.positions) || !Array.isArray(mesh.cells)) {
  console.error(`${dir}: package does not export positions and cells`);
  process.exit(1);
}
const lines = [`# ${pkg.name}@${pkg.version}: ${mesh.positions.length} vertices, ${mesh.cells.length} faces`];
for (const p of mesh.positions) lines.push(`v ${p[0]} ${p[1]} ${p[2]}`);
for (const c of mesh.cells) lines.push('f ' + c.map((i) => i + 1).join(' '));
fs.writeFileSync(out + '.tmp', lines.join('\n') + '\n');
fs.renameSync(out + '.tmp', out);
