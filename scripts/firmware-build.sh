#!/usr/bin/env bash
# Builds a board's firmware image and prints its path.
#   bash scripts/firmware-build.sh [m4f|m7|stm32f405|stm32h743] [cargo build options...]
#   m4f        QEMU mps2-an386 (Cortex-M4F), the default image: target/thumbv7em-none-eabihf/firmware/evcal-firmware
#   stm32f405  a real STM32F405, same place (it overwrites the m4f image)
#   m7         QEMU mps2-an500 (Cortex-M7): target/m7/thumbv7em-none-eabihf/firmware/evcal-firmware
#   stm32h743  a real STM32H743, same place as m7 (it overwrites the m7 image)
# The Cortex-M7 images are built with `-C target-cpu=cortex-m7` (.cargo/config.toml sets
# cortex-m4 for the target; cargo's per-target environment variable replaces it) in a target
# directory of their own, target/m7: flags that differ would otherwise rebuild every
# dependency each time the other core's image is built.
set -euo pipefail
cd "$(dirname "$0")/.."
board="${1:-m4f}"; shift || true
target_dir="${CARGO_TARGET_DIR:-target}"
fw=(-p evcal-firmware --target thumbv7em-none-eabihf --profile firmware)
case "$board" in
  m4f) cargo build -q "${fw[@]}" "$@" ;;
  stm32f405) cargo build -q "${fw[@]}" --features board-stm32f405 "$@" ;;
  m7|stm32h743)
    feature=board-mps2-an500; [ "$board" = stm32h743 ] && feature=board-stm32h743
    target_dir="$target_dir/m7"
    CARGO_TARGET_DIR="$target_dir" CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS="-C target-cpu=cortex-m7" \
      cargo build -q "${fw[@]}" --features "$feature" "$@" ;;
  *) echo "firmware-build.sh: m4f, m7, stm32f405 or stm32h743, not $board" >&2; exit 2 ;;
esac
echo "$target_dir/thumbv7em-none-eabihf/firmware/evcal-firmware"
