#!/usr/bin/env bash
# Checks a firmware image against its board's memory budget (docs/firmware.md, Budgets held
# in CI): flash (.text + .rodata + .data, what the image puts in flash) and static RAM
# (.data + .bss) within the part's. Cortex-M4F boards (mps2-an386, stm32f405: an STM32F405):
# flash 512 KiB, static RAM the 128 KiB of SRAM, the stack the 64 KiB CCM. Cortex-M7 boards
# (mps2-an500, stm32h743: an STM32H743): flash 2 MiB, static RAM the 512 KiB AXI SRAM, the
# stack the 128 KiB DTCM. (firmware/boards/*.x; the stack's peak is checked by the QEMU
# tests and reported by the benchmark.) The detector's working memory is in its static
# storage, so these figures are the real budget; the linker enforces the same regions, this
# says by how much they are kept. Prints the figures.
# With a board's NAME it also checks that the image starts at that board's flash (its vector
# table where the chip boots from); without one, the Cortex-M4F's budget applies.
#   bash scripts/firmware-size.sh ELF [mps2-an386|stm32f405|mps2-an500|stm32h743]
set -euo pipefail
elf="$1"; name="${2:-$1}"
case "$name" in
  mps2-an500|stm32h743) flash_budget=$((2048 * 1024)); ram_budget=$((512 * 1024)) ;;
  *) flash_budget=$((512 * 1024)); ram_budget=$((128 * 1024)) ;;
esac
# binutils' size (it reads ARM ELFs), Berkeley format: text (code and read-only data,
# vector table included), data, bss.
read -r text data bss _ < <(size "$elf" | tail -n 1)
flash=$((text + data)); ram=$((data + bss))
echo "firmware size: $name: flash $flash B of $flash_budget, static RAM $ram B of $ram_budget"
ok=1
[ "$flash" -le "$flash_budget" ] || { echo "firmware size: $name: flash over budget by $((flash - flash_budget)) B" >&2; ok=0; }
[ "$ram" -le "$ram_budget" ] || { echo "firmware size: $name: static RAM over budget by $((ram - ram_budget)) B" >&2; ok=0; }
case "$name" in
  mps2-an386|mps2-an500) origin=0x00000000 ;;
  stm32f405|stm32h743) origin=0x08000000 ;;
  *) origin= ;;
esac
if [ -n "$origin" ]; then
  vt=$(size -A "$elf" | awk '$1 == ".vector_table" { print $3 }')
  [ "$((vt))" -eq "$((origin))" ] \
    || { echo "firmware size: $name: vector table at $(printf '0x%08x' "$vt"), not at the board's flash $origin" >&2; ok=0; }
fi
[ "$ok" = 1 ]
