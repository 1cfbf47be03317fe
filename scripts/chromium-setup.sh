#!/usr/bin/env bash
# Installs what the dashboard browser tests need: Debian's `chromium` (driven headless
# over the DevTools protocol) and the page's npm packages (pinned by
# ground/web/package-lock.json). Idempotent: does nothing when both are present.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
    $SUDO apt-get update -q
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends chromium
fi
command -v node >/dev/null 2>&1 || { echo "chromium-setup: node and npm are needed (apt-get install nodejs npm)" >&2; exit 1; }
if [ ! -d ground/web/node_modules ] || [ ground/web/package-lock.json -nt ground/web/node_modules/.package-lock.json ]; then
    (cd ground/web && npm ci --no-audit --no-fund)
fi
chromium --version
