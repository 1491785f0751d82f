#!/usr/bin/env bash
# Fetches faery's source distribution from PyPI and unpacks its real sensor recordings
# (tests/data/) and their reference figures (tests/assets.py) into target/test-data/faery/.
# The data are LGPL-3.0: they are fetched at test time and never committed.
# Idempotent: does nothing when the files are there. Prints the data directory.
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION="${FAERY_VERSION:-0.7.1}"
DEST=target/test-data/faery
if [ -f "$DEST/tests/assets.py" ] && [ -f "$DEST/tests/data/davis346.aedat4" ]; then
  echo "$DEST/tests/data"
  exit 0
fi

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 -m pip download --quiet --disable-pip-version-check --no-deps --no-binary faery \
  "faery==$VERSION" -d "$tmp" >&2
sdist="$(ls "$tmp"/faery-*.tar.gz)"
mkdir -p "$DEST"
# Only the test data and assets: the rest of the sdist (sources, fonts, docs) is not needed.
tar -xzf "$sdist" -C "$tmp" "faery-$VERSION/tests/data" "faery-$VERSION/tests/assets.py"
rm -rf "$DEST/tests"
mv "$tmp/faery-$VERSION/tests" "$DEST/tests"
echo "$DEST/tests/data"
