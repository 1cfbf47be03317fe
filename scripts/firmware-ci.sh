#!/usr/bin/env bash
# Firmware CI: toolchain setup, rustfmt and clippy (warnings denied), release build of
# both ESP32-C3 images with warnings denied, the panic-file lookup on board A's image, the
# host tests of the firmware's control period against the simulator, the on-target tests
# under QEMU (instruction counts of the control period, the stack of its deepest path),
# the QEMU board end to end against the real ground binary (tests/tests/qemu_board_e2e.rs),
# then the size report against the memory map (firmware/memory-map.txt, from the MIB:
# every region with its margin, 30 % enforced).
# Fails on the first failing step.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
FW="$ROOT/firmware"
TARGET=riscv32imc-unknown-none-elf
start=$(date +%s)
step() { echo; echo "=== firmware: $* ($(( $(date +%s) - start )) s)"; }

step "setup"
bash "$ROOT/scripts/firmware-setup.sh"

# The firmware workspace builds in its own firmware/target (git-ignored) unless the
# caller chose a target directory.
export CARGO_TARGET_DIR="${FIRMWARE_TARGET_DIR:-$FW/target}"
# Warnings denied, source paths in the images short and machine-independent
# (tools/rustflags.sh says why).
RUSTFLAGS="$(bash "$FW/tools/rustflags.sh")"
export RUSTFLAGS
export CARGO_TERM_COLOR=never

step "format and lints (firmware workspace and on-target tests)"
(cd "$FW" && cargo fmt --check)
(cd "$FW/qemu-tests" && cargo fmt --check)
(cd "$FW/qemu-board" && cargo fmt --check)
(cd "$FW" && cargo clippy --release -p board-a -p board-b -p fw-core -p fw-esp -- -D warnings)
(cd "$FW/qemu-tests" && CARGO_TARGET_DIR="$CARGO_TARGET_DIR/qemu-tests" cargo clippy -- -D warnings)
(cd "$FW/qemu-board" && CARGO_TARGET_DIR="$CARGO_TARGET_DIR/qemu-tests" cargo clippy --release -- -D warnings)

step "build board images (release)"
(cd "$FW" && cargo build --release -p board-a -p board-b)

step "panic file lookup (PREVIOUS_PANIC file_crc -> path, in board A's image)"
# 0x231DC4FE = CRC-32/ISO-HDLC of "board-a/src/main.rs", a panic location in the image.
bash "$ROOT/scripts/firmware-panic-file.sh" 0x231DC4FE "$CARGO_TARGET_DIR/$TARGET/release/board-a" \
  | grep -qx "0x231DC4FE  board-a/src/main.rs"

step "host tests: board A's control period against the simulator"
# (host target: warnings denied, without the RISC-V flags of tools/rustflags.sh)
(cd "$FW" && RUSTFLAGS="-D warnings" cargo test -p fw-core --target x86_64-unknown-linux-gnu)

step "on-target tests (qemu-system-riscv32 -machine virt)"
IMAGES="${FIRMWARE_TARGET_DIR:-$FW/target}/$TARGET/release"
export CARGO_TARGET_DIR="${FIRMWARE_TARGET_DIR:-$FW/target}/qemu-tests"
qemu_log=$(mktemp)
trap 'rm -f "$qemu_log"' EXIT
(cd "$FW/qemu-tests" && timeout 600 cargo run) 2>&1 | tee "$qemu_log"
[ "${PIPESTATUS[0]}" -eq 0 ] || exit 1

step "QEMU board end to end (the real ground over the UART: plan, replay refused, SIGKILL mid-outage)"
# The QEMU board image (firmware/qemu-board, with the QEMU tests' target directory: the
# same dependencies), then the end-to-end test in the root workspace with its own target
# directory and flags (the root CI's build: nothing rebuilt but the test).
(cd "$FW/qemu-board" && cargo build --release)
board_elf="$CARGO_TARGET_DIR/$TARGET/release/qemu-board"
(cd "$ROOT" && env -u CARGO_TARGET_DIR -u RUSTFLAGS QEMU_BOARD_ELF="$board_elf" \
  timeout 300 cargo test -p e2e-tests --test qemu_board_e2e -- --ignored --nocapture)

step "size report (memory map from the MIB, flight margin enforced)"
# The stack: the deepest path the QEMU run measured with the images' static layout
# (t_budget: the largest TC frame and its TM framing), until the images report their own
# painted high-water mark in housekeeping.
stack=$(sed -n 's/.*stack high-water of the TC frame and TM framing path.*: \([0-9]*\) bytes.*/\1/p' "$qemu_log")
[ -n "$stack" ] || { echo "no stack figure in the QEMU run" >&2; exit 1; }
"$FW/tools/size-report.sh" --stack "board-a=$stack@QEMU, TC frame path" \
  "$IMAGES/board-a" "$IMAGES/board-b"

step "done"
