#!/usr/bin/env bash
# Fetches the ONNX Runtime shared library that opennav loads through `ort`
# (load-dynamic): the CPU build 1.31.1 from its PyPI wheel, checksum-verified,
# extracted into a project-local folder.
#
#   scripts/fetch-onnxruntime.sh [DEST]     (default: .onnxruntime/ in the repo)
#
# Prints the library path on success. Nothing else is downloaded at build time.
set -euo pipefail

VERSION=1.31.1
WHEEL=onnxruntime-${VERSION}-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
SHA256=5752bd508126ae7c49894d3b9d2e83f0c3d487319246d04c444b393308d7ad7f
repo=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-$repo/.onnxruntime}
lib=$dest/libonnxruntime.so.$VERSION

if [ -f "$lib" ] && [ -f "$dest/.sha256-ok" ]; then
  echo "$lib"
  exit 0
fi
mkdir -p "$dest"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 -m pip download --quiet --no-deps --only-binary=:all: \
  --platform manylinux_2_28_x86_64 --python-version 3.11 --implementation cp --abi cp311 \
  -d "$work" "onnxruntime==$VERSION" >&2
whl=$(ls "$work"/onnxruntime-"$VERSION"-*.whl 2>/dev/null | head -n 1)
if [ -z "$whl" ]; then
  echo "fetch-onnxruntime: pip did not produce an onnxruntime $VERSION wheel" >&2
  exit 1
fi
got=$(sha256sum "$whl" | cut -d' ' -f1)
if [ "$got" != "$SHA256" ]; then
  echo "fetch-onnxruntime: checksum mismatch for $(basename "$whl"): got $got, want $SHA256" >&2
  exit 1
fi
python3 - "$whl" "$dest" "$VERSION" <<'PY'
import sys, zipfile, os
whl, dest, ver = sys.argv[1:]
name = f"onnxruntime/capi/libonnxruntime.so.{ver}"
with zipfile.ZipFile(whl) as z:
    data = z.read(name)
out = os.path.join(dest, f"libonnxruntime.so.{ver}")
with open(out + ".tmp", "wb") as f:
    f.write(data)
os.replace(out + ".tmp", out)
PY
ln -sf "libonnxruntime.so.$VERSION" "$dest/libonnxruntime.so"
echo "$WHEEL $SHA256" > "$dest/.sha256-ok"
echo "$lib"
