#!/usr/bin/env bash
# Fetches ONNX Runtime's shared library from PyPI's `onnxruntime` wheel into target/ort (once)
# and prints its path, for `export ORT_DYLIB_PATH=$(tools/setup_ort.sh)`. Needs python3 + pip.
# The version is pinned: the `ort` crate (Cargo.toml) is built against this API version.
set -euo pipefail
cd "$(dirname "$0")/.."
VERSION="${ORT_VERSION:-1.31.1}"
DEST="target/ort/onnxruntime-$VERSION"
find_lib() { find "$DEST/onnxruntime/capi" -maxdepth 1 -name 'libonnxruntime.so.*' -type f 2>/dev/null | sort | head -n 1; }
LIB="$(find_lib || true)"
if [[ -z "$LIB" ]]; then
  mkdir -p target/ort
  TMP="$(mktemp -d target/ort/.download.XXXXXX)"
  trap 'rm -rf "$TMP"' EXIT
  get() { python3 -m pip download --quiet --disable-pip-version-check --no-deps \
    --only-binary=:all: "onnxruntime==$VERSION" -d "$TMP" "$@" >&2; }
  # The library inside does not depend on the Python version: if the local interpreter has no
  # wheel of this version, take the CPython 3.12 one for this machine.
  get || get --python-version 3.12 --implementation cp --platform "manylinux_2_28_$(uname -m)"
  WHEEL="$(ls "$TMP"/onnxruntime-*.whl)"
  # A wheel is a zip archive; Python's zipfile unpacks it without other tools.
  python3 - "$WHEEL" "$TMP/unpacked" <<'PY'
import sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z:
    for name in z.namelist():
        if name.startswith("onnxruntime/capi/libonnxruntime.so"):
            z.extract(name, sys.argv[2])
PY
  rm -rf "$DEST"
  mv "$TMP/unpacked" "$DEST"
  LIB="$(find_lib || true)"
fi
if [[ -z "$LIB" || ! -f "$LIB" ]]; then
  echo "setup_ort.sh: no libonnxruntime.so.* in the onnxruntime $VERSION wheel" >&2
  exit 1
fi
realpath "$LIB"
