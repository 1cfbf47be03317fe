#!/usr/bin/env bash
# Dashboard benchmark: ROBOTS robots with HK at HZ Hz (synthetic feed) in headless
# Chromium for SECONDS per phase; prints update latency (median/p95/p99) and browser,
# renderer and server CPU, fleet view against the same page not drawing HK (baseline).
# Usage: bash ground/bench/dashboard_bench.sh [ROBOTS=50] [HZ=10] [SECONDS=20]
set -euo pipefail
cd "$(dirname "$0")/../.."
bash scripts/chromium-setup.sh >/dev/null
cargo build --release -p ground --example dashboard_demo
cd ground/web
node test/bench.mjs ../../target/release/examples/dashboard_demo "${1:-50}" "${2:-10}" "${3:-20}"
