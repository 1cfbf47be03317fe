#!/usr/bin/env bash
# Collector benchmark: ROBOTS obsw (ROBOT_STATUS HK at 10 Hz, commanded by the
# collector's config) followed by one `ground collect` for MINUTES. Samples the
# collector's CPU % and RSS every 10 s; at the end stops the obsws, lets the collector
# fill what is left, stops it with SIGTERM and checks the archive against what each obsw
# really sent (its --tm-log when the obsw has one, else the sequence counts): packets
# lost, packets stored twice.
#   ground/bench/collect_bench.sh [ROBOTS] [MINUTES]      (default 50 robots, 10 min)
# Not part of `cargo test`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-50}"
MIN="${2:-10}"
BASE="${COLLECT_BENCH_BASE_PORT:-21000}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
# COLLECT_BENCH_BIN: a directory with prebuilt `obsw` and `ground` (for long runs while
# the tree is rebuilt); otherwise they are built here.
if [ -n "${COLLECT_BENCH_BIN:-}" ]; then
    BIN="$COLLECT_BENCH_BIN"
else
    cargo build --release -q -p obsw -p ground
    BIN="$CARGO_TARGET_DIR/release"
fi
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

TMLOG=0
if "$BIN/obsw" --help | grep -q -- --tm-log; then TMLOG=1; fi

CFG="$WORK/collector.toml"
{
    echo 'transport = "lab-udp"'   # the bare-packet lab link: the collector's own cost
    for r in $(seq 1 "$N"); do
        printf '[[robot]]\nnumber = %d\naddr = "127.0.0.1:%d"\nhk_interval_ms = 100\n' "$r" "$((BASE + r))"
    done
} > "$CFG"
"$BIN/ground" collect --check-config "$CFG" >/dev/null

for r in $(seq 1 "$N"); do
    EXTRA=()
    [ "$TMLOG" = 1 ] && EXTRA=(--tm-log "$WORK/tm-$r.hex")
    "$BIN/obsw" --robot "$r" --lab-bare-packets --udp "127.0.0.1:$((BASE + r))" --sim-ctl "127.0.0.1:$((BASE + 1000 + r))" \
        "${EXTRA[@]}" >/dev/null 2>"$WORK/obsw-$r.log" &
    PIDS+=($!)
done
sleep 2

DB="$WORK/collect.db"
"$BIN/ground" --archive "$DB" collect --config "$CFG" --plain 2> "$WORK/collect.log" &
CPID=$!

# CPU % (of one core) and RSS of the collector every 10 s.
TCK=$(getconf CLK_TCK)
SAMPLES="$WORK/samples.txt"
sample() { # prints "cpu_ticks rss_kb"
    local stat rss
    stat=$(cut -d' ' -f14,15 "/proc/$CPID/stat")
    rss=$(awk '/VmRSS/ {print $2}' "/proc/$CPID/status")
    echo "$(( ${stat% *} + ${stat#* } )) $rss"
}
END=$(( $(date +%s) + MIN * 60 ))
read -r T0 _ < <(sample)
W0=$(date +%s.%N)
while [ "$(date +%s)" -lt "$END" ]; do
    sleep 10
    read -r T1 RSS < <(sample)
    W1=$(date +%s.%N)
    awk -v t0="$T0" -v t1="$T1" -v w0="$W0" -v w1="$W1" -v tck="$TCK" -v rss="$RSS" -v el="$(( $(date +%s) - END + MIN * 60 ))" \
        'BEGIN { printf "%d %.1f %d\n", el, 100 * (t1 - t0) / tck / (w1 - w0), rss }' >> "$SAMPLES"
    T0=$T1; W0=$W1
done

# Stop the obsws first (nothing more is sent), give the collector time to fill the
# last holes, then SIGTERM it.
for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
sleep 5
T_STOP=$(date +%s.%N)
kill -TERM "$CPID"
set +e
wait "$CPID"
CODE=$?
set -e
CPID=""
cp "$WORK/collect.log" "${TMPDIR:-/tmp}/collect_bench_last.log" 2>/dev/null || true
STOP_S=$(awk -v a="$T_STOP" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')

python3 - "$DB" "$N" "$MIN" "$SAMPLES" "$WORK" "$TMLOG" "$CODE" "$STOP_S" <<'PY'
import sqlite3, sys, os
db, n, mins, samples, work, tmlog, code, stop_s = sys.argv[1:9]
n = int(n)
c = sqlite3.connect(db)
rows = c.execute("select apid, seq, obt_ms, count(*) from packet group by apid, seq, obt_ms").fetchall()
archived = {}
twice = 0
for apid, seq, obt, k in rows:
    archived.setdefault(apid, set()).add((seq, obt))
    twice += k - 1
total = sum(len(v) for v in archived.values())
def parse_hex(path):
    out = set()
    with open(path) as f:
        for line in f:
            b = bytes.fromhex(line.strip())
            if len(b) < 20: continue
            apid = ((b[0] << 8) | b[1]) & 0x7FF
            seq = ((b[2] << 8) | b[3]) & 0x3FFF
            days = (b[14] << 8) | b[15]
            ms = int.from_bytes(b[16:20], "big")
            obt = (days - 4383) * 86400000 + ms
            out.add((apid, seq, obt))
    return out
lost = 0
sent_total = 0
if tmlog == "1":
    for r in range(1, n + 1):
        p = os.path.join(work, f"tm-{r}.hex")
        if not os.path.exists(p): continue
        sent = parse_hex(p)
        sent_total += len(sent)
        for apid, seq, obt in sent:
            if (seq, obt) not in archived.get(apid, set()):
                lost += 1
    judge = "against each obsw's --tm-log"
else:
    for apid, s in archived.items():
        seqs = sorted(x[0] for x in s)
        lost += (seqs[-1] - seqs[0] + 1) - len(set(seqs))
    sent_total = total
    judge = "from sequence-count continuity (obsw has no --tm-log)"
hk10 = c.execute("select count(*) from packet where substr(raw, 8, 2) = x'0319'").fetchone()[0]
lines = [l.split() for l in open(samples)]
def avg(ls, i): return sum(float(l[i]) for l in ls) / max(1, len(ls))
k = max(1, min(3, len(lines) // 3))
first, last = lines[:k], lines[-k:]
print(f"robots {n}, {mins} min, HK 10 Hz: {total} TM archived ({hk10} HK), sent {sent_total}")
print(f"lost {lost}, stored twice {twice}  (judged {judge})")
print(f"collector CPU % of one core: start {avg(first,1):.1f}, end {avg(last,1):.1f}, mean {avg(lines,1):.1f}")
print(f"collector RSS: start {int(avg(first,2))} kB, end {int(avg(last,2))} kB, max {max(int(l[2]) for l in lines)} kB")
print(f"SIGTERM: exit {code} after {stop_s} s")
print("samples (s, cpu %, rss kB): " + "; ".join(" ".join(l) for l in lines))
if lost or twice or code != "0":
    sys.exit(1)
PY
