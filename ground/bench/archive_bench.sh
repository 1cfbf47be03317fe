#!/usr/bin/env bash
# Archive benchmark: ingest rate, re-import, size on disk, a one-parameter query, a CSV
# export of one parameter and a plot of the whole file — `ground` against a baseline in
# the same run (Python's sqlite3 storing bare packets as rows, one-parameter questions
# answered by decoding the packets). Medians of RUNS runs; every ingest into a new file.
#   ground/bench/archive_bench.sh [PACKETS] [RUNS]    (default 300000 packets = 8.3 h of
#                                                      10 Hz HK, 3 runs)
# With ARCHIVE_BENCH_PG=1 the same file is also imported into a throwaway PostgreSQL
# (scripts/postgres-test.sh: Unix socket, fsync off) and compared with SQLite's ingest
# of the same run.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
N="${1:-300000}"
RUNS="${2:-3}"
PARAM=V_BAT_A
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
cd "$ROOT"
cargo build --release -q -p ground --bin ground --example gen_hk
BIN="$CARGO_TARGET_DIR/release"
G="$BIN/ground"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
FMT="$("$BIN/examples/gen_hk" "$N" "$WORK/hk.bin")"
RAW=$(stat -c %s "$WORK/hk.bin")
echo "file: $N TM[3,25] ROBOT_STATUS packets (10 Hz), $RAW bytes; medians of $RUNS runs"

# The parameter's field in the HK structure and its calibration, from the MIB.
"$G" mib export --format json --out "$WORK/mib" > /dev/null
read -r FIELD SCALE OFFSET < <(python3 - "$WORK/mib/mmic-i.mib.json" "$PARAM" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
p = next(p for p in d["parameters"] if p["name"] == sys.argv[2])
hk = next(h for h in d["hk_structures"] if h["name"] == "ROBOT_STATUS")
print(hk["params"].index(p["id"]) + 1, p["calibration"]["scale"], p["calibration"]["offset"])
PY
)

ms() { local s e; s=$(date +%s%N); "$@" > /dev/null 2>&1; e=$(date +%s%N); echo $(( (e - s) / 1000000 )); }
median() { tr ' ' '\n' | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
rate() { awk -v n="$1" -v ms="$2" 'BEGIN {printf "%.0f", n * 1000 / (ms > 0 ? ms : 1)}'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.2f", a / b}'; }
size() { local t=0 f; for f in "$1" "$1-wal" "$1-shm"; do [ -f "$f" ] && t=$(( t + $(stat -c %s "$f") )); done; echo "$t"; }

T_LO=1767225600000
T_HI=$(( T_LO + 3600000 ))   # one hour

g_in=() ; p_in=() ; g_re=() ; g_q=() ; p_q=() ; g_ex=() ; p_ex=() ; g_pl=()
for r in $(seq "$RUNS"); do
    DB="$WORK/g$r.db"; PDB="$WORK/p$r.db"
    g_in+=("$(ms "$G" --archive "$DB" archive import "$WORK/hk.bin" --robot 1)")
    p_in+=("$(ms python3 "$ROOT/ground/bench/py_archive.py" ingest "$WORK/hk.bin" "$PDB")")
    g_re+=("$(ms "$G" --archive "$DB" archive import "$WORK/hk.bin" --robot 1)")
    g_q+=("$(ms "$G" --archive "$DB" archive export --csv --type hk --param "$PARAM" --since "$T_LO" --until "$T_HI" --out "$WORK/q.csv")")
    p_q+=("$(ms python3 "$ROOT/ground/bench/py_archive.py" query "$PDB" "$FMT" "$FIELD" "$SCALE" "$OFFSET" "$T_LO" "$T_HI")")
    g_ex+=("$(ms "$G" --archive "$DB" archive export --csv --type hk --param "$PARAM" --out "$WORK/g.csv")")
    p_ex+=("$(ms python3 "$ROOT/ground/bench/py_archive.py" export "$PDB" "$FMT" "$FIELD" "$SCALE" "$OFFSET" "$WORK/p.csv")")
    g_pl+=("$(ms "$G" --archive "$DB" archive plot "$PARAM" --out "$WORK/plot.png")")
done

# Correctness of what was timed.
"$G" --archive "$WORK/g1.db" archive import "$WORK/hk.bin" --robot 1 > "$WORK/re.txt"
grep -q " 0 stored, $N already archived" "$WORK/re.txt" || { echo "re-import stored something:"; cat "$WORK/re.txt"; exit 1; }
rows=$(( $(wc -l < "$WORK/g.csv") - 1 ))
[ "$rows" -eq "$N" ] || { echo "export has $rows rows, $N expected"; exit 1; }
"$G" --archive "$WORK/g1.db" archive check > "$WORK/check.txt" || { cat "$WORK/check.txt"; exit 1; }

GS=$(size "$WORK/g1.db"); PS=$(size "$WORK/p1.db")
gi=$(echo "${g_in[*]}" | median); pi=$(echo "${p_in[*]}" | median)
printf '%-34s %14s %14s\n' "" "ground" "baseline"
printf '%-34s %14s %14s\n' "ingest (packets/s)" "$(rate "$N" "$gi")" "$(rate "$N" "$pi")"
printf '%-34s %14s %14s\n' "re-import, nothing added (ms)" "$(echo "${g_re[*]}" | median)" "-"
printf '%-34s %14s %14s\n' "size on disk (bytes)" "$GS" "$PS"
printf '%-34s %14s %14s\n' "size / raw packet bytes" "$(ratio "$GS" "$RAW")" "$(ratio "$PS" "$RAW")"
printf '%-34s %14s %14s\n' "query $PARAM, 1 hour (ms)" "$(echo "${g_q[*]}" | median)" "$(echo "${p_q[*]}" | median)"
printf '%-34s %14s %14s\n' "export $PARAM, $N rows CSV (ms)" "$(echo "${g_ex[*]}" | median)" "$(echo "${p_ex[*]}" | median)"
printf '%-34s %14s %14s\n' "plot $PARAM, whole file PNG (ms)" "$(echo "${g_pl[*]}" | median)" "-"
echo "(times include process start; the baseline's ingest runs in one process without CRC checks)"

if [ "${ARCHIVE_BENCH_PG:-0}" = 1 ]; then
    PGDIR="/tmp/archive-bench-pg-$$"   # the server user must reach it (not in the 0700 $WORK)
    URL=$(bash "$ROOT/scripts/postgres-test.sh" start "$PGDIR" $$)
    PSQL=$(ls /usr/lib/postgresql/*/bin/psql | head -1)
    pq_in=() ; pq_re=()
    for r in $(seq "$RUNS"); do
        "$PSQL" -q "$URL" -c "CREATE DATABASE bench$r" > /dev/null
        DBURL="${URL/\/postgres?//bench$r?}"
        pq_in+=("$(ms "$G" --archive "$DBURL" archive import "$WORK/hk.bin" --robot 1)")
        pq_re+=("$(ms "$G" --archive "$DBURL" archive import "$WORK/hk.bin" --robot 1)")
    done
    DBURL="${URL/\/postgres?//bench1?}"
    "$G" --archive "$DBURL" archive import "$WORK/hk.bin" --robot 1 > "$WORK/pre.txt"
    grep -q " 0 stored, $N already archived" "$WORK/pre.txt" || { echo "PostgreSQL re-import stored something:"; cat "$WORK/pre.txt"; exit 1; }
    "$G" --archive "$DBURL" archive check > "$WORK/pcheck.txt" || { cat "$WORK/pcheck.txt"; exit 1; }
    qi=$(echo "${pq_in[*]}" | median)
    echo
    printf '%-34s %14s %14s\n' "" "PostgreSQL" "SQLite"
    printf '%-34s %14s %14s\n' "ingest (packets/s)" "$(rate "$N" "$qi")" "$(rate "$N" "$gi")"
    printf '%-34s %14s %14s\n' "re-import, nothing added (ms)" "$(echo "${pq_re[*]}" | median)" "$(echo "${g_re[*]}" | median)"
    echo "PostgreSQL ingest / SQLite ingest: $(ratio "$gi" "$qi")"
    bash "$ROOT/scripts/postgres-test.sh" stop "$PGDIR"
fi
