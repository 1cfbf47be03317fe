#!/usr/bin/env bash
# Known-vulnerable, unsound, unmaintained or yanked dependencies, offline: cargo-deny's
# advisory check of both lock files (the root workspace's and firmware/Cargo.lock)
# against a snapshot of the RustSec advisory database.
#
#   RUSTSEC_DB  folder of the snapshot (default: ../shared/rustsec-advisory-db beside the
#               repository root, where CI lays shared/). Its SNAPSHOT file names the
#               database commit and date: advisories published after that date are not
#               in it, so a pass here says nothing about them.
#
# Policy (what is refused, what is recorded and why) is deny.toml's [advisories].
# Exit status: 0 when both workspaces pass, 1 on an advisory or a missing snapshot
# (with --if-present, CI's form: a missing snapshot is said and exits 0).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SNAP="${RUSTSEC_DB:-$ROOT/../shared/rustsec-advisory-db}"
# cargo-deny 0.20 reads the database from DB_PATH/advisory-db-<hash of the default
# database URL>; the directory name below is that version's (see the snapshot's SNAPSHOT).
DENY_VERSION=0.20.2
DB_DIR_NAME=advisory-db-3157b0e258782691

if [ ! -d "$SNAP/crates" ] && [ "${1:-}" = "--if-present" ]; then
  echo "== advisories: NOT CHECKED: no RustSec advisory database snapshot at $SNAP"
  exit 0
fi
if [ ! -d "$SNAP/crates" ]; then
  echo "advisories: no RustSec advisory database snapshot at $SNAP" >&2
  echo "advisories: set RUSTSEC_DB to the snapshot's folder (the one holding crates/ and SNAPSHOT)" >&2
  exit 1
fi
if ! cargo deny --version 2>/dev/null | grep -q "^cargo-deny $DENY_VERSION"; then
  cargo install --locked "cargo-deny@$DENY_VERSION"
fi

# cargo-deny wants a git repository: a throw-away one of the snapshot's working tree.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
db="$tmp/$DB_DIR_NAME"
mkdir -p "$db"
cp -r "$SNAP/." "$db"
git -C "$db" init -q
git -C "$db" add -A
git -C "$db" -c user.name=snapshot -c user.email=snapshot@localhost commit -qm snapshot

# deny.toml with the database path set (the path is this run's temporary folder).
awk -v p="$tmp" '{ print } /^\[advisories\]$/ { print "db-path = \"" p "\"" }' \
  "$ROOT/deny.toml" > "$tmp/deny.toml"
grep -q "^db-path = " "$tmp/deny.toml" || { echo "advisories: deny.toml has no [advisories] table" >&2; exit 1; }

echo "advisories: RustSec snapshot $(grep -o 'commit [0-9a-f]*' "$SNAP/SNAPSHOT" | head -1) $(grep -o '([0-9-]*)' "$SNAP/SNAPSHOT" | head -1); later advisories are not covered"
status=0
for manifest in "$ROOT/Cargo.toml" "$ROOT/firmware/Cargo.toml"; do
  echo "advisories: ${manifest#"$ROOT/"}"
  # cargo-deny reads the graph for every platform: the crates of all targets first (from
  # the registry, the lock file unchanged), then the check with no network at all.
  cargo fetch --locked --manifest-path "$manifest" >/dev/null
  if ! cargo deny --frozen --manifest-path "$manifest" --config "$tmp/deny.toml" --workspace check advisories; then
    status=1
  fi
done
exit $status
