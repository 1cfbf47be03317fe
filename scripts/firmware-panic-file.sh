#!/usr/bin/env bash
# Names the source file of a PREVIOUS_PANIC event: its `file_crc` is the CRC-32
# (ISO-HDLC, zlib's crc32) of the panic location's path as the image stores it
# (`core::panic::Location::file()`). Every such path is a string in the image's
# .rodata, so this scans the ELF that ran for paths ending in `.rs`, hashes each, and
# prints the ones that match.
#
#   firmware-panic-file.sh FILE_CRC [ELF...]
#
# FILE_CRC: decimal or 0x-hex. ELF defaults to board A's release image.
# Exit status: 0 a match was found, 1 none, 2 usage error.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -ge 1 ] || { sed -n '2,11p' "$0" >&2; exit 2; }
crc=$1
shift
if [ $# -eq 0 ]; then
  set -- "${FIRMWARE_TARGET_DIR:-$ROOT/firmware/target}/riscv32imc-unknown-none-elf/release/board-a"
fi
for elf in "$@"; do
  [ -f "$elf" ] || { echo "error: no such file: $elf" >&2; exit 2; }
done
command -v python3 >/dev/null || { echo "error: python3 not found" >&2; exit 2; }

python3 - "$crc" "$@" <<'PY'
import re, sys, zlib
try:
    want = int(sys.argv[1], 0)
except ValueError:
    sys.exit(f"error: not a number: {sys.argv[1]}")
found = set()
for elf in sys.argv[2:]:
    data = open(elf, "rb").read()
    # Rust string literals are not NUL-terminated: a path may run into its neighbours,
    # so every start position before each ".rs" is tried.
    for run in re.finditer(rb"[\x21-\x7e]{4,}", data):
        s = run.group()
        for end in (m.end() for m in re.finditer(rb"\.rs", s)):
            for start in range(end):
                if zlib.crc32(s[start:end]) == want:
                    found.add(s[start:end].decode())
for path in sorted(found):
    print(f"0x{want:08X}  {path}")
sys.exit(0 if found else 1)
PY
