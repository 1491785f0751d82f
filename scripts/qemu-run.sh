#!/usr/bin/env bash
# Runs a firmware ELF on QEMU's mps2 boards: mps2-an386 (Cortex-M4 with FPU) for an image built
# for the Cortex-M4 (the default), mps2-an500 (Cortex-M7) for one built with
# `-C target-cpu=cortex-m7` (feature board-mps2-an500, scripts/firmware-build.sh m7): the
# image's own ARM attributes say which. Semihosting for logs and the exit code, deterministic
# instruction timing (-icount shift=0), and a time limit so that a hung firmware can never
# hang CI.
#   EVCAL_QEMU_SERIAL  QEMU -serial argument (default: null), e.g. tcp:127.0.0.1:4555,server=on,wait=on,nodelay=on
#   EVCAL_QEMU_TIMEOUT seconds before QEMU is killed (default: 600)
#   EVCAL_QEMU_MACHINE mps2-an386 or mps2-an500, to override the image's CPU
# Further arguments go to QEMU after the image (e.g. -append "bench FILE", -plugin ...).
set -euo pipefail
elf="$1"; shift || true
cpu=$(readelf -A "$elf" | sed -n 's/.*Tag_CPU_name: "\(.*\)"/\1/p' | head -n 1)
case "${EVCAL_QEMU_MACHINE:-}" in
  mps2-an500) cpu=cortex-m7 ;;
  mps2-an386) cpu=cortex-m4 ;;
  "") ;;
  *) echo "qemu-run.sh: EVCAL_QEMU_MACHINE: mps2-an386 or mps2-an500, not $EVCAL_QEMU_MACHINE" >&2; exit 2 ;;
esac
case "$cpu" in
  cortex-m7) machine=mps2-an500 ;;
  *) machine=mps2-an386; cpu=cortex-m4 ;;
esac
exec timeout --kill-after=5 "${EVCAL_QEMU_TIMEOUT:-600}" qemu-system-arm \
  -machine "$machine" -cpu "$cpu" -nographic -monitor none \
  -icount shift=0 \
  -semihosting-config enable=on,target=native \
  -serial "${EVCAL_QEMU_SERIAL:-null}" \
  -kernel "$elf" "$@"
