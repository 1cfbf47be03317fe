#!/usr/bin/env bash
# Flash and static-RAM use of ESP32-C3 images, from `riscv64-unknown-elf-size -A`.
#
#   size-report.sh [--flash-budget BYTES] [--ram-budget BYTES] [--margin PCT] ELF...
#
# Besides the budget (exceeding it fails), each image's use is shown in % of the budget
# against the flight margin (default 30 %, GSFC-STD-1000): "margin ok" at or below
# 100 - PCT %, "BELOW MARGIN" above it (reported, not failed: REV-ANOM-12).
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
# Exit status: 0 within budget, 1 over budget, 2 usage or tool error.
set -euo pipefail

FLASH_BUDGET=$((256 * 1024))
RAM_BUDGET=$((128 * 1024))
MARGIN=30
SIZE=${SIZE:-riscv64-unknown-elf-size}
elfs=()
while [ $# -gt 0 ]; do
  case "$1" in
    --flash-budget) FLASH_BUDGET=$2; shift 2 ;;
    --ram-budget) RAM_BUDGET=$2; shift 2 ;;
    --margin) MARGIN=$2; shift 2 ;;
    -h|--help) sed -n '2,21p' "$0"; exit 0 ;;
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
  m=$(awk -v f="$fpct" -v r="$rpct" -v m="$MARGIN" 'BEGIN { print (f <= 100 - m && r <= 100 - m) ? "margin ok" : "BELOW MARGIN" }')
  margins+=("$(printf '%-10s flash %5s %%, static RAM %5s %% of budget: %s (flight margin %s %%)' "$name" "$fpct" "$rpct" "$m" "$MARGIN")")
done
for line in "${margins[@]}"; do echo "$line"; done
printf 'budget: flash %d bytes (%d KiB), static RAM %d bytes (%d KiB)\n' \
  "$FLASH_BUDGET" $((FLASH_BUDGET / 1024)) "$RAM_BUDGET" $((RAM_BUDGET / 1024))
exit $status
