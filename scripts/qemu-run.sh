#!/usr/bin/env bash
# Runs a firmware ELF on QEMU's mps2-an386 (Cortex-M4 with FPU): semihosting for logs and
# the exit code, deterministic instruction timing (-icount shift=0), and a time limit so
# that a hung firmware can never hang CI.
#   EVCAL_QEMU_SERIAL  QEMU -serial argument (default: null), e.g. tcp:127.0.0.1:4555,server=on,wait=on,nodelay=on
#   EVCAL_QEMU_TIMEOUT seconds before QEMU is killed (default: 600)
# Further arguments go to QEMU after the image (e.g. -append "bench FILE", -plugin ...).
set -euo pipefail
elf="$1"; shift || true
exec timeout --kill-after=5 "${EVCAL_QEMU_TIMEOUT:-600}" qemu-system-arm \
  -machine mps2-an386 -cpu cortex-m4 -nographic -monitor none \
  -icount shift=0 \
  -semihosting-config enable=on,target=native \
  -serial "${EVCAL_QEMU_SERIAL:-null}" \
  -kernel "$elf" "$@"
