#!/usr/bin/env bash
# Runs every cargo-fuzz target in fuzz/ for a bounded time each.
#
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]    (default: 60 s, every target)
#
# Targets: the EVT decoders (evt2, evt21, evt3), the wire (wire_*), the detector, the input
# filter's time order (time_filter), and one per
# host reader (read_text, read_raw, read_dat, read_aedat4, read_bag, read_h5), which are
# seeded with the format fixtures.
#
# Targets are the [[bin]]s of fuzz/Cargo.toml (`cargo fuzz list`); a new file in
# fuzz/fuzz_targets/ listed there is picked up here without change. Corpora grow in
# fuzz/corpus/TARGET (not committed); a crash is saved in fuzz/artifacts/TARGET and fails
# the run (reproduce: cd fuzz && cargo +nightly fuzz run TARGET artifacts/TARGET/crash-...).
set -euo pipefail
cd "$(dirname "$0")/.."

secs="${1:-60}"
[ $# -gt 0 ] && shift
bash scripts/setup.sh --fuzz

# cargo fuzz builds with -Z flags (sanitizer, coverage): nightly if installed, else the
# default toolchain told to accept them.
toolchain=()
if rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
  toolchain=(+nightly)
else
  export RUSTC_BOOTSTRAP=1
fi

# The host reader targets write each input to a file too (to compare with the stream) and
# spool the formats that need random access: on a RAM disk that is a third of the time.
# Each run has a folder of its own there, removed at the end, so that runs side by side (a
# long run beside CI's) never remove each other's files.
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then
  export TMPDIR=/dev/shm
fi
TMPDIR="$(mktemp -d "${TMPDIR:-/tmp}/evcal-fuzz-run.XXXXXX")"
export TMPDIR
trap 'rm -rf "$TMPDIR"' EXIT

cd fuzz
if [ $# -gt 0 ]; then targets=("$@"); else mapfile -t targets < <(cargo fuzz list); fi
# EVCAL_FUZZ_SKIP: targets (space-separated) left out of this run, though built.
if [ -n "${EVCAL_FUZZ_SKIP:-}" ]; then
  kept=()
  for t in "${targets[@]}"; do
    case " $EVCAL_FUZZ_SKIP " in *" $t "*) echo "fuzz: $t skipped (EVCAL_FUZZ_SKIP)" ;; *) kept+=("$t") ;; esac
  done
  targets=("${kept[@]}")
fi
# Only the targets asked for are built: the host readers' build the host library and HDF5
# from source with the sanitizer, most of the build's time.
# The host readers' targets need the fuzz crate's `host` feature (fuzz/Cargo.toml).
features() {
  case "$1" in
    read_*) echo "--features=host" ;;
  esac
}
if [ $# -gt 0 ]; then
  for t in "${targets[@]}"; do cargo "${toolchain[@]}" fuzz build $(features "$t") "$t"; done
else
  cargo "${toolchain[@]}" fuzz build --features=host
fi
# The host readers start from files of each format (the fuzzer would take long to find an
# AEDAT4 or HDF5 structure by itself); the other targets start empty.
seeds() {
  case "$1" in
    read_text) ls ../host-tools/tests/fixtures/formats/*.txt ;;
    read_raw) ls ../tests/fixtures/prophesee/*.raw ;;
    read_dat) ls ../tests/fixtures/prophesee/*.dat ;;
    read_aedat4) ls ../host-tools/tests/fixtures/formats/*.aedat4 ;;
    read_bag) ls ../host-tools/tests/fixtures/formats/*.bag ;;
    read_h5) ls ../host-tools/tests/fixtures/formats/*.h5 ;;
  esac
}
# The streamed formats read the same at any length, so their inputs are kept to 8 KiB (over
# the 4096-byte text line limit, past a RAW event batch): each execution is then some ten
# times faster than on the 55-96 kB seeds. HDF5, AEDAT4 and bags need their whole structure,
# so they keep libFuzzer's default, the largest seed.
max_len() {
  case "$1" in
    read_text | read_raw | read_dat) echo "-max_len=8192" ;;
  esac
}
for t in "${targets[@]}"; do
  echo "fuzz: $t for $secs s"
  mkdir -p "corpus/$t"
  if [ -z "$(ls -A "corpus/$t")" ]; then
    for f in $(seeds "$t"); do cp "$f" "corpus/$t/"; done
  fi
  # -max_total_time ends a run cleanly; a crash or a failure to run exits nonzero.
  log="$(mktemp -p /tmp)"
  status=0
  # The HDF5 C library allocates global state on first use (filter registry, error stacks),
  # which LeakSanitizer reports as a leak of a run that cannot be reproduced alone; and on
  # corrupt metadata it asks malloc for absurd sizes and handles the failure (evcal then
  # reports the file as unreadable, in some 16 MB): malloc may fail there, as it does outside
  # the sanitizer. Memory actually used stays limited by libFuzzer's -rss_limit_mb.
  extra=()
  asan="${ASAN_OPTIONS:-}"
  if [ "$t" = read_h5 ]; then
    # Both leak checks off: libFuzzer's own (-detect_leaks) and LeakSanitizer's at the
    # process's exit (ASAN_OPTIONS), which otherwise fails the run on HDF5's few hundred
    # bytes of global state.
    extra=(-detect_leaks=0 -malloc_limit_mb=1048576)
    asan="${asan:+$asan:}allocator_may_return_null=1:detect_leaks=0"
  fi
  ASAN_OPTIONS="$asan" cargo "${toolchain[@]}" fuzz run $(features "$t") "$t" "corpus/$t" -- -max_total_time="$secs" -print_final_stats=1 $(max_len "$t") "${extra[@]}" >"$log" 2>&1 || status=$?
  grep -E '^(Done|stat::number_of_executed_units)|ERROR|panicked|SUMMARY|Test unit written' "$log" || true
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$log" >&2
    rm -f "$log"
    echo "fuzz: $t failed (exit $status); a failing input is kept in fuzz/artifacts/$t/" >&2
    exit 1
  fi
  rm -f "$log"
  rm -rf "${TMPDIR:?}"/evcal-fuzz-*
done
echo "fuzz: ${#targets[@]} targets, $secs s each, no failure"
