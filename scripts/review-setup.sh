#!/usr/bin/env bash
# Tools for the review package (`cargo run -p xtask -- review`): cargo-llvm-cov
# (coverage), cargo-deny (licence and source policy) from crates.io, and rustup's
# llvm-tools-preview component that cargo-llvm-cov needs. Idempotent: a tool already
# installed is not reinstalled.
set -euo pipefail
export CARGO_TERM_COLOR=never

if ! rustup component list --installed 2>/dev/null | grep -q '^llvm-tools'; then
  rustup component add llvm-tools-preview
fi
for tool in cargo-llvm-cov cargo-deny; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    cargo install --locked "$tool"
  fi
done
echo "review tools: $(cargo llvm-cov --version 2>/dev/null | head -1); $(cargo deny --version 2>/dev/null | head -1)"
