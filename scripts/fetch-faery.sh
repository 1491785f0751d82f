#!/usr/bin/env bash
# Fetches the real sensor recordings that ship in faery's source distribution (PyPI, LGPL-3.0
# data: fetched at test time, never committed) and prints the directory that holds them:
#   davis346.aedat4  evt2.raw  evt3.raw  gen4.dat  ...  and ../assets.py (digests, time ranges)
#
#   DATA=$(bash scripts/fetch-faery.sh)     # e.g. target/test-data/faery-0.7.1/tests/data
#
# Idempotent and quiet when the data is already there (checked by the archive's digest).
# Messages go to standard error; only the directory goes to standard output. Exit status is
# non-zero if the data cannot be had (no network to PyPI, no pip).
# Override the destination with EVCAL_TEST_DATA (default: <repo>/target/test-data).
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION=0.7.1
# sha256 of faery-0.7.1.tar.gz as published on PyPI: pins the files the tests' numbers are for.
SHA256=15ddf16d927d6b7c88c1e8b9adb72fe17dc17d08f6ac81f7404ec4d5e9528e56

root="${EVCAL_TEST_DATA:-$PWD/target/test-data}"
dest="$root/faery-$VERSION"
stamp="$dest/.fetched-$SHA256"

# One fetch at a time: a test binary's tests call this at once, and a second caller must wait
# for the first to finish, not read the directory while it is being replaced.
mkdir -p "$root"
exec 9>"$root/.fetch-faery.lock"
flock 9

if [ ! -f "$stamp" ]; then
  echo "fetch-faery: downloading faery $VERSION's source distribution from PyPI" >&2
  tmp="$(mktemp -d "$root/.fetch.XXXXXX")"
  trap 'rm -rf "$tmp"' EXIT
  python3 -m pip download --quiet --disable-pip-version-check --no-deps --no-binary faery \
    "faery==$VERSION" -d "$tmp" >&2
  archive="$tmp/faery-$VERSION.tar.gz"
  got="$(sha256sum "$archive" | cut -d' ' -f1)"
  if [ "$got" != "$SHA256" ]; then
    echo "fetch-faery: $archive has sha256 $got, expected $SHA256" >&2
    exit 1
  fi
  tar -xzf "$archive" -C "$tmp" "faery-$VERSION/tests/data" "faery-$VERSION/tests/assets.py" \
    "faery-$VERSION/LICENSE"
  rm -rf "$dest"
  mv "$tmp/faery-$VERSION" "$dest"
  touch "$stamp"
  echo "fetch-faery: ok, $(ls "$dest/tests/data" | wc -l) files in $dest/tests/data" >&2
fi
echo "$dest/tests/data"
