#!/usr/bin/env bash
# Installs everything evcal needs on a fresh machine of this kind (Debian + rustup).
# Idempotent: re-running it only checks. Called by scripts/test.sh and the README.
#   --fuzz   also cargo-fuzz (about a minute to build; scripts/fuzz.sh asks for it)
#   --host   only what building the host tool `evcal` needs (a C compiler, pkg-config, CMake
#            >= 3.26 for HDF5): no QEMU, no firmware target, no Python test stack
set -euo pipefail
want_fuzz=0
host_only=0
for arg in "$@"; do
  case "$arg" in
    --fuzz) want_fuzz=1 ;;
    --host) host_only=1 ;;
    *) echo "setup: unknown option $arg" >&2; exit 2 ;;
  esac
done

need_apt=()
dpkg -s pkg-config >/dev/null 2>&1 || need_apt+=(pkg-config)
command -v gcc >/dev/null 2>&1 || need_apt+=(gcc)
# binutils' size, nm and readelf read the firmware's ARM ELF (scripts/firmware-size.sh, the QEMU
# tests; scripts/qemu-run.sh picks the emulated board from the image's CPU with readelf).
command -v size >/dev/null 2>&1 || need_apt+=(binutils)
if [ "${#need_apt[@]}" -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

# CMake >= 3.26 builds HDF5 from source (the hdf5 crate's "static"; Debian 12's cmake is
# 3.25): from PyPI, pinned, when the one on PATH is older.
cmake_ok() {
  command -v cmake >/dev/null 2>&1 || return 1
  local v
  v="$(cmake --version | head -1 | awk '{print $3}')"
  [ "$(printf '%s\n3.26\n' "$v" | sort -V | head -1)" = "3.26" ]
}
if ! cmake_ok; then
  echo "setup: installing CMake 3.31.10 (Python package cmake)"
  python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "cmake==3.31.10"
  command -v pyenv >/dev/null 2>&1 && pyenv rehash
  hash -r
  cmake_ok || { echo "setup: cmake >= 3.26 is still not first on PATH ($(command -v cmake || echo none)); put pip's scripts folder first" >&2; exit 1; }
fi
if [ "$host_only" = 1 ]; then
  echo "setup: ok (the host tool's needs)"
  exit 0
fi

# The emulated boards the firmware is tested on (QEMU's mps2-an386 and mps2-an500); without its recommended
# packages (GUI, firmware images for other machines), which the tests do not need.
if ! dpkg -s qemu-system-arm >/dev/null 2>&1; then
  echo "setup: installing Debian package qemu-system-arm"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  [ "${#need_apt[@]}" -gt 0 ] || $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends qemu-system-arm >/dev/null
fi

# Independent writers of the recording formats (scripts/make-format-fixtures.py): iniVation's
# dv-processing (AEDAT4), rosbags (ROS1 bags), h5py and hdf5plugin (HDF5, Blosc as DSEC
# uses it), at the versions that wrote the committed fixtures. pip also fetches faery's test
# recordings (scripts/fetch-faery.sh).
writers=(dv-processing==2.0.4 rosbags==0.11.9 h5py==3.16.0 hdf5plugin==7.1.0)
# Independent readers of the calibration exports (host-tools/src/export tests): OpenCV's
# cv::FileStorage and PyYAML (as Kalibr reads a camchain).
readers=(opencv-python-headless==4.12.0.88 PyYAML==6.0.3)
if ! python3 - "${writers[@]}" "${readers[@]}" >/dev/null 2>&1 <<'PY'
import importlib.metadata as m, sys
for w in sys.argv[1:]:
    name, version = w.split("==")
    if m.version(name) != version:
        sys.exit(1)
PY
then
  echo "setup: installing Python packages: ${writers[*]} ${readers[*]} numpy"
  python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "${writers[@]}" "${readers[@]}" numpy
fi

# The core and the firmware build for the Cortex-M4F.
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
  echo "setup: adding rustup target thumbv7em-none-eabihf"
  rustup target add thumbv7em-none-eabihf
fi
for comp in clippy rustfmt; do
  rustup component list --installed | grep -q "^$comp" || rustup component add "$comp"
done
# Python packages the tests use as independent writers of Prophesee files
# (tests/fixtures/prophesee/make.py): expelliarmus and numpy.
if ! python3 -c "import expelliarmus, numpy" >/dev/null 2>&1; then
  echo "setup: installing Python packages: expelliarmus numpy"
  python3 -m pip install --quiet --disable-pip-version-check "expelliarmus==1.1.12" numpy
fi
if [ "$want_fuzz" = 1 ] && ! command -v cargo-fuzz >/dev/null 2>&1; then
  echo "setup: installing cargo-fuzz (crates.io)"
  cargo install --quiet --locked cargo-fuzz
fi
echo "setup: ok"
