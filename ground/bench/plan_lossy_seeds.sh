#!/usr/bin/env bash
# The on-board demo plan through the 20/5/5 lab relay (tests/tests/plan_e2e.rs,
# `the_demo_plan_on_board_through_a_lossy_ground_link_...`) over many relay seeds: how
# often it passes and how long the ground's run took.
#
#   cargo build -p obsw -p ground --bins && cargo test -p e2e-tests --test plan_e2e --no-run
#   nice -n 19 ground/bench/plan_lossy_seeds.sh RUNS [FIRST_SEED]
#
# Run i gives robot 1's relay seed FIRST_SEED + 2i and robot 2's the next (the test's
# `PLAN_LOSSY_SEED`), so no two runs share a seed. FIRST_SEED defaults to 35, the test's
# own. One line per run (seed, pass or fail, wall-clock seconds of the test, the ground
# run's seconds and the relays' counts from the test's output), then the pass count and the
# medians. A failing run's output is kept in ${TMPDIR:-/tmp}/plan-lossy-SEED.out.
# Binaries from target/debug unless BIN=DIR; the test executable is the newest
# target/debug/deps/plan_e2e-* unless TEST=PATH.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$ROOT/target/debug}
RUNS=${1:-20}
SEED0=${2:-35}
TEST=${TEST:-$(ls -t "$ROOT"/target/debug/deps/plan_e2e-* 2>/dev/null | grep -v '\.d$' | head -1)}
[[ -x $TEST ]] || { echo "no test executable: cargo test -p e2e-tests --test plan_e2e --no-run" >&2; exit 2; }
NAME=the_demo_plan_on_board_through_a_lossy_ground_link_gives_the_same_summary_and_runs_each_step_once
WORK=$(mktemp -d "${TMPDIR:-/tmp}/plan-lossy.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
OUT=$WORK/out
# Copies of the binaries, given to the test so that it does not run cargo itself and a
# build during the batch does not change them under it.
cp "$BIN/obsw" "$BIN/ground" "$TEST" "$WORK/" || exit 2
TEST=$WORK/$(basename "$TEST")
export OBSW_BIN=$WORK/obsw GROUND_BIN=$WORK/ground
PASS=0
WALL=()
RUN=()
for ((i = 0; i < RUNS; i++)); do
    seed=$((SEED0 + 2 * i))
    t0=$(date +%s.%N)
    PLAN_LOSSY_SEED=$seed "$TEST" --exact "$NAME" --nocapture --test-threads 1 >"$OUT" 2>&1
    rc=$?
    t1=$(date +%s.%N)
    secs=$(python3 -c "print(f'{$t1 - $t0:.1f}')")
    WALL+=("$secs")
    line=$(grep -ho "on board through 20/5/5[^;]*" "$OUT" | tail -1)
    ran=$(sed -n 's/.*: \([0-9.]*\) s$/\1/p' <<<"$line")
    [[ -n $ran ]] && RUN+=("$ran")
    if ((rc == 0)); then
        PASS=$((PASS + 1))
        echo "seed $seed: pass in $secs s | ${line:-no run line}"
    else
        cp "$OUT" "${TMPDIR:-/tmp}/plan-lossy-$seed.out"
        why=$(grep -h -m1 -A2 "panicked at" "$OUT" | tr '\n' ' ' | cut -c1-300)
        echo "seed $seed: FAIL (exit $rc) in $secs s | ${line:-no run line} | $why"
    fi
done
median() { printf '%s\n' "$@" | sort -n | awk '{a[NR]=$1} END {print (NR ? a[int((NR+1)/2)] : "-")}'; }
echo "on-board demo through 20/5/5: $PASS of $RUNS passed (seeds $SEED0.. step 2); median test $(median "${WALL[@]}") s, median ground run $(median "${RUN[@]:-}") s"
