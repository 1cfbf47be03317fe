#!/usr/bin/env bash
# Provisioning of board A's space-link keys (issue 22): writes the key record that
# fw_core::link_store reads at boot into the flash area at 0x9000 (the default partition
# table's nvs partition; the SDLS counter log follows it at 0xA000..0xBFFF).
#
#   provision-keys.sh KEYDIR ROBOT [--port /dev/ttyACM0]   # write it to the board (espflash)
#   provision-keys.sh KEYDIR ROBOT --out FILE               # only write the 76-byte record
#
# KEYDIR is what `ground keys create KEYDIR --robot ROBOT` made: KEYDIR/robot-N/tc-spi1.key
# (TC, ground -> robot, SPI 1) and KEYDIR/robot-N/tm-spi17.key (TM, SPI 17), raw 32 bytes.
# Record: "MKY1", TC SPI (u16 BE), TM SPI (u16 BE), TC key, TM key, CRC-32/ISO-HDLC of the
# 72 bytes before it (LE). The keys are never printed; the temporary record file is 0600
# and removed. The image itself carries no key: a board never provisioned (or with a
# corrupted record) accepts no TC frame. Re-provisioning a key does not reset the SDLS
# counters (the counter log is separate): a new key with a fresh ground counter needs the
# counter sectors erased too (`espflash erase-region 0xA000 0x2000`).
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,16p' "$0" >&2; exit 2; }
keydir=$1; robot=$2; shift 2
port=(); out=
while [ $# -gt 0 ]; do
  case "$1" in
    --port) port=(--port "$2"); shift 2 ;;
    --out) out=$2; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
dir="$keydir/robot-$robot"
tc="$dir/tc-spi1.key"; tm="$dir/tm-spi17.key"
for f in "$tc" "$tm"; do
  [ -f "$f" ] || { echo "error: no key file $f (ground keys create $keydir --robot $robot)" >&2; exit 1; }
  [ "$(stat -c %s "$f")" = 32 ] || { echo "error: $f is not a 32-byte key" >&2; exit 1; }
done
umask 077
rec=${out:-$(mktemp)}
python3 - "$tc" "$tm" "$rec" <<'EOF'
import sys, zlib, struct
tc = open(sys.argv[1], "rb").read()
tm = open(sys.argv[2], "rb").read()
if tc == tm:
    sys.exit("error: the TC and TM key files hold the same key (GCM nonces would repeat)")
body = b"MKY1" + struct.pack(">HH", 1, 17) + tc + tm
open(sys.argv[3], "wb").write(body + struct.pack("<I", zlib.crc32(body)))
EOF
if [ -n "$out" ]; then
  echo "key record for robot $robot written to $out (76 bytes; keys not shown)"
  exit 0
fi
trap 'rm -f "$rec"' EXIT
espflash write-bin --chip esp32c3 "${port[@]}" 0x9000 "$rec"
echo "robot $robot: key record written at 0x9000 (TC SPI 1, TM SPI 17; keys not shown)"
