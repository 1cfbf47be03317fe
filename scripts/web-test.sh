#!/usr/bin/env bash
# Dashboard browser test: installs Debian's chromium and the pinned npm packages,
# checks that the committed page bundle matches its sources, then drives the real page
# in headless Chromium against `ground collect --http` following two real obsw processes
# (ground/web/test/e2e.mjs).
# Screenshots go to docs/img/ when SHOTS=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/chromium-setup.sh
bash scripts/web-build.sh --check
cargo build --bin obsw -p obsw --bin ground -p ground
shots=""
if [ "${SHOTS:-0}" = 1 ]; then mkdir -p docs/img; shots="$(pwd)/docs/img"; fi
cd ground/web
node test/e2e.mjs ../../target/debug/ground ../../target/debug/obsw $shots
