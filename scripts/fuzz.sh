#!/usr/bin/env bash
# Runs every cargo-fuzz target in fuzz/ for a bounded time each (default 30 s; the first
# argument or EVCAL_FUZZ_SECONDS sets it), on the nightly toolchain. Installs cargo-fuzz when
# missing (a few minutes of compiling, once per machine). Exits non-zero on the first crash;
# the input that crashed is saved under fuzz/artifacts/<target>/.
#   bash scripts/fuzz.sh          # all targets, 30 s each
#   bash scripts/fuzz.sh 300 evt3 # one target, 5 minutes
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${1:-${EVCAL_FUZZ_SECONDS:-30}}"
shift || true

if ! rustup toolchain list | grep -q '^nightly'; then
  echo "fuzz: installing the nightly toolchain (cargo-fuzz needs it)"
  rustup toolchain install nightly --profile minimal
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz"
  cargo install cargo-fuzz --locked --quiet
fi

targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
  mapfile -t targets < <(cd fuzz && cargo +nightly fuzz list)
fi
mkdir -p target
for t in "${targets[@]}"; do
  echo "=== fuzz $t for ${seconds}s"
  mkdir -p "fuzz/corpus/$t"
  rm -rf "fuzz/artifacts/$t"
  log="target/fuzz-$t.log"
  # -rss_limit_mb: the decoders allocate nothing; a large RSS would be a bug in a harness.
  if ! (cd fuzz && cargo +nightly fuzz run "$t" -- -max_total_time="$seconds" -rss_limit_mb=1024 \
        -print_final_stats=1) >"$log" 2>&1; then
    tail -40 "$log"
    echo "fuzz: $t failed; the input is in fuzz/artifacts/$t/ (full log: $log)"
    exit 1
  fi
  grep -E '^stat::number_of_executed_units' "$log" | sed "s/^/  $t: /" || true
done
echo "fuzz: ${#targets[@]} targets ran ${seconds}s each without a failure"
