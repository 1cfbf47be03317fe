#!/usr/bin/env bash
# TM decode rate of `ground decode` (one core) against the Python `spacepackets`
# package on the same file of HK packets, in the same run.
#   ground/bench/decode_bench.sh [PACKETS]     (default 1000000)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-1000000}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
cargo build --release -q -p ground --bin ground --example gen_hk
BIN="$CARGO_TARGET_DIR/release"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
FMT="$("$BIN/examples/gen_hk" "$N" "$WORK/hk.bin")"
echo "file: $N TM[3,25] ROBOT_STATUS packets, $(stat -c %s "$WORK/hk.bin") bytes"

PIN=""
command -v taskset >/dev/null && PIN="taskset -c 0"

# ground: best of 3 (decode to structs, no per-packet output).
best=0
for _ in 1 2 3; do
    line="$($PIN "$BIN/ground" decode --summary "$WORK/hk.bin" 2>&1 >/dev/null | tail -1)"
    rate="$(echo "$line" | sed -E 's/.*; ([0-9]+) packets\/s.*/\1/')"
    [ "$rate" -gt "$best" ] && best="$rate"
done
echo "ground decode: $best packets/s (best of 3, one core)"

# Python spacepackets in the repository's .venv.
if [ ! -x "$ROOT/.venv/bin/python" ]; then
    python3 -m venv "$ROOT/.venv"
fi
if ! "$ROOT/.venv/bin/python" -c 'import spacepackets' 2>/dev/null; then
    "$ROOT/.venv/bin/pip" install --quiet --disable-pip-version-check spacepackets
fi
PYN=$(( N < 200000 ? N : 200000 ))
head -c "$(( $(stat -c %s "$WORK/hk.bin") / N * PYN ))" "$WORK/hk.bin" > "$WORK/hk-py.bin"
pyline="$($PIN "$ROOT/.venv/bin/python" "$ROOT/ground/bench/py_decode.py" "$WORK/hk-py.bin" "$FMT")"
echo "$pyline (first $PYN packets)"
pyrate="$(echo "$pyline" | sed -E 's/.*= ([0-9]+) packets\/s/\1/')"
echo "ratio: $(( best / (pyrate > 0 ? pyrate : 1) ))x"
