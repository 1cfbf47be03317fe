#!/usr/bin/env bash
# Flash and SRAM use of ESP32-C3 images against the boards' memory map, from
# `riscv64-unknown-elf-size -A` and firmware/memory-map.txt (generated from the MIB,
# mib::memory).
#
#   size-report.sh [--map FILE] [--stack IMAGE=BYTES[@SOURCE]]... ELF...
#
# Prints every region of the memory map with its use and margin, then each image:
#   flash        = .text, .rodata*, .trap, .rwtext*, .data* (initial values),
#                  .flash.appdesc, .rtc_fast.text/.data: against the smallest
#                  application slot;
#   static RAM   = .trap, .rwtext* (code copied into IRAM, the same physical SRAM as
#                  DRAM on the C3), .data*, .bss*, .noinit: against the usable SRAM, with
#                  the stack's measured high-water mark (--stack) added when given;
#   RTC fast RAM = .rtc_fast.*: against the 8 KB of RTC fast memory.
# Not counted: the address-space placeholders *_dummy, .stack (everything left over),
# sections not loaded (address 0). An allocated section this script does not know is
# counted in flash AND static RAM and named, so the check can only err on the safe side.
#
# The flight margin (memory-map.txt, GSFC-STD-1000: 30 %) is compared in bytes and
# ENFORCED for every region with a use and for the flight images `board-a` and `board-b`
# (MARGIN_ENFORCED="name ..." replaces that list); other images are reported only.
# The last line starts with "budget:". Exit status: 0 every enforced region inside the
# margin, 1 one outside it, 2 usage or tool error.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
MAP="$HERE/../memory-map.txt"
MARGIN_ENFORCED=${MARGIN_ENFORCED:-board-a board-b}
SIZE=${SIZE:-riscv64-unknown-elf-size}
elfs=()
declare -A stack=() stack_src=()
while [ $# -gt 0 ]; do
  case "$1" in
    --map) MAP=$2; shift 2 ;;
    --stack)
      spec=${2%%@*}; stack[${spec%%=*}]=${spec#*=}
      [[ "$2" == *@* ]] && stack_src[${spec%%=*}]=${2#*@}
      shift 2 ;;
    -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
    *) elfs+=("$1"); shift ;;
  esac
done
[ ${#elfs[@]} -gt 0 ] || { echo "usage: $0 [--map FILE] [--stack IMAGE=BYTES] ELF..." >&2; exit 2; }
[ -f "$MAP" ] || { echo "error: no memory map $MAP" >&2; exit 2; }
command -v "$SIZE" >/dev/null || { echo "error: $SIZE not found (Debian: binutils-riscv64-unknown-elf)" >&2; exit 2; }

# The map: margin, regions, slots, fixed uses.
MARGIN=$(awk '$1 == "margin" { print $2 }' "$MAP")
SRAM_USABLE=$(( $(awk '$1 == "sram_usable" { print $2 }' "$MAP") ))
RTC_FAST=$(( $(awk '$1 == "rtc_fast" { print $2 }' "$MAP") ))
SLOT=
while read -r _ _ v; do
  if [ -z "$SLOT" ] || [ $((v)) -lt "$SLOT" ]; then SLOT=$((v)); fi
done < <(grep '^slot ' "$MAP")
[ -n "$MARGIN" ] && [ "$SRAM_USABLE" -gt 0 ] && [ -n "$SLOT" ] || { echo "error: incomplete memory map $MAP" >&2; exit 2; }

status=0
# within USED AVAILABLE: the flight margin kept, in bytes (70.001 % is out).
within() { [ $(( 100 * $1 )) -le $(( (100 - MARGIN) * $2 )) ]; }
pct() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", 100 * a / b }'; }
line() { # name kind size used note enforced
  local name=$1 kind=$2 size=$3 used=$4 note=$5 enf=$6 v
  if [ "$used" = "-" ]; then
    printf '  %-16s %-6s %9d  %9s  %6s  %-13s %s\n' "$name" "$kind" "$size" "-" "-" "-" "$note"
    return
  fi
  if within "$used" "$size"; then v="margin ok"; else v="BELOW MARGIN"; [ "$enf" = yes ] && status=1; fi
  printf '  %-16s %-6s %9d  %9d  %5s%%  %-13s %s\n' "$name" "$kind" "$size" "$used" "$(pct "$used" "$size")" "$v" "$note"
}

declare -A img_flash=() img_ram=() img_rtc=()
table=()
for elf in "${elfs[@]}"; do
  [ -f "$elf" ] || { echo "error: no such file: $elf" >&2; exit 2; }
  name=$(basename "$elf")
  read -r text rodata data bss flash ram rtc unknown < <("$SIZE" -A "$elf" | awk '
    NR > 2 && NF == 3 && $3 ~ /^[0-9]+$/ {
      s = $1; n = $2 + 0; a = $3 + 0
      if (a == 0 || n == 0) next                       # not loaded / empty
      if (s ~ /_dummy$/ || s == ".stack") next         # placeholders, stack
      if (s ~ /^\.text/ || s ~ /^\.rotext/) { text += n; flash += n; next }
      if (s ~ /^\.rodata/ || s == ".flash.appdesc") { rodata += n; flash += n; next }
      if (s == ".rtc_fast.text") { text += n; flash += n; rtc += n; next }
      if (s == ".rtc_fast.data") { data += n; flash += n; rtc += n; next }
      if (s == ".rtc_fast.bss" || s == ".rtc_fast.persistent") { bss += n; rtc += n; next }
      if (s == ".trap" || s ~ /^\.rwtext/) { text += n; flash += n; ram += n; next }
      if (s ~ /^\.data/) { data += n; flash += n; ram += n; next }
      if (s ~ /^\.bss/ || s == ".noinit") { bss += n; ram += n; next }
      flash += n; ram += n; unknown = unknown s "(" n ") "
    }
    END { printf "%d %d %d %d %d %d %d %s\n", text, rodata, data, bss, flash, ram, rtc, (unknown == "" ? "-" : unknown) }')
  img_flash[$name]=$flash; img_ram[$name]=$ram; img_rtc[$name]=$rtc
  table+=("$(printf '%-10s %10d %10d %10d %10d %10d %10d' "$name" "$text" "$rodata" "$data" "$bss" "$flash" "$ram")")
  if [ "$unknown" != "-" ]; then table+=("  note: unclassified sections counted as flash and RAM: $unknown"); fi
done

echo "memory map ($(basename "$MAP"), flight margin $MARGIN %: used <= $((100 - MARGIN)) % of the region, in bytes)"
printf '  %-16s %-6s %9s  %9s  %6s  %-13s %s\n' region where bytes used use verdict "what"
while read -r kind rname a b c; do
  case "$kind" in
    flash)
      size=$((b))
      if awk -v n="$rname" '$1 == "slot" && $2 == n { f = 1 } END { exit !f }' "$MAP"; then
        # Each image must fit every slot (a software update goes to the other one).
        for elf in "${elfs[@]}"; do
          name=$(basename "$elf"); enf=no
          [[ " $MARGIN_ENFORCED " == *" $name "* ]] && enf=yes
          line "$rname" flash "$size" "${img_flash[$name]}" "image $name" "$enf"
        done
        continue
      fi
      used=$(awk -v n="$rname" '$1 == "used" && $2 == n { print $3 }' "$MAP")
      [ -n "$used" ] && used=$((used))
      case "$rname" in
        bootloader) line "$rname" flash "$size" - "espflash's ESP-IDF bootloader: not built here" no ;;
        otadata) line "$rname" flash "$size" - "two sectors, written alternately (fixed by ESP-IDF)" no ;;
        files) line "$rname" flash "$size" 0 "CFDP file store: empty until CFDP" yes ;;
        tm_store) line "$rname" flash "$size" - "PUS 15 store: its two areas below" no
          while read -r _ aname room need; do
            line "$aname" area $((room)) $((need)) "the area's room vs. the 2 h outage as stored (mib::memory::store)" yes
          done < <(grep '^area tm_store\.' "$MAP") ;;
        *) line "$rname" flash "$size" "${used:-0}" "fixed by its layout" yes ;;
      esac ;;
    sram)
      size=$((b))
      if [ "$c" = usable ]; then
        for elf in "${elfs[@]}"; do
          name=$(basename "$elf"); enf=no
          [[ " $MARGIN_ENFORCED " == *" $name "* ]] && enf=yes
          s=${stack[$name]:-}
          if [ -n "$s" ]; then
            line "$rname" sram "$size" $(( img_ram[$name] + s )) "image $name: static ${img_ram[$name]} + stack high-water $s (${stack_src[$name]:-measured})" "$enf"
          else
            line "$rname" sram "$size" "${img_ram[$name]}" "image $name: static RAM only, stack NOT MEASURED" "$enf"
          fi
        done
      else
        line "$rname" sram "$size" - "reserved (not usable by the images)" no
      fi ;;
  esac
done < <(grep -E '^(flash|sram) ' "$MAP")
for elf in "${elfs[@]}"; do
  name=$(basename "$elf"); enf=no
  [[ " $MARGIN_ENFORCED " == *" $name "* ]] && enf=yes
  line rtc_fast rtc "$RTC_FAST" "${img_rtc[$name]}" "image $name: panic record" "$enf"
done

echo
printf '%-10s %10s %10s %10s %10s %10s %10s\n' image text rodata "data(init)" bss "flash" "static RAM"
for l in "${table[@]}"; do echo "$l"; done
printf 'budget: flash %d bytes per image (70 %% of the %d-byte slot), SRAM %d bytes (70 %% of %d usable), flight margin %s %%: %s\n' \
  $(( SLOT * (100 - MARGIN) / 100 )) "$SLOT" $(( SRAM_USABLE * (100 - MARGIN) / 100 )) "$SRAM_USABLE" "$MARGIN" \
  "$([ $status -eq 0 ] && echo "every enforced region inside" || echo "A REGION OUTSIDE THE MARGIN")"
exit $status
