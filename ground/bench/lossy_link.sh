#!/usr/bin/env bash
# The ground CLI over the space link through the project's lossy relay (tests/bin/relay.rs:
# 20 % drop, 5 % duplicate, 5 % corrupt, both directions, seeded), against a fresh obsw per
# run: how often each verb ends with the exit code its case should give, how long it took,
# and whether a live robot was ever called lost. Also: a robot that really goes silent
# (kill -STOP of the obsw under `ground watch`) and how long the ground took to say so.
#
#   cargo build -p obsw -p ground --bins && cargo build -p e2e-tests --bin relay
#   (one command with --bin relay would build the relay only and leave the others stale)
#   ground/bench/lossy_link.sh CASE RUNS [FIRST_SEED]
#
# CASE: checkout (plans/checkout.toml), plan3 (a three-step plan), ping, send, mode,
# silent. One line per run (case, seed, exit code, seconds, the last stderr line), then
# a tally of exit codes and the median time. Binaries from target/debug unless BIN=DIR.
# Expected: checkout, plan3, send, mode exit 0; ping exit 0; silent exit 5 within
# LINK_LOSS_MS (2.5 s) plus the poll (stated in the message). "lost" (exit 5), "another
# APID" (7) or "nothing heard" (8) with a live robot is a false loss and is counted as such.
#
# The archive, judged from the obsw's own TM log (`--tm-log`, ground/bench/archive_once.py):
# for checkout and plan3, every packet the obsw sent with a count in the run's TM range
# (the summary's "complete from seq FROM up to seq UPTO", FROM being the run's first packet)
# is in the archive exactly once; for every case, each archived packet is one the obsw sent
# and none is archived twice. A run whose check fails is counted in the tally's "archive".
#
# What the relay saw (its `--trace`, ground/bench/relay_gaps.py), on every run's line: the
# longest time the obsw sent no TM frame, the longest time no intact frame went on to the
# ground, and the time from the last intact one to the ground's exit — to tell a silent
# obsw, a relay not scheduled (a gap, then a burst) and a ground that missed what came.
# A failed run (non-zero exit where 0 is expected, or the archive check) keeps its files in
# KEEP (default: TMPDIR or /tmp) as lossy-CASE-SEED.*: the obsw's TM log, stdout and
# stderr, the relay's trace, the ground's stdout, stderr and archive.
# The obsw's on-board TM store (PUS 15) is a fresh file per run unless KEEP_STORE=1, where
# one store file serves every run of the batch and fills with what the runs before sent, or
# TM_STORE=FILE, where every run starts from a copy of FILE (a full store:
# `cargo run --release -p obsw-core --example fill_store -- FILE 1 30000`), so each store
# retrieval has a full store behind it (docs/space-link.md, "A deep on-board store"). The
# link's counter state is kept across runs either way (the ground's TM IV window needs it).
# PORT_LO, PORT_HI: the range the script's own ports come from (default 32000-32767; give
# two batches run side by side disjoint ranges, or they can take each other's ports).
#
# Figures (40 checkout, 50 each of plan3, ping, send, mode, 10 silent; seeds, exit codes,
# medians, archive) and what the non-zero exits were: docs/space-link.md, "Liveness and the
# run's start over frames".
set -u
PORT_LO=${PORT_LO:-32000}
PORT_HI=${PORT_HI:-32767}
KEEP=${KEEP:-${TMPDIR:-/tmp}}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$ROOT/target/debug}
CASE=${1:?case: checkout plan3 ping send mode silent}
RUNS=${2:-5}
SEED0=${3:-1}
WORK=$(mktemp -d "${TMPDIR:-/tmp}/lossy-link-$CASE.XXXXXX")
# Only this shell cleans up: a background command's subshell killed before it execs would
# otherwise run the trap too (and remove the work folder under the batch).
trap '[[ $BASHPID == "$$" ]] && { kill $(jobs -p) 2>/dev/null; rm -rf "$WORK"; }' EXIT
"$BIN/ground" --no-archive keys create "$WORK/keys" --robot 1 >/dev/null 2>&1

# A port free now for a child to bind later (the relay's target, the ground's TM port),
# from 32000-32767: below the kernel's ephemeral range (32768-60999), where every socket
# bound to port 0 (the obsw's, the relay's, other programs') gets its port, and above the
# range the end-to-end tests hand out (tests/src.rs `free_port`, 10000-31999), so a batch
# beside a test run takes neither's ports.
# Two distinct ports in one probe (two probes could both pick the same free port: the
# obsw's frame port and the ground's TM port then collide, 1 run in a few hundred).
free_ports() {
    PORT_LO=$PORT_LO PORT_HI=$PORT_HI python3 - <<'PY'
import os, random, socket
lo, hi = int(os.environ["PORT_LO"]), int(os.environ["PORT_HI"])
held, ports = [], []
for _ in range(400):
    port = random.randint(lo, hi)
    if port in ports:
        continue
    try:
        t = socket.socket(socket.AF_INET, socket.SOCK_STREAM); t.bind(("127.0.0.1", port))
        u = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); u.bind(("127.0.0.1", port))
    except OSError:
        continue
    held += [t, u]
    ports.append(port)
    if len(ports) == 2:
        print(*ports)
        break
else:
    raise SystemExit(f"no two free ports in {lo}-{hi}")
PY
}

cat >"$WORK/plan3.toml" <<'EOF'
name = "three-steps"
description = "Three TCs in a row: HK rate, OPERATIONAL, STANDBY"

[[robot]]
number = 1
initial_state = "Xneg"

[[step]]
id = "hk"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 1000 }

[[step]]
id = "operational"
robot = 1
action = "mode"
confirm = true
mode = "operational"
after = ["hk"]

[[step]]
id = "standby"
robot = 1
action = "mode"
confirm = true
mode = "standby"
after = ["operational"]
EOF

declare -A TALLY
TIMES=()
FALSE_LOST=0
ARCHIVE_BAD=0
NOSTART=0
for ((i = 0; i < RUNS; i++)); do
    seed=$((SEED0 + i))
    # A shared machine's /tmp may be cleaned under a long batch: stop rather than count
    # runs that never ran (TMPDIR=DIR puts the work folder elsewhere).
    [[ -d $WORK/keys ]] || { echo "lossy_link: the work folder $WORK vanished; stopped before seed $seed" >&2; exit 3; }
    read -r frame tmport < <(free_ports)
    store=$WORK/tm-store.bin
    if [[ -n ${TM_STORE:-} ]]; then
        cp "$TM_STORE" "$store"
    elif [[ ${KEEP_STORE:-0} != 1 ]]; then
        store=$WORK/tm-store-$seed.bin
        rm -f "$store"
    fi
    # The relay: TC frames to the obsw's frame port, TM frames to the ground's address.
    coproc RELAY { exec "$BIN/relay" --to-udp "127.0.0.1:$frame" --drop 0.20 --duplicate 0.05 --corrupt 0.05 \
        --seed "$seed" --tm-frames-to "127.0.0.1:$tmport" --idle 60 --lifetime 900 --trace "$WORK/relay.trace" 2>/dev/null; }
    rpid=$RELAY_PID
    read -r line <&"${RELAY[0]}"
    relay_udp=$(sed -n 's/.*udp=\([^ ]*\).*/\1/p' <<<"$line")
    relay_tm=$(sed -n 's/.*tm_frames=\([^ ]*\).*/\1/p' <<<"$line")
    "$BIN/obsw" --robot 1 --udp 127.0.0.1:0 --tcp 127.0.0.1:0 --sim-ctl 127.0.0.1:0 --seed "$seed" \
        --frame-udp "127.0.0.1:$frame" --frame-tm-to "$relay_tm" \
        --tc-key "$WORK/keys/robot-1/tc-spi1.key" --tm-key "$WORK/keys/robot-1/tm-spi17.key" \
        --link-state "$WORK/obsw-link.state" --tm-store "$store" --tm-log "$WORK/obsw-tm.log" >"$WORK/obsw.out" 2>"$WORK/obsw.err" &
    obsw=$!
    ready=0
    for _ in $(seq 300); do grep -q READY "$WORK/obsw.out" 2>/dev/null && { ready=1; break; }; sleep 0.1; done
    if ((!ready)); then
        # Not a run: the ground would only meet an obsw still starting.
        echo "$CASE seed $seed: obsw not READY within 30 s; not counted ($(tail -1 "$WORK/obsw.err" 2>/dev/null))"
        cp "$WORK/obsw.err" "$KEEP/lossy-$CASE-$seed.notready.err" 2>/dev/null
        NOSTART=$((NOSTART + 1))
        kill "$obsw" "$rpid" 2>/dev/null
        wait "$obsw" "$rpid" 2>/dev/null
        continue
    fi
    link=(--keys "$WORK/keys" --robot "1=$relay_udp" --tm-listen "1=127.0.0.1:$tmport")
    arch=(--archive "$WORK/a-$seed.db")
    t0=$(date +%s.%N)
    case $CASE in
    checkout) "$BIN/ground" "${arch[@]}" run "$ROOT/plans/checkout.toml" "${link[@]}" --plain >"$WORK/out" 2>"$WORK/err" ;;
    plan3) "$BIN/ground" "${arch[@]}" run "$WORK/plan3.toml" "${link[@]}" --plain >"$WORK/out" 2>"$WORK/err" ;;
    ping) "$BIN/ground" "${arch[@]}" ping "${link[@]}" -c 1 >"$WORK/out" 2>"$WORK/err" ;;
    send) "$BIN/ground" "${arch[@]}" send "${link[@]}" HK_SET_INTERVAL sid=1 interval_ms=1000 >"$WORK/out" 2>"$WORK/err" ;;
    mode) "$BIN/ground" "${arch[@]}" mode "${link[@]}" operational --confirm >"$WORK/out" 2>"$WORK/err" ;;
    silent)
        "$BIN/ground" "${arch[@]}" watch "${link[@]}" >"$WORK/out" 2>"$WORK/err" &
        g=$!
        sleep 5
        kill -STOP "$obsw"
        t0=$(date +%s.%N)
        wait "$g"
        ;;
    *) echo "unknown case $CASE" >&2; exit 2 ;;
    esac
    rc=$?
    rc_archive=0
    t1=$(date +%s.%N)
    kill -CONT "$obsw" 2>/dev/null
    kill "$obsw" 2>/dev/null
    wait "$obsw" 2>/dev/null
    kill "$rpid" 2>/dev/null
    wait "$rpid" 2>/dev/null
    secs=$(python3 -c "print(f'{$t1 - $t0:.1f}')")
    TIMES+=("$secs")
    TALLY[$rc]=$((${TALLY[$rc]:-0} + 1))
    # The robot runs: "heard, then lost" (5), "another APID" (7) or "nothing heard" (8)
    # would be false.
    if [[ $CASE != silent && ($rc == 5 || $rc == 7 || $rc == 8) ]]; then FALSE_LOST=$((FALSE_LOST + 1)); fi
    last=$(grep -v '^\s*$' "$WORK/err" | tail -1)
    tm=$(grep -h "^TM robot" "$WORK/out" "$WORK/err" 2>/dev/null | tail -1)
    range=()
    case $CASE in
    checkout | plan3)
        # A run must state its TM complete from its first packet; no such line, no range,
        # and the check fails on it.
        read -r from upto < <(sed -n 's/^TM robot 1: complete from seq \([0-9]*\) up to seq \([0-9]*\).*/\1 \2/p' <<<"$tm")
        range=("${from:-x}" "${upto:-x}")
        ;;
    esac
    if [[ ${range[0]:-} == x ]]; then
        archive="archive: no complete TM range in the summary"
        ARCHIVE_BAD=$((ARCHIVE_BAD + 1))
        rc_archive=1
    elif ! archive=$(python3 "$ROOT/ground/bench/archive_once.py" "$WORK/obsw-tm.log" "$WORK/a-$seed.db" 1 "${range[@]}" 2>&1); then
        ARCHIVE_BAD=$((ARCHIVE_BAD + 1))
        rc_archive=1
    fi
    relay=$(python3 "$ROOT/ground/bench/relay_gaps.py" "$WORK/relay.trace" "$t0" "$t1")
    echo "$CASE seed $seed: exit $rc in $secs s | ${tm:+$tm | }$archive | $relay | $last"
    expected=0
    [[ $CASE == silent ]] && expected=5
    if [[ $rc != "$expected" || $rc_archive != 0 ]]; then
        k="$KEEP/lossy-$CASE-$seed"
        for f in obsw-tm.log:tm.log obsw.out:obsw.out obsw.err:obsw.err relay.trace:relay.trace out:out err:err "a-$seed.db:db"; do
            cp "$WORK/${f%%:*}" "$k.${f#*:}" 2>/dev/null
        done
    fi
    rm -f "$WORK/a-$seed.db" "$WORK/relay.trace"
    [[ ${KEEP_STORE:-0} == 1 ]] || rm -f "$store"
done
median=$(printf '%s\n' "${TIMES[@]}" | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
max=$(printf '%s\n' "${TIMES[@]}" | sort -n | tail -1)
echo -n "$CASE: $((RUNS - NOSTART)) runs ($NOSTART more did not start), exit codes:"
for k in "${!TALLY[@]}"; do echo -n " $k×${TALLY[$k]}"; done
echo "; median $median s (max $max s); false 'lost' (exit 5, 7 or 8 with a live robot): $FALSE_LOST; archive not exactly once: $ARCHIVE_BAD"
