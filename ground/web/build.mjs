// Builds the dashboard page into dist/ (committed, embedded into the ground binary by
// include_str!). `node build.mjs --check` rebuilds into a temporary folder and fails if
// dist/ differs from what the sources produce (run by scripts/web-test.sh).
import * as esbuild from 'esbuild';
import { copyFileSync, mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const check = process.argv.includes('--check');
const out = check ? mkdtempSync(join(tmpdir(), 'dash-')) : join(here, 'dist');

await esbuild.build({
  entryPoints: { app: join(here, 'src/app.js') },
  bundle: true,
  minify: true,
  format: 'iife',
  target: ['chrome100', 'firefox100', 'safari15'],
  outdir: out,
  legalComments: 'eof',
  logLevel: 'warning',
});
copyFileSync(join(here, 'src/index.html'), join(out, 'index.html'));

if (check) {
  let stale = [];
  for (const f of ['index.html', 'app.js', 'app.css']) {
    const a = readFileSync(join(out, f));
    const b = readFileSync(join(here, 'dist', f));
    if (!a.equals(b)) stale.push(f);
  }
  rmSync(out, { recursive: true, force: true });
  if (stale.length) {
    console.error(`ground/web/dist is stale (${stale.join(', ')}): run \`bash scripts/web-build.sh\` and commit dist/`);
    process.exit(1);
  }
  console.log('ground/web/dist matches the sources');
}
