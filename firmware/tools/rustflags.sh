#!/usr/bin/env bash
# RUSTFLAGS for the firmware images and the QEMU test binary: warnings denied, and source
# paths stored in the image (panic locations, `core::panic::Location::file()`) made short
# and independent of the build machine:
#   <repository root>/obsw/core/src/obsw.rs           -> obsw/core/src/obsw.rs
#   $CARGO_HOME/registry/src/index.crates.io-<h>/esp-hal-1.2.2/src/... -> esp-hal-1.2.2/src/...
# Firmware workspace crates are already relative (board-a/src/main.rs). Paths of `core`
# (/rustc/<hash>/library/...) come precompiled and stay as they are.
#
# No size flags: the images have a 576 KiB application slot each (mib::memory), so the
# linker relaxation rustc marks unstable, `--cfg aes_compact`, the forced machine
# outliner and LLD's identical code folding are gone (what each cost and saved, measured:
# docs/firmware.md, Memory map and budgets).
#
#   RUSTFLAGS="$(bash firmware/tools/rustflags.sh)" cargo build --release
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
flags="-D warnings --remap-path-prefix=$ROOT/="
cargo_home=${CARGO_HOME:-$HOME/.cargo}
for d in "$cargo_home"/registry/src/*/ "$cargo_home"/git/checkouts/; do
  [ -d "$d" ] && flags="$flags --remap-path-prefix=$d="
done
echo "$flags"
