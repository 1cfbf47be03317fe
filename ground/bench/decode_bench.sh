#!/usr/bin/env bash
# Decode rate of `ground decode` (text and --json, one core) against two Python peers on
# the same file of HK packets, all in the same run:
#   - space-packet-parser decoding the file into named values from our XTCE export
#     (`ground mib export --format xtce`), the full-decode peer;
#   - Python `spacepackets` unpacking the headers only (no MIB), for reference.
# Every rate is the median of RUNS runs (default 5), each pinned to one core.
#   ground/bench/decode_bench.sh [PACKETS] [RUNS]     (default 1000000 packets, 5 runs)
# The Python peers decode the first PY_PACKETS packets (default 100000) of the same file:
# they are 10-1000x slower, and their per-packet rate does not depend on the file length.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-1000000}"
RUNS="${2:-5}"
PYN="${PY_PACKETS:-100000}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
cargo build --release -q -p ground --bin ground --example gen_hk
bash "$ROOT/scripts/python-env.sh" >/dev/null
BIN="$CARGO_TARGET_DIR/release"
PY="$ROOT/.venv/bin/python"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
"$BIN/examples/gen_hk" "$N" "$WORK/hk.bin" >/dev/null
"$BIN/ground" mib export --format xtce --out "$WORK/xtce" >/dev/null
XTCE="$(ls "$WORK"/xtce/*.xml | head -1)"
PYN=$(( N < PYN ? N : PYN ))
head -c "$(( $(stat -c %s "$WORK/hk.bin") / N * PYN ))" "$WORK/hk.bin" > "$WORK/hk-py.bin"
echo "file: $N TM[3,25] ROBOT_STATUS packets, $(stat -c %s "$WORK/hk.bin") bytes; Python peers: first $PYN packets; median of $RUNS runs"

PIN=""
command -v taskset >/dev/null && PIN="taskset -c 0"

median() { sort -n | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : int((a[NR/2]+a[NR/2+1])/2))}'; }
rate_of() { sed -E 's/.*[=;] ([0-9]+) packets\/s.*/\1/'; }

# The JSON output must be valid and complete: checked once, outside the timed runs.
"$BIN/ground" decode --json "$WORK/hk-py.bin" 2>/dev/null | "$PY" -c '
import json, sys
n = 0
for line in sys.stdin:
    p = json.loads(line)
    assert p["type"] == "tm" and p["name"] == "HK_REPORT" and "error" not in p, line
    assert len(p["body"]["params"]) > 0
    n += 1
print(f"JSON check: {n} lines, all valid, every packet decoded")'

# space-packet-parser must decode every packet too (no "bad" ones).
"$PY" "$ROOT/ground/bench/py_decode.py" spp "$XTCE" "$WORK/hk-py.bin" | grep -q "(0 bad" \
    || { echo "space-packet-parser does not decode every packet of the file" >&2; exit 1; }

text=(); json=(); spp=(); sp=()
for _ in $(seq "$RUNS"); do
    text+=("$($PIN "$BIN/ground" decode "$WORK/hk.bin" 2>&1 >/dev/null | tail -1 | rate_of)")
    json+=("$($PIN "$BIN/ground" decode --json "$WORK/hk.bin" 2>&1 >/dev/null | tail -1 | rate_of)")
    spp+=("$($PIN "$PY" "$ROOT/ground/bench/py_decode.py" spp "$XTCE" "$WORK/hk-py.bin" | rate_of)")
    sp+=("$($PIN "$PY" "$ROOT/ground/bench/py_decode.py" spacepackets "$WORK/hk-py.bin" | rate_of)")
done
T=$(printf '%s\n' "${text[@]}" | median)
J=$(printf '%s\n' "${json[@]}" | median)
S=$(printf '%s\n' "${spp[@]}" | median)
P=$(printf '%s\n' "${sp[@]}" | median)
echo "ground decode (text):                       $T packets/s   runs: ${text[*]}"
echo "ground decode --json:                       $J packets/s   runs: ${json[*]}"
echo "space-packet-parser (XTCE, named values):   $S packets/s   runs: ${spp[*]}"
echo "python spacepackets (headers only):         $P packets/s   runs: ${sp[*]}"
awk -v t="$T" -v j="$J" -v s="$S" -v p="$P" 'BEGIN {
    printf "ratios (medians): text %.1fx and JSON %.1fx space-packet-parser; text %.1fx and JSON %.1fx spacepackets\n",
        t / s, j / s, t / p, j / p }'
