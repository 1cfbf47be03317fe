#!/usr/bin/env bash
# Time to complete plans/demo.toml driven from the ground vs run on board, in the same
# conditions: two fresh host obsws per run (authenticated team link, the simulator at
# --speed S), the ground on the bare-packet lab link, runs alternating so that both see
# the same machine load. Reports each run's time (the summary's `seconds`: from the run's
# start to the last step's completion, upload included for on board), the medians and the
# ratio on-board / ground-driven.
#
#   scripts/plan-onboard-bench.sh [RUNS] [SPEED]      (default 5 runs each, speed 4)
#
# Needs `cargo build -p obsw -p ground` (binaries from target/debug, or BIN_DIR).
set -euo pipefail
runs=${1:-5}
speed=${2:-4}
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${BIN_DIR:-$root/target/debug}
plan=$root/plans/demo.toml
work=$(mktemp -d "${TMPDIR:-/tmp}/plan-bench.XXXXXX")
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    rm -rf "$work"
}
trap cleanup EXIT

free_port() { python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

head -c 32 /dev/urandom > "$work/team.key"
chmod 600 "$work/team.key"

# Starts robots 1 and 2 in $1; prints "UDP1 UDP2".
start_pair() {
    local d=$1 t1 t2 u1 u2
    mkdir -p "$d"
    t1=127.0.0.1:$(free_port); t2=127.0.0.1:$(free_port)
    u1=127.0.0.1:$(free_port); u2=127.0.0.1:$(free_port)
    "$bin/obsw" --robot 1 --lab-bare-packets --udp "$u1" --tcp "$u1" --sim-ctl 127.0.0.1:0 \
        --team-udp "$t1" --peer "2=$t2" --team-state "$d/t1.state" --team-key "$work/team.key" \
        --initial-state Xneg --speed "$speed" > "$d/o1.out" 2> /dev/null &
    pids+=($!)
    "$bin/obsw" --robot 2 --lab-bare-packets --udp "$u2" --tcp "$u2" --sim-ctl 127.0.0.1:0 \
        --team-udp "$t2" --peer "1=$t1" --team-state "$d/t2.state" --team-key "$work/team.key" \
        --initial-state Xpos --speed "$speed" > "$d/o2.out" 2> /dev/null &
    pids+=($!)
    for f in "$d/o1.out" "$d/o2.out"; do
        for _ in $(seq 100); do grep -q READY "$f" 2>/dev/null && break; sleep 0.1; done
    done
    echo "$u1 $u2"
}

stop_pair() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    pids=()
}

# One run of mode $1 (ground|onboard) number $2: prints its seconds.
one() {
    local mode=$1 n=$2 d=$work/$1-$2 addrs extra=()
    addrs=$(start_pair "$d")
    read -r u1 u2 <<< "$addrs"
    [ "$mode" = onboard ] && extra=(--on-board)
    "$bin/ground" --no-archive run --lab-udp "$plan" --robot "1=$u1" --robot "2=$u2" --plain --json \
        "${extra[@]}" > "$d/summary.json" 2> "$d/ground.err"
    stop_pair
    python3 - "$d/summary.json" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
assert s["done"] == len(s["steps"]) == 10, s
print(f'{s["seconds"]:.2f}')
EOF
}

g=(); o=()
for i in $(seq "$runs"); do
    g+=("$(one ground "$i")")
    o+=("$(one onboard "$i")")
    echo "run $i: ground-driven ${g[-1]} s, on board ${o[-1]} s" >&2
done
python3 - "${g[*]}" "${o[*]}" "$speed" <<'EOF'
import statistics, sys
g = [float(x) for x in sys.argv[1].split()]
o = [float(x) for x in sys.argv[2].split()]
mg, mo = statistics.median(g), statistics.median(o)
print(f"plans/demo.toml, 2 robots, simulator speed x{sys.argv[3]}, {len(g)} runs each")
print(f"ground-driven: median {mg:.2f} s  (runs {', '.join(f'{x:.2f}' for x in g)})")
print(f"on board:      median {mo:.2f} s  (runs {', '.join(f'{x:.2f}' for x in o)})")
print(f"ratio on board / ground-driven: {mo / mg:.3f}")
EOF
