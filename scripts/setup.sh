#!/usr/bin/env bash
# Installs everything evcal needs on a fresh machine of this kind (Debian + rustup).
# Idempotent: re-running it only checks. Called by scripts/test.sh and the README.
#   --fuzz   also cargo-fuzz (about a minute to build; scripts/fuzz.sh asks for it)
set -euo pipefail
want_fuzz=0
for arg in "$@"; do
  case "$arg" in
    --fuzz) want_fuzz=1 ;;
    *) echo "setup: unknown option $arg" >&2; exit 2 ;;
  esac
done

need_apt=()
dpkg -s libhdf5-dev >/dev/null 2>&1 || need_apt+=(libhdf5-dev)
dpkg -s pkg-config >/dev/null 2>&1 || need_apt+=(pkg-config)
if [ "${#need_apt[@]}" -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

# The core must build for the Cortex-M4F.
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
  echo "setup: adding rustup target thumbv7em-none-eabihf"
  rustup target add thumbv7em-none-eabihf
fi
for comp in clippy rustfmt; do
  rustup component list --installed | grep -q "^$comp" || rustup component add "$comp"
done
if [ "$want_fuzz" = 1 ] && ! command -v cargo-fuzz >/dev/null 2>&1; then
  echo "setup: installing cargo-fuzz (crates.io)"
  cargo install --quiet --locked cargo-fuzz
fi
echo "setup: ok"
