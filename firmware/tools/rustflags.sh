#!/usr/bin/env bash
# RUSTFLAGS for the firmware images and the QEMU test binary: warnings denied, and source
# paths stored in the image (panic locations, `core::panic::Location::file()`) made short
# and independent of the build machine:
#   <repository root>/obsw/core/src/obsw.rs           -> obsw/core/src/obsw.rs
#   $CARGO_HOME/registry/src/index.crates.io-<h>/esp-hal-1.2.2/src/... -> esp-hal-1.2.2/src/...
# Firmware workspace crates are already relative (board-a/src/main.rs). Paths of `core`
# (/rustc/<hash>/library/...) come precompiled and stay as they are.
#
# One size flag: linker relaxation (`-C target-feature=+relax`). rustc leaves it off for
# RISC-V (GCC's default is on), so every call stays an `auipc`+`jalr` pair; with it LLD
# turns calls and jumps in reach into `jal`/`c.j`. It took board A from 414 208 to
# 404 652 B (its budget, 70 % of the 576 KiB slot: 412 876 B) and removes instructions, not
# adds them. rustc prints "unstable feature specified" for it once per crate (a warning,
# not a lint: `-D warnings` leaves it); the QEMU test binary is built with the same flags,
# so its instruction counts are the images' code. `--cfg aes_compact`, the forced machine
# outliner and LLD's identical code folding stay off (ICF saved 24 B here; what each cost
# and saved: docs/firmware.md, Memory map and budgets).
#
#   RUSTFLAGS="$(bash firmware/tools/rustflags.sh)" cargo build --release
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
flags="-D warnings -C target-feature=+relax --remap-path-prefix=$ROOT/="
cargo_home=${CARGO_HOME:-$HOME/.cargo}
for d in "$cargo_home"/registry/src/*/ "$cargo_home"/git/checkouts/; do
  [ -d "$d" ] && flags="$flags --remap-path-prefix=$d="
done
echo "$flags"
