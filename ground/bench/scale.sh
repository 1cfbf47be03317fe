#!/usr/bin/env bash
# Scale test: N robots (one obsw each, ROBOT_STATUS HK at 10 Hz) driven by one
# `ground run`, archived; checks that no TM is lost (per-APID TM sequence counts have
# no gaps in the archive) and reports the ground's CPU use.
#   ground/bench/scale.sh [ROBOTS] [SECONDS]      (default 50 robots, 20 s)
# Not part of `cargo test` (it takes about SECONDS + 15 s).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-50}"
SECS="${2:-20}"
BASE="${SCALE_BASE_PORT:-20000}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
cargo build --release -q -p obsw -p ground
BIN="$CARGO_TARGET_DIR/release"
WORK="$(mktemp -d)"
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$WORK"; }
trap cleanup EXIT

# One OBSW per robot.
for r in $(seq 1 "$N"); do
    "$BIN/obsw" --robot "$r" --lab-bare-packets --udp "127.0.0.1:$((BASE + r))" --sim-ctl "127.0.0.1:$((BASE + 1000 + r))" \
        >/dev/null 2>"$WORK/obsw-$r.log" &
    PIDS+=($!)
done
sleep 2

# The plan: every robot switches ROBOT_STATUS to 10 Hz, then everybody waits.
PLAN="$WORK/scale.toml"
{
    echo 'name = "scale"'
    for r in $(seq 1 "$N"); do printf '[[robot]]\nnumber = %d\n' "$r"; done
    for r in $(seq 1 "$N"); do
        printf '[[step]]\nid = "hk-%d"\nrobot = %d\naction = "command"\ntc = "HK_SET_INTERVAL"\nargs = { sid = 1, interval_ms = 100 }\n' "$r" "$r"
        printf '[[step]]\nid = "wait-%d"\nrobot = %d\naction = "wait"\nseconds = %s\n' "$r" "$r" "$SECS"
    done
} > "$PLAN"
ROBOTS=()
for r in $(seq 1 "$N"); do ROBOTS+=(--robot "$r=127.0.0.1:$((BASE + r))"); done

DB="$WORK/scale.db"
/usr/bin/time -f "%U %S %e %M" -o "$WORK/time" \
    "$BIN/ground" --archive "$DB" run "$PLAN" --plain --lab-udp "${ROBOTS[@]}" > "$WORK/run.out" 2> "$WORK/run.err" || {
    tail -20 "$WORK/run.out" "$WORK/run.err"; exit 1; }
tail -n 3 "$WORK/run.out" | head -n 2 || true
read -r USR SYS WALL MAXKB < "$WORK/time"

# TM per robot and sequence gaps (lost packets) from the archive.
python3 - "$DB" "$N" "$SECS" "$USR" "$SYS" "$WALL" "$MAXKB" <<'PY'
import sqlite3, sys
db, n, secs, usr, sys_, wall, maxkb = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]), int(sys.argv[7])
c = sqlite3.connect(db)
total = c.execute("select count(*) from packet").fetchone()[0]
corrupt = c.execute("select count(*) from bad_packet").fetchone()[0]
# TM[3,25] whose SID (first two bytes of the source data, byte 21 on) is 1.
hk10 = c.execute("select count(*) from packet where substr(raw, 8, 2) = x'0319' and substr(raw, 21, 2) = x'0001'").fetchone()[0]
gaps = lost = 0
robots = 0
for (apid,) in c.execute("select apid from stream").fetchall():
    robots += 1
    seqs = [s for (s,) in c.execute("select seq from packet where apid = ? order by obt_ms, seq", (apid,))]
    for a, b in zip(seqs, seqs[1:]):
        d = (b - a) % 16384
        if d != 1:
            gaps += 1
            lost += (d - 1) if d > 1 else 0
print(f"robots answering: {robots}/{n}; TM archived: {total} ({corrupt} corrupt), ROBOT_STATUS reports: {hk10} "
      f"(10 Hz x {n} x {secs:.0f} s = {int(10 * n * secs)} expected in the wait)")
print(f"TM sequence gaps: {gaps} (packets lost: {lost})")
print(f"ground CPU: user {usr:.2f} s + sys {sys_:.2f} s over {wall:.1f} s wall = {100 * (usr + sys_) / wall:.1f}% of one core; max RSS {maxkb / 1024:.1f} MiB")
sys.exit(0 if lost == 0 and robots == n else 1)
PY
