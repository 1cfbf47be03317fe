#!/usr/bin/env bash
# Flash and static-RAM use of ESP32-C3 images, from `riscv64-unknown-elf-size -A`.
#
#   size-report.sh [--flash-budget BYTES] [--ram-budget BYTES] [--margin PCT] ELF...
#
# Besides the budget (exceeding it fails), each image's use is shown in % of the budget
# against the flight margin (default 30 %, GSFC-STD-1000): "margin ok" at or below
# 100 - PCT % of the budget in bytes (flash <= 183 500 B and static RAM <= 91 750 B for
# the defaults), "BELOW MARGIN" above it. The margin is ENFORCED (exit status 1) for the
# flight images, the ELF files named `board-a` and `board-b` (the default images CI
# builds); any other image (an experiment such as CI's `board-a-frames`) is reported only.
# MARGIN_ENFORCED="name ..." replaces that list of file names.
#
# Flash (bytes stored in the image): .text, .rodata*, .trap, .rwtext*, .data* (initial
#   values), .flash.appdesc, .rtc_fast.text, .rtc_fast.data.
# Static RAM (reserved at link time, stack excluded): .trap and .rwtext* (code copied
#   into IRAM, same physical SRAM as DRAM on the C3), .data*, .bss*, .noinit, and the
#   RTC fast RAM sections.
# Not counted: the address-space placeholders *_dummy, .stack (everything left over),
#   and sections not loaded at all (address 0: debug info, .comment, attributes).
# An allocated section this script does not know is counted in BOTH totals and named,
# so the budget check can only err on the safe side.
# Exit status: 0 within budget (and margin where enforced), 1 over budget or a flight
# image below the margin, 2 usage or tool error.
set -euo pipefail

FLASH_BUDGET=$((256 * 1024))
RAM_BUDGET=$((128 * 1024))
MARGIN=30
MARGIN_ENFORCED=${MARGIN_ENFORCED:-board-a board-b}
SIZE=${SIZE:-riscv64-unknown-elf-size}
elfs=()
while [ $# -gt 0 ]; do
  case "$1" in
    --flash-budget) FLASH_BUDGET=$2; shift 2 ;;
    --ram-budget) RAM_BUDGET=$2; shift 2 ;;
    --margin) MARGIN=$2; shift 2 ;;
    -h|--help) sed -n '2,25p' "$0"; exit 0 ;;
    *) elfs+=("$1"); shift ;;
  esac
done
[ ${#elfs[@]} -gt 0 ] || { echo "usage: $0 [--flash-budget B] [--ram-budget B] ELF..." >&2; exit 2; }
command -v "$SIZE" >/dev/null || { echo "error: $SIZE not found (Debian: binutils-riscv64-unknown-elf)" >&2; exit 2; }

status=0
printf '%-10s %10s %10s %10s %10s %10s %10s  %s\n' image text rodata "data(init)" bss "flash" "static RAM" verdict
margins=()
for elf in "${elfs[@]}"; do
  [ -f "$elf" ] || { echo "error: no such file: $elf" >&2; exit 2; }
  name=$(basename "$elf")
  read -r text rodata data bss flash ram unknown < <("$SIZE" -A "$elf" | awk '
    NR > 2 && NF == 3 && $3 ~ /^[0-9]+$/ {
      s = $1; n = $2 + 0; a = $3 + 0
      if (a == 0 || n == 0) next                       # not loaded / empty
      if (s ~ /_dummy$/ || s == ".stack") next         # placeholders, stack
      if (s ~ /^\.text/ || s ~ /^\.rotext/) { text += n; flash += n; next }
      if (s ~ /^\.rodata/ || s == ".flash.appdesc") { rodata += n; flash += n; next }
      if (s == ".trap" || s ~ /^\.rwtext/ || s == ".rtc_fast.text") { text += n; flash += n; ram += n; next }
      if (s ~ /^\.data/ || s == ".rtc_fast.data") { data += n; flash += n; ram += n; next }
      if (s ~ /^\.bss/ || s == ".noinit" || s == ".rtc_fast.bss" || s == ".rtc_fast.persistent") { bss += n; ram += n; next }
      flash += n; ram += n; unknown = unknown s "(" n ") "
    }
    END { printf "%d %d %d %d %d %d %s\n", text, rodata, data, bss, flash, ram, (unknown == "" ? "-" : unknown) }')
  verdict=ok
  if [ "$flash" -gt "$FLASH_BUDGET" ]; then verdict="FLASH OVER BUDGET"; status=1; fi
  if [ "$ram" -gt "$RAM_BUDGET" ]; then verdict="${verdict/ok/}RAM OVER BUDGET"; status=1; fi
  printf '%-10s %10d %10d %10d %10d %10d %10d  %s\n' "$name" "$text" "$rodata" "$data" "$bss" "$flash" "$ram" "$verdict"
  if [ "$unknown" != "-" ]; then echo "  note: unclassified sections counted as flash and RAM: $unknown"; fi
  fpct=$(awk -v a="$flash" -v b="$FLASH_BUDGET" 'BEGIN { printf "%.1f", 100 * a / b }')
  rpct=$(awk -v a="$ram" -v b="$RAM_BUDGET" 'BEGIN { printf "%.1f", 100 * a / b }')
  # In bytes, not the rounded percentages: 183 501 B is 70.0 % rounded but over.
  m=$(awk -v f="$flash" -v fb="$FLASH_BUDGET" -v r="$ram" -v rb="$RAM_BUDGET" -v m="$MARGIN" \
    'BEGIN { print (100 * f <= (100 - m) * fb && 100 * r <= (100 - m) * rb) ? "margin ok" : "BELOW MARGIN" }')
  enforced="reported only"
  if [[ " $MARGIN_ENFORCED " == *" $name "* ]]; then
    enforced="enforced"
    if [ "$m" != "margin ok" ]; then status=1; fi
  fi
  margins+=("$(printf '%-10s flash %5s %%, static RAM %5s %% of budget: %s (flight margin %s %%, %s)' "$name" "$fpct" "$rpct" "$m" "$MARGIN" "$enforced")")
done
for line in "${margins[@]}"; do echo "$line"; done
printf 'budget: flash %d bytes (%d KiB), static RAM %d bytes (%d KiB)\n' \
  "$FLASH_BUDGET" $((FLASH_BUDGET / 1024)) "$RAM_BUDGET" $((RAM_BUDGET / 1024))
exit $status
