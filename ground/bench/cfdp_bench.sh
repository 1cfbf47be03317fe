#!/usr/bin/env bash
# CFDP class 2 file transfers, clean link against the 20 % drop / 5 % duplicate / 5 % corrupt
# relay, measured in the same run (docs/files.md "Measured").
#
#   ground/bench/cfdp_bench.sh [RUNS] [KIB]      (default 5 runs of 256 KiB)
#
# Each run starts a fresh obsw (`--files`) behind a fresh relay (faults 0/0/0 for "clean",
# 0.2/0.05/0.05 both ways for "lossy"), then times `ground file put` and `ground file get` of
# a random KIB-KiB file and checks both copies byte for byte. Prints each run, then medians,
# the lossy/clean ratio, and the clean link's efficiency: file bytes against the raw TM
# frame bytes that reached the ground during the `get` (every TM frame is
# `mib::link::tm_frame::LEN` = 1024 bytes: file data, NAK answers, housekeeping and idle
# frames alike, as `ground file get` counts them). Uses the debug binaries in target/debug
# (`cargo build -p obsw -p ground -p e2e-tests --bins`), or BIN=DIR. TRACE=DIR keeps each
# run's `--trace` of the ground (every PDU in and out, ms) as DIR/<clean|lossy>-<run>-<put|get>.
# BASE=DIR runs the binaries in DIR as a baseline in the same run: each run does BIN's clean
# and lossy transfers and then BASE's, and the summary gives both and their ratio.
set -euo pipefail
RUNS=${1:-5}
KIB=${2:-256}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$ROOT/target/debug}
W=$(mktemp -d /tmp/cfdp-bench.XXXXXX)
trap 'rm -rf "$W"' EXIT
export MMIC_GROUND_LOCK_DIR=$W/locks
mkdir -p "$W/local" "$W/locks"
head -c $((KIB * 1024)) /dev/urandom >"$W/up.bin"
port() { python3 -c 'import socket;s=socket.socket(socket.AF_INET,socket.SOCK_DGRAM);s.bind(("127.0.0.1",0));print(s.getsockname()[1])'; }

# one FAULTS SEED OUT NAME: appends "put_s get_s get_tm_frames" to OUT
one() {
    local faults=$1 seed=$2 out=$3 fr li line ru tmf op rp t0 t1 t2 frames
    # A key folder per variant: the obsw keeps its state there (link counters, its TM
    # store file, whose size is the build's), which another build may refuse.
    local keys=$W/keys-${4%%-*}
    [ -d "$keys" ] || "$X/ground" --no-archive keys create "$keys" --robot 1 >/dev/null 2>&1
    fr=127.0.0.1:$(port)
    li=127.0.0.1:$(port)
    # The last run's outputs go first: a background process truncates its file only when it
    # starts, and a wait on the old file's content went on before it.
    rm -rf "$W/robot" "$W/local/"* "$W/relay.out" "$W/obsw.out"
    mkdir -p "$W/robot"
    "$X/relay" --to-udp "$fr" $faults --seed "$seed" --tm-frames-to "$li" --idle 900 --lifetime 900 \
        </dev/null >"$W/relay.out" &
    rp=$!
    until grep -q RELAY "$W/relay.out" 2>/dev/null; do sleep 0.05; done
    line=$(grep RELAY "$W/relay.out")
    ru=$(sed 's/.*udp=\([^ ]*\).*/\1/' <<<"$line")
    tmf=$(sed 's/.*tm_frames=\([^ ]*\).*/\1/' <<<"$line")
    "$X/obsw" --robot 1 --udp 127.0.0.1:0 --tcp 127.0.0.1:0 --sim-ctl 127.0.0.1:0 --keys "$keys" \
        --frame-udp "$fr" --frame-tm-to "$tmf" --files "$W/robot" >"$W/obsw.out" 2>/dev/null &
    op=$!
    # An obsw that did not start (a port taken between `port` and its bind) ends the run
    # instead of holding it for ever; the caller tries once more with new ports.
    until [ -s "$W/obsw.out" ]; do
        kill -0 "$op" 2>/dev/null || { echo "obsw did not start" >&2; kill "$rp"; wait "$rp" 2>/dev/null; return 1; }
        sleep 0.05
    done
    cp "$W/up.bin" "$W/local/up.bin"
    cd "$W/local"
    local g=("$X/ground" --no-archive file)
    local l=(--robot "1=$ru" --tm-listen "1=$li" --keys "$keys")
    [ -n "${TRACE:-}" ] && l+=(--trace)
    t0=$(date +%s.%N)
    "${g[@]}" put "${l[@]}" up.bin >/dev/null 2>"$W/put.err" || { cat "$W/put.err" >&2; echo "put failed" >&2; }
    t1=$(date +%s.%N)
    cmp -s "$W/up.bin" "$W/robot/up.bin" || echo "put: NOT byte-identical" >&2
    "${g[@]}" get "${l[@]}" up.bin down.bin >"$W/get.out" 2>"$W/get.err" || { cat "$W/get.err" >&2; echo "get failed" >&2; }
    t2=$(date +%s.%N)
    cmp -s "$W/up.bin" "$W/local/down.bin" || echo "get: NOT byte-identical" >&2
    if [ -n "${TRACE:-}" ]; then
        mkdir -p "$TRACE"
        cp "$W/put.err" "$TRACE/$4-$seed-put"
        cp "$W/get.err" "$TRACE/$4-$seed-get"
    fi
    cd "$ROOT"
    kill "$op" 2>/dev/null || true
    wait "$op" 2>/dev/null || true
    # Stopped by hand: with an idle timeout the relay left a transfer half way whenever a
    # loaded machine held the processes back for longer than it.
    kill "$rp" 2>/dev/null || true
    wait "$rp" 2>/dev/null || true
    frames=$(sed -n 's/.*; \([0-9]*\) TM frames.*/\1/p' "$W/get.out")
    echo "$(echo "$t1 - $t0" | bc) $(echo "$t2 - $t1" | bc) ${frames:-0}" >>"$out"
}

median() { sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }

variants=(new)
[ -n "${BASE:-}" ] && variants+=(base)
dir_of() { if [ "$1" = base ]; then echo "$BASE"; else echo "$BIN"; fi; }
for v in "${variants[@]}"; do : >"$W/$v-clean"; : >"$W/$v-lossy"; done
for i in $(seq 1 "$RUNS"); do
    for v in "${variants[@]}"; do
        X=$(dir_of "$v")
        one "" "$i" "$W/$v-clean" "$v-clean" || one "" "$i" "$W/$v-clean" "$v-clean"
        echo "run $i $v clean: put s, get s, TM frames: $(tail -1 "$W/$v-clean")"
        lossy=(--drop 0.2 --duplicate 0.05 --corrupt 0.05)
        one "${lossy[*]}" "$i" "$W/$v-lossy" "$v-lossy" || one "${lossy[*]}" "$i" "$W/$v-lossy" "$v-lossy"
        echo "run $i $v lossy: put s, get s, TM frames: $(tail -1 "$W/$v-lossy")"
    done
done
B=$((KIB * 1024))
for v in "${variants[@]}"; do
    cp_=$(awk '{print $1}' "$W/$v-clean" | median); cg=$(awk '{print $2}' "$W/$v-clean" | median)
    lp=$(awk '{print $1}' "$W/$v-lossy" | median); lg=$(awk '{print $2}' "$W/$v-lossy" | median)
    eff=$(awk -v b=$B '{print b / ($3 * 1024)}' "$W/$v-clean" | median)
    echo "$v ($(dir_of "$v")): medians of $RUNS runs, $KIB KiB class 2:"
    echo "  clean: put $cp_ s ($(echo "$B / $cp_" | bc) B/s), get $cg s ($(echo "$B / $cg" | bc) B/s)"
    echo "  lossy: put $lp s, get $lg s"
    echo "  lossy/clean: put $(echo "scale=2; $lp / $cp_" | bc), get $(echo "scale=2; $lg / $cg" | bc) (done when <= 3)"
    echo "  clean get: file bytes / raw TM frame bytes received during it = $eff (aim >= 0.80)"
done
