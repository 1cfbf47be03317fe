#!/usr/bin/env bash
# RUSTFLAGS for the firmware images: warnings denied, and source paths stored in the
# image (panic locations, `core::panic::Location::file()`) made short and independent of
# the build machine:
#   <repository root>/obsw/core/src/obsw.rs           -> obsw/core/src/obsw.rs
#   $CARGO_HOME/registry/src/index.crates.io-<h>/esp-hal-1.2.2/src/... -> esp-hal-1.2.2/src/...
# Saves about 3.4 KB of board A's flash (REV-ANOM-12). Firmware workspace crates are
# already relative (board-a/src/main.rs). Paths of `core` (/rustc/<hash>/library/...)
# come precompiled and stay as they are.
#
# And linker relaxation (`-C target-feature=+relax`): rustc does not enable it for RISC-V,
# so every call stays an `auipc`+`jalr` pair (8 bytes) that LLD could shorten to `jal`
# or `c.jal`; with it LLD relaxes calls and jumps (not gp-relative accesses, which LLD
# only does with --relax-gp). Saves about 10.3 KB of board A's flash. rustc marks the
# feature unstable (a warning, not an error); the on-target QEMU tests run with the same
# flags, so the relaxed code is what they exercise. Done the same way by Tock
# (tock/tock#3517) and Caliptra (chipsalliance/caliptra-sw#207).
#
# And `--cfg aes_compact` (RustCrypto `aes`): the compact software AES instead of the
# unrolled fixslice code, for the space link's AES-256-GCM (board A with `frame-link`, the
# QEMU tests): 1 526 B less flash, and the largest TC frame's cost under QEMU is 385 028
# instead of 383 135 instructions (GHASH and the rest of the pipeline dominate).
#
# And the LLVM machine outliner forced on (`-C llvm-args=-enable-machine-outliner=always`:
# repeated instruction sequences become calls) with LLD's identical code folding
# (`-C link-arg=--icf=all`): together 688 B less flash on board A (183 336 -> 182 648),
# 692 B on board B, 1 200 B on board A with `frame-link`; the QEMU tests run with both.
#
#   RUSTFLAGS="$(bash firmware/tools/rustflags.sh)" cargo build --release
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
flags="-D warnings -C target-feature=+relax --cfg aes_compact -C llvm-args=-enable-machine-outliner=always -C link-arg=--icf=all --remap-path-prefix=$ROOT/="
cargo_home=${CARGO_HOME:-$HOME/.cargo}
for d in "$cargo_home"/registry/src/*/ "$cargo_home"/git/checkouts/; do
  [ -d "$d" ] && flags="$flags --remap-path-prefix=$d="
done
echo "$flags"
