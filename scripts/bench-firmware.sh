#!/usr/bin/env bash
# The firmware benchmark (not a test): cost of the host's windows on a board's core under
# QEMU. Simulates a recording of the sensor (4x11 grid, cone; 3.5 s, about 100 windows at
# the paper's 33 ms), replays it into the firmware from a bulk file, checks every window
# against the host's core bit for bit, and prints instructions per window (exact, between
# the firmware's bench_start/bench_stop markers, counted by a QEMU plugin), per stage
# (SysTick under -icount shift=0), the time they imply at the board's clock, and flash/RAM;
# it ends with one `bench-summary:` line a script can read (tests/examples/bench_firmware.rs).
#   bash scripts/bench-firmware.sh [--board m4f|m7] [--sensor davis346|genx320|dvxplorer|imx636]
#        [--light good|low] [--seconds S] [--step-ms MS] [--events N] [--cpi X] [--mhz F] [--profile N]
# Takes about a minute (mostly the simulation); output also goes to target/bench-firmware/report.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh >/dev/null
mkdir -p target/bench-firmware
plugin=target/bench-firmware/libinsn_count.so
if [ ! -e "$plugin" ] || [ firmware/tools/insn_count.c -nt "$plugin" ]; then
  gcc -shared -fPIC -O2 -Wall -o "$plugin" firmware/tools/insn_count.c
fi
# The example builds the board's image itself (tests/src/firmware.rs, build_firmware_for).
cargo run -q --release -p evcal-tests --example bench_firmware -- --plugin "$plugin" "$@" \
  | tee target/bench-firmware/report.txt
