#!/usr/bin/env bash
# Checks a firmware image against the memory budget (docs/firmware.md, Budgets held in CI):
# flash (.text + .rodata + .data, what the image puts in flash) at most 512 KiB, static RAM
# (.data + .bss) at most 80 KiB, so that the stack keeps 48 KiB of a 128 KiB part (its peak
# is 43.7 KB on the emulated board, docs/firmware.md). The detector's working memory is in
# its static storage, so this figure is the real budget. The linker enforces only the
# 512 KiB / 128 KiB regions (memory.x, firmware/boards/*.x); static RAM creeping past 80 KiB
# would eat the stack silently. Prints the figures.
#   bash scripts/firmware-size.sh ELF [NAME]
set -euo pipefail
elf="$1"; name="${2:-$1}"
flash_budget=$((512 * 1024)); ram_budget=$((80 * 1024))
# binutils' size (it reads ARM ELFs), Berkeley format: text (code and read-only data,
# vector table included), data, bss.
read -r text data bss _ < <(size "$elf" | tail -n 1)
flash=$((text + data)); ram=$((data + bss))
echo "firmware size: $name: flash $flash B of $flash_budget, static RAM $ram B of $ram_budget"
ok=1
[ "$flash" -le "$flash_budget" ] || { echo "firmware size: $name: flash over budget by $((flash - flash_budget)) B" >&2; ok=0; }
[ "$ram" -le "$ram_budget" ] || { echo "firmware size: $name: static RAM over budget by $((ram - ram_budget)) B" >&2; ok=0; }
[ "$ok" = 1 ]
