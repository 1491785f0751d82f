#!/usr/bin/env bash
# Every check evcal has, as CI runs it. README's test command; .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh

step() { echo; echo "=== $*"; }

step "format"
cargo fmt --all -- --check

step "clippy (host crates, all targets)"
cargo clippy --workspace --all-targets -- -D warnings

step "core builds for the Cortex-M4F (thumbv7em-none-eabihf), with and without defmt"
cargo build -p evcal-core --target thumbv7em-none-eabihf --release
cargo build -p evcal-core --target thumbv7em-none-eabihf --release --features defmt

step "fuzz the wire decoders and the device loop (bounded: ${EVCAL_FUZZ_SECONDS:-20} s per target)"
# About 3 minutes on a fresh 2-core machine: installing cargo-fuzz ~65 s, building the
# targets ~60 s, running them. Longer runs: bash scripts/fuzz.sh 600
cargo fmt --manifest-path fuzz/Cargo.toml -- --check
bash scripts/fuzz.sh "${EVCAL_FUZZ_SECONDS:-20}"

step "tests (host: unit, property, end to end)"
cargo test --workspace --no-fail-fast 2>&1 | tee target/test-output.txt
# Repeat the runner's closing totals on one line for CI readers.
awk '/^test result:/ { split($0, a, /[.;] /); p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' target/test-output.txt
