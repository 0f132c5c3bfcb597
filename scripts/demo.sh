#!/usr/bin/env bash
# The main job on the bundled default: opennav detect on the bundled RGB-D
# frame (MRPT bookshelf), prompt "book", 3D objects in the base frame, an
# overlay PNG and one PLY per object in out/demo/.
#   scripts/demo.sh [extra opennav detect arguments]
# Models: OPENNAV_MODELS, else ../shared/models beside the checkout, else models/.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
export ORT_DYLIB_PATH=${ORT_DYLIB_PATH:-$(scripts/fetch-onnxruntime.sh)}
models=${OPENNAV_MODELS:-}
if [ -z "$models" ]; then
  if [ -f "$repo/../shared/models/yolo11n_coco.onnx" ]; then models=$repo/../shared/models; else models=$repo/models; fi
fi
fx=tests/fixtures/mrpt_openni2
cargo build --release --quiet
exec target/release/opennav detect \
  --rgb $fx/rgb.png --depth $fx/depth_mm.png --calibration $fx/calibration.json \
  --prompt "book" --score-threshold 0.15 --models "$models" --out out/demo --format text "$@"
