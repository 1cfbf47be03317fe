#!/usr/bin/env bash
# A throwaway PostgreSQL for the archive tests (and for trying the PostgreSQL path by
# hand). Installs Debian's `postgresql` package if no server binaries are found, runs
# initdb in DIR, listens only on a Unix socket in DIR (no TCP port), and stops the
# server and deletes DIR on `stop` — or by itself once process OWNER_PID has exited.
#
#   scripts/postgres-test.sh install                 only installs (CI set-up step)
#   scripts/postgres-test.sh start DIR [OWNER_PID]   prints the URL of database "postgres"
#   scripts/postgres-test.sh stop DIR
#
# initdb refuses to run as root: as root the server runs as the `postgres` user that the
# Debian package creates.
set -euo pipefail
cmd=${1:?usage: postgres-test.sh install | start|stop DIR [OWNER_PID]}
if [ "$cmd" = install ]; then dir=; else dir=${2:?usage: postgres-test.sh start|stop DIR [OWNER_PID]}; fi

find_bin() {
    local d
    for d in /usr/lib/postgresql/*/bin; do
        if [ -x "$d/initdb" ] && [ -x "$d/pg_ctl" ]; then echo "$d"; return 0; fi
    done
    return 1
}

BIN=$(find_bin || true)
if [ -z "$BIN" ]; then
    echo "postgres-test: installing Debian's postgresql package" >&2
    SUDO=()
    [ "$(id -u)" = 0 ] || SUDO=(sudo -n)
    "${SUDO[@]}" apt-get update -qq >&2
    DEBIAN_FRONTEND=noninteractive "${SUDO[@]}" apt-get install -y -qq postgresql >&2
    BIN=$(find_bin)
fi

AS=()
if [ "$(id -u)" = 0 ]; then AS=(runuser -u postgres --); fi

case "$cmd" in
install)
    echo "PostgreSQL server binaries: $BIN"
    ;;
start)
    mkdir -p "$dir"
    if [ "$(id -u)" = 0 ]; then chown postgres "$dir"; fi
    "${AS[@]}" "$BIN/initdb" -D "$dir/data" -A trust -U ground -E UTF8 --no-sync > "$dir/initdb.log" 2>&1 || {
        cat "$dir/initdb.log" >&2; exit 1; }
    "${AS[@]}" "$BIN/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
        -o "-k $dir -c listen_addresses= -c fsync=off -c max_connections=200" start > /dev/null || {
        cat "$dir/server.log" >&2; exit 1; }
    if [ -n "${3:-}" ]; then
        owner=$3
        nohup setsid bash -c "while kill -0 $owner 2>/dev/null; do sleep 1; done; '$0' stop '$dir'" \
            > /dev/null 2>&1 < /dev/null &
    fi
    echo "postgresql://ground@/postgres?host=$dir"
    ;;
stop)
    if [ -d "$dir/data" ]; then
        "${AS[@]}" "$BIN/pg_ctl" -D "$dir/data" -m fast -w stop > /dev/null 2>&1 || true
    fi
    rm -rf "$dir"
    ;;
*)
    echo "usage: postgres-test.sh install | start|stop DIR [OWNER_PID]" >&2
    exit 2
    ;;
esac
