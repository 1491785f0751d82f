#!/usr/bin/env bash
# Runs every cargo-fuzz target in fuzz/ for a bounded time each.
#
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]    (default: 60 s, every target)
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

cd fuzz
if [ $# -gt 0 ]; then targets=("$@"); else mapfile -t targets < <(cargo fuzz list); fi
cargo "${toolchain[@]}" fuzz build
for t in "${targets[@]}"; do
  echo "fuzz: $t for $secs s"
  mkdir -p "corpus/$t"
  # -max_total_time ends a run cleanly; a crash or a failure to run exits nonzero.
  log="$(mktemp)"
  status=0
  cargo "${toolchain[@]}" fuzz run "$t" "corpus/$t" -- -max_total_time="$secs" -print_final_stats=1 >"$log" 2>&1 || status=$?
  grep -E '^(Done|stat::number_of_executed_units)|ERROR|panicked|SUMMARY|Test unit written' "$log" || true
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$log" >&2
    rm -f "$log"
    echo "fuzz: $t failed (exit $status); a failing input is kept in fuzz/artifacts/$t/" >&2
    exit 1
  fi
  rm -f "$log"
done
echo "fuzz: ${#targets[@]} targets, $secs s each, no failure"
