#!/usr/bin/env bash
# Every check evcal has, as CI runs it. README's test command; .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh

# Each step's wall time is printed when the next begins, and all of them at the end: CI's
# time is a budget (under 20 minutes on 2 cores; docs/testing.md), kept by knowing where it goes.
times=()
step_end() { [ -n "${step_name:-}" ] && times+=("$(printf '%5d s  %s' $((SECONDS - step_t0)) "$step_name")"); return 0; }
step() { step_end; step_name="$*"; step_t0=$SECONDS; echo; echo "=== $*"; }

step "format; documentation links (every relative link and anchor in README, CHANGELOG, docs/)"
cargo fmt --all -- --check
python3 scripts/check-doc-links.py

step "clippy (host crates, all targets)"
cargo clippy --workspace --all-targets -- -D warnings

step "core builds for the Cortex-M4F (thumbv7em-none-eabihf), with and without defmt"
cargo build -p evcal-core --target thumbv7em-none-eabihf --release
cargo build -p evcal-core --target thumbv7em-none-eabihf --release --features defmt

# The firmware: measured 80 s from a cold target directory on 2 shared cores (clippy for
# three feature sets 42 s, three images with whole-program optimisation 36 s). Clippy for
# each board; the STM32F405 image and the defmt build must link too (their memory map and
# defmt's linker script), though only the emulated board runs.
fw=(-p evcal-firmware --target thumbv7em-none-eabihf --profile firmware)
step "firmware: clippy and images for the Cortex-M4F (emulated board; STM32F405 board; with defmt)"
cargo clippy "${fw[@]}" -- -D warnings
cargo clippy "${fw[@]}" --features board-stm32f405 -- -D warnings
cargo clippy "${fw[@]}" --features defmt -- -D warnings
cargo build "${fw[@]}" --features board-stm32f405
# Each board's image within the flash and static-RAM budget, checked as it is built (the
# next build overwrites it).
elf="${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/firmware/evcal-firmware"
bash scripts/firmware-size.sh "$elf" stm32f405
cargo build "${fw[@]}" --features defmt
cargo build "${fw[@]}"  # last: the image QEMU boots
bash scripts/firmware-size.sh "$elf" mps2-an386

# The Cortex-M7 boards: built with `-C target-cpu=cortex-m7` in target/m7 (the environment
# variable replaces .cargo/config.toml's cortex-m4 for the target; a target directory of its
# own keeps the two cores' builds from rebuilding each other's dependencies), as
# scripts/firmware-build.sh and the QEMU tests build them. Measured from a cold target/m7 on 2
# shared cores: 123 s (clippy for the STM32H743 74 s, checking embassy-stm32 and its register
# crate; the H743 image then 41 s, 46 s on its own; the mps2-an500's clippy and image 8 s).
m7=(env CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}/m7" CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS="-C target-cpu=cortex-m7")
step "firmware: clippy and images for the Cortex-M7 (emulated board; STM32H743 board)"
"${m7[@]}" cargo clippy "${fw[@]}" --features board-stm32h743 -- -D warnings
"${m7[@]}" cargo clippy "${fw[@]}" --features board-mps2-an500 -- -D warnings
"${m7[@]}" cargo build "${fw[@]}" --features board-stm32h743
elf7="${CARGO_TARGET_DIR:-target}/m7/thumbv7em-none-eabihf/firmware/evcal-firmware"
bash scripts/firmware-size.sh "$elf7" stm32h743
"${m7[@]}" cargo build "${fw[@]}" --features board-mps2-an500  # last: the image QEMU boots
bash scripts/firmware-size.sh "$elf7" mps2-an500

step "API documentation, private items too, warnings denied (broken links, bad code blocks)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --document-private-items

step "test data: faery's real recordings (fetched, not committed), Prophesee fixtures as make.py writes them"
bash scripts/fetch-faery.sh >/dev/null
python3 tests/fixtures/prophesee/make.py --check

step "tests (host: unit, property, end to end; real recordings required)"
EVCAL_REQUIRE_TEST_DATA=1 cargo test --workspace --no-fail-fast 2>&1 | tee target/test-output.txt

step "recordings written again by dv-processing, rosbags, h5py (versions pinned in setup.sh), read again"
python3 scripts/make-format-fixtures.py target/test-data/formats-fresh
EVCAL_FORMAT_FIXTURES="$PWD/target/test-data/formats-fresh" cargo test --workspace --test cli -- formats:: 2>&1 \
  | tee -a target/test-output.txt

step "fuzz the core's decoders, the wire and the detection pipeline (bounded: ${EVCAL_FUZZ_SECONDS:-8} s per target)"
# The core's 8 targets (the EVT decoders, the wire, the detector, the time filter): installing
# cargo-fuzz ~65 s, building them, then 8 s each. The 6 host readers' targets build the host
# library and HDF5 from source under the sanitizer (some 4 of CI's minutes): the slow tier
# fuzzes them (scripts/test-slow.sh, docs/testing.md#fuzzing). Longer: bash scripts/fuzz.sh 600
cargo fmt --manifest-path fuzz/Cargo.toml -- --check
mapfile -t core_targets < <(sed -n 's/^name = "\([a-z0-9_]*\)"$/\1/p' fuzz/Cargo.toml | grep -v -e '^evcal-fuzz$' -e '^read_')
bash scripts/fuzz.sh "${EVCAL_FUZZ_SECONDS:-8}" "${core_targets[@]}"

# The firmware on QEMU's mps2-an386 against the host: measured 65-90 s (the 100-window UART
# replay is 35 s of it), and the instruction budget over the benchmark's scenario about 25 s
# more on 2 loaded cores (its simulation mostly); the test binary is the workspace tests'
# build (`--workspace`: with `-p evcal-tests` alone the features unify otherwise and the host
# library is built again, minutes of CI), the image the one built above. See
# tests/tests/end_to_end/firmware_qemu.rs. Ignored by a plain `cargo test`, which needs no QEMU.
# The Cortex-M7 (mps2-an500) test, a 640x480 recording in the host's 15 000-event windows:
# about 25 s more on 2 loaded cores (its image is built in the step above).
step "firmware under QEMU (emulated Cortex-M4F and Cortex-M7 boards)"
cargo test --workspace --test end_to_end -- --ignored firmware_qemu:: 2>&1 | tee -a target/test-output.txt

# Repeat the runner's closing totals on one line for CI readers.
awk '/^test result:/ { split($0, a, /[.;] /); p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' target/test-output.txt
step_end
echo; echo "=== wall time per step (total $SECONDS s)"; printf '%s\n' "${times[@]}"
