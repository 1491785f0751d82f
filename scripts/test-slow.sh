#!/usr/bin/env bash
# The slow tier: what CI's fast tier (scripts/test.sh, README's test command) holds only by a
# smoke case. Run it before a change to the detection, the solve or a reader lands, and
# before a release (docs/testing.md#tiers):
#   - the tests under a `slow` module, ignored by a plain `cargo test`: the physics sweep's
#     three corners at full length, the filled-disc fallback of `evcal calibrate` on a dim
#     DVXplorer, the calibration cases beyond CI's;
#   - the host readers' fuzz targets, EVCAL_FUZZ_SECONDS (default 60) s each.
# Measured on 2 cores: see docs/testing.md#tiers.
#   bash scripts/test-slow.sh
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh
t0=$SECONDS
cargo test --workspace --no-fail-fast -- --ignored slow:: 2>&1 | tee target/test-slow-output.txt
t1=$SECONDS
mapfile -t reader_targets < <(sed -n 's/^name = "\(read_[a-z0-9_]*\)"$/\1/p' fuzz/Cargo.toml)
bash scripts/fuzz.sh "${EVCAL_FUZZ_SECONDS:-60}" "${reader_targets[@]}"
awk '/^test result:/ { split($0, a, /[.;] /); p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' target/test-slow-output.txt
echo "slow tier: tests $((t1 - t0)) s, readers' fuzzing $((SECONDS - t1)) s"
