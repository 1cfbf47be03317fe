#!/usr/bin/env bash
# Installs what the firmware build and its on-target tests need. Idempotent: every step
# checks first and does nothing when the tool is already there.
#   - Rust target riscv32imc-unknown-none-elf (rustup)
#   - qemu-system-riscv32 (Debian qemu-system-misc) for the on-target tests
#   - riscv64-unknown-elf-size (Debian binutils-riscv64-unknown-elf) for the size report
# espflash (flashing real boards, `cargo install espflash`) is optional and not installed.
set -euo pipefail

TARGET=riscv32imc-unknown-none-elf

if ! rustup target list --installed | grep -qx "$TARGET"; then
  echo "firmware-setup: adding Rust target $TARGET"
  rustup target add "$TARGET"
fi

need=()
command -v qemu-system-riscv32 >/dev/null 2>&1 || need+=(qemu-system-misc)
command -v riscv64-unknown-elf-size >/dev/null 2>&1 || need+=(binutils-riscv64-unknown-elf)
if [ ${#need[@]} -gt 0 ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "firmware-setup: installing ${need[*]}"
  export DEBIAN_FRONTEND=noninteractive
  # Refresh the package lists only when a package is not known yet.
  for p in "${need[@]}"; do
    if ! apt-cache show "$p" >/dev/null 2>&1; then
      $SUDO apt-get update -qq
      break
    fi
  done
  if ! $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null; then
    # Stale lists (package version gone from the mirror): refresh once and retry.
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  fi
fi

echo "firmware-setup: $(rustc --version), target $TARGET ok"
echo "firmware-setup: $(qemu-system-riscv32 --version | head -1)"
echo "firmware-setup: $(riscv64-unknown-elf-size --version | head -1)"
