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
e2e_log=$(mktemp)
trap 'rm -f "$qemu_log" "$e2e_log"' EXIT
# Built before the timeout, which bounds the test's run, not its compile (a cold target, as
# the full review's, takes longer than the run).
(cd "$ROOT" && env -u CARGO_TARGET_DIR -u RUSTFLAGS cargo test -p e2e-tests --test qemu_board_e2e --no-run)
(cd "$ROOT" && env -u CARGO_TARGET_DIR -u RUSTFLAGS QEMU_BOARD_ELF="$board_elf" \
  timeout 300 cargo test -p e2e-tests --test qemu_board_e2e -- --ignored --nocapture) 2>&1 | tee "$e2e_log"
[ "${PIPESTATUS[0]}" -eq 0 ] || exit 1

step "size report (memory map from the MIB, flight margin enforced)"
# The stack: the deepest path the QEMU run measured with the images' static layout
# (t_budget: the largest TC frame and its TM framing), and each board's control period
# on the QEMU board; the images' own painted marks exist only on a board.
stack=$(sed -n 's/.*stack high-water of the TC frame and TM framing path.*: \([0-9]*\) bytes.*/\1/p' "$qemu_log")
[ -n "$stack" ] || { echo "no stack figure in the QEMU run" >&2; exit 1; }
# Each board's control period on the QEMU board (painted below the loop, per period, over
# the whole end-to-end run); board A's figure is the larger of the two measurements.
qemu_a=$(sed -n 's/.*stack high-water of the control period: board A \([0-9]*\) bytes.*/\1/p' "$e2e_log" | sort -n | tail -1)
qemu_b=$(sed -n 's/.*stack high-water of the control period: .*board B \([0-9]*\) bytes.*/\1/p' "$e2e_log" | sort -n | tail -1)
[ -n "$qemu_a" ] && [ -n "$qemu_b" ] || { echo "no stack figures from the QEMU board" >&2; exit 1; }
if [ "$qemu_a" -gt "$stack" ]; then a_stack="$qemu_a@QEMU board, control period"; else a_stack="$stack@QEMU, TC frame path"; fi
"$FW/tools/size-report.sh" --stack "board-a=$a_stack" --stack "board-b=$qemu_b@QEMU board, control period" \
  "$IMAGES/board-a" "$IMAGES/board-b"

step "done"
