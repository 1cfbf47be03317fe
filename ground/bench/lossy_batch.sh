#!/usr/bin/env bash
# Several cases of ground/bench/lossy_link.sh one after the other, with the machine's load
# beside them, and one Markdown table at the end (the form of docs/space-link.md's).
#
#   ground/bench/lossy_batch.sh OUT CASE:RUNS:FIRST_SEED ...
#   e.g. BIN=target/bench-bin TMPDIR=target/bench-tmp \
#        ground/bench/lossy_batch.sh target/bench-tmp/b1 ping:50:7401 send:50:7501
#
# OUT (created): CASE.log per case (every run's line and the tally), load.log (`uptime`
# every 30 s while the batch runs), table.md. Failed runs keep their files in OUT
# (lossy_link.sh's KEEP). BIN, TMPDIR, PORT_LO, PORT_HI pass on to lossy_link.sh; the
# priority is the caller's (run it under `nice -n 19`, or not, and say which).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
OUT=${1:?OUT folder, then CASE:RUNS:FIRST_SEED ...}
shift
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
(while :; do echo "$(date -u +%H:%M:%S) $(uptime | sed 's/.*load average: //')"; sleep 30; done) >>"$OUT/load.log" &
sampler=$!
trap 'kill $sampler 2>/dev/null' EXIT
rows=()
for spec in "$@"; do
    IFS=: read -r case runs seed <<<"$spec"
    start=$(date -u +%H:%M)
    KEEP=$OUT "$ROOT/ground/bench/lossy_link.sh" "$case" "$runs" "$seed" >"$OUT/$case.log" 2>&1
    end=$(date -u +%H:%M)
    tally=$(grep "^$case: " "$OUT/$case.log" | tail -1)
    # Load averages (1 min) sampled while this case ran.
    load=$(awk -v a="$start" -v b="$end" '{t=substr($1,1,5)} t>=a && t<=b {gsub(",","",$2); print $2}' "$OUT/load.log" |
        sort -n | awk 'NR==1{lo=$1} {hi=$1} END {if (NR) printf "%s–%s", lo, hi; else print "?"}')
    rows+=("$case|$runs ($seed–$((seed + runs - 1)))|$tally|$start–$end UTC|$load")
    echo "$spec done: $tally"
done
{
    echo "| case | runs (seeds) | exit codes | median (max) | false \"lost\" | archive not exactly once | not started | time | load (1 min) |"
    echo "|---|---|---|---|---|---|---|---|---|"
    for r in "${rows[@]}"; do
        IFS='|' read -r case runs tally when load <<<"$r"
        codes=$(sed -n 's/.*exit codes: *\([^;]*\);.*/\1/p' <<<"$tally")
        med=$(sed -n 's/.*median \([^;]*\);.*/\1/p' <<<"$tally")
        fl=$(sed -n "s/.*with a live robot): \([0-9]*\);.*/\1/p" <<<"$tally")
        ab=$(sed -n 's/.*archive not exactly once: \([0-9]*\).*/\1/p' <<<"$tally")
        ns=$(sed -n 's/.*(\([0-9]*\) more did not start).*/\1/p' <<<"$tally")
        echo "| $case | $runs | $codes | $med | $fl | $ab | $ns | $when | $load |"
    done
} | tee "$OUT/table.md"
