#!/usr/bin/env bash
# Fuzzing CI: the cargo-fuzz (libFuzzer) targets of tests/fuzz, each briefly. Installs
# cargo-fuzz if missing (the nightly toolchain must be there), checks the fuzz crate's
# formatting and lints, builds every target (release, debug assertions and overflow checks
# on, no sanitizer: the code under test is safe Rust, and the speed buys executions), then
# per target replays its committed corpus (tests/fuzz/corpus/<target>/: the seeds and every
# input that ever found a bug) and fuzzes for FUZZ_SECONDS (default 20). New inputs go to a
# scratch folder, not into the committed corpus. Fails on the first crash, failed assertion,
# hang (10 s per input) or leak of memory past 2 GB; libFuzzer writes the input to
# tests/fuzz/artifacts/<target>/.
# The long campaign and how to reproduce a finding: docs/fuzzing.md.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
SECONDS_PER_TARGET=${FUZZ_SECONDS:-20}
FUZZ="cargo +nightly fuzz"
FLAGS=(--fuzz-dir tests/fuzz --sanitizer none)

rustup toolchain list | grep -q '^nightly' || { echo "fuzz-ci: the nightly toolchain is missing (rustup toolchain install nightly)"; exit 1; }
command -v cargo-fuzz >/dev/null || cargo install --locked cargo-fuzz

echo "== fuzz: format and lint"
cargo +nightly fmt --manifest-path tests/fuzz/Cargo.toml -- --check
cargo +nightly clippy --manifest-path tests/fuzz/Cargo.toml --all-targets -- -D warnings
echo "== fuzz: the harnesses' own tests"
cargo +nightly test --manifest-path tests/fuzz/Cargo.toml --lib

echo "== fuzz: build"
$FUZZ build "${FLAGS[@]}"

scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
for t in $($FUZZ list --fuzz-dir tests/fuzz); do
    echo "== fuzz: $t (${SECONDS_PER_TARGET} s)"
    mkdir -p "$scratch/$t"
    log="$scratch/$t.log"
    if ! $FUZZ run "${FLAGS[@]}" "$t" "$scratch/$t" "tests/fuzz/corpus/$t" -- \
        -max_total_time="$SECONDS_PER_TARGET" -max_len=4096 -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 >"$log" 2>&1; then
        tail -n 60 "$log"
        echo "fuzz-ci: $t failed; the input is in tests/fuzz/artifacts/$t/"
        exit 1
    fi
    grep -E '^#[0-9]+[[:space:]]+(INITED|DONE)|^stat::number_of_executed_units' "$log" || true
done
echo "== fuzz: every target ran ${SECONDS_PER_TARGET} s without a finding"
