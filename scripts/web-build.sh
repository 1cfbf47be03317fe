#!/usr/bin/env bash
# Rebuilds the dashboard page (ground/web/dist, committed and embedded into the ground
# binary) from ground/web/src with the npm packages pinned by package-lock.json.
# `--check`: fail if the committed dist/ differs from what the sources produce.
set -euo pipefail
cd "$(dirname "$0")/../ground/web"
command -v npm >/dev/null 2>&1 || { echo "web-build: npm is needed (apt-get install nodejs npm)" >&2; exit 1; }
if [ ! -d node_modules ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
    npm ci --no-audit --no-fund
fi
if [ "${1:-}" = "--check" ]; then node build.mjs --check; else node build.mjs; fi
