#!/usr/bin/env bash
# Dashboard benchmark against the real thing: ROBOTS `obsw` processes (ROBOT_STATUS HK
# at HZ Hz, commanded by the collector's configuration) followed by one
# `ground collect --http`, whose page is shown in headless Chromium for SECONDS per phase.
# Prints update latency (HK on-board time → value drawn, median/p95/p99), renderer and
# Chromium CPU, the collector's CPU and the obsw processes' CPU, fleet view against the
# same page not drawing HK (baseline), and the time to draw a day of 10 Hz V_BAT_A
# (864 000 samples imported into the collector's archive before it starts).
# Usage: bash ground/bench/dashboard_bench.sh [ROBOTS=50] [HZ=10] [SECONDS=20]
# Not part of `cargo test`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-50}"
HZ="${2:-10}"
SECS="${3:-20}"
BASE="${DASH_BENCH_BASE_PORT:-31000}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
bash scripts/chromium-setup.sh >/dev/null
cargo build --release -q -p obsw -p ground --bin obsw --bin ground --example gen_hk
BIN="$CARGO_TARGET_DIR/release"
WORK="$(mktemp -d)"
PIDS=()
CPID=""
cleanup() {
    [ -n "$CPID" ] && kill "$CPID" 2>/dev/null || true
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    rm -rf "$WORK"
}
trap cleanup EXIT

# A day of 10 Hz V_BAT_A (robot 1) ending now, in the collector's archive.
NOW_MS=$(($(date +%s%3N)))
"$BIN/examples/gen_hk" 864000 "$WORK/day.bin" $((NOW_MS - 86400000 - 60000)) > /dev/null
"$BIN/ground" --archive "$WORK/a.db" archive import "$WORK/day.bin" --robot 1 > /dev/null

INTERVAL=$((1000 / HZ))
echo 'transport = "lab-udp"' > "$WORK/collect.toml"   # the bare-packet lab link
for n in $(seq 1 "$N"); do
    "$BIN/obsw" --robot "$n" --lab-bare-packets --udp "127.0.0.1:$((BASE + 2 * n))" --sim-ctl "127.0.0.1:$((BASE + 2 * n + 1))" \
        --seed "$n" > /dev/null 2>&1 &
    PIDS+=($!)
    printf '[[robot]]\nnumber = %d\naddr = "127.0.0.1:%d"\nhk_interval_ms = %d\n' "$n" $((BASE + 2 * n)) "$INTERVAL" \
        >> "$WORK/collect.toml"
done
WEB="127.0.0.1:$((BASE + 1))"
"$BIN/ground" --archive "$WORK/a.db" collect --plain --config "$WORK/collect.toml" --http "$WEB" \
    2> "$WORK/collect.log" &
CPID=$!
for _ in $(seq 1 100); do
    curl -sf "http://$WEB/api/mib" > /dev/null 2>&1 && break
    sleep 0.2
done
cd ground/web
node test/bench.mjs "http://$WEB/" "$CPID" "$(IFS=,; echo "${PIDS[*]}")" "$N" "$HZ" "$SECS"
