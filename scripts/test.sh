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

step "test data: faery's real recordings (fetched, not committed), Prophesee fixtures as make.py writes them"
bash scripts/fetch-faery.sh >/dev/null
python3 tests/fixtures/prophesee/make.py --check

step "tests (host: unit, property, end to end; real recordings required)"
EVCAL_REQUIRE_TEST_DATA=1 cargo test --workspace --no-fail-fast 2>&1 | tee target/test-output.txt

step "recordings written again by dv-processing, rosbags, h5py (versions pinned in setup.sh), read again"
python3 scripts/make-format-fixtures.py target/test-data/formats-fresh
EVCAL_FORMAT_FIXTURES="$PWD/target/test-data/formats-fresh" cargo test --workspace --test formats 2>&1 \
  | tee -a target/test-output.txt

step "fuzz the EVT decoders (cargo-fuzz, nightly; 15 s a target)"
bash scripts/fuzz.sh "${EVCAL_FUZZ_SECONDS:-15}"

# Repeat the runner's closing totals on one line for CI readers.
awk '/^test result:/ { split($0, a, /[.;] /); p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' target/test-output.txt
