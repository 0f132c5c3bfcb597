#!/usr/bin/env bash
# The main job on the bundled defaults, no hardware needed:
# 1. opennav detect on the bundled RGB-D frame (MRPT bookshelf), prompt
#    "book": 3D objects in the base frame, an overlay PNG and one PLY per
#    object in out/demo/;
# 2. opennav run --sim — the daemon on the simulator's devices (the same
#    code as on the chair), on the virtual clock: the word "chair", the
#    chair finds one in the living room and drives there through the real
#    R-Net writer; its report goes to out/demo/run.json.
# 3. with OPENNAV_DEMO_WAV=FILE (16 kHz mono WAV, e.g. made with espeak-ng
#    and sox): the simulated chair listens to it instead of taking the word
#    (a build with the `voice` feature: PocketSphinx from Debian, which
#    tests/run.sh installs); synthetic speech is asked back ("Did you say
#    the chair?"), so the demo answers for it with voice.confirm = never.
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
echo "== building opennav (release; the first build takes several minutes) =="
cargo build --release --quiet
mkdir -p out/demo
# the detection part needs a detector's weights (not in the repository)
detector=""
for f in yolo_world.onnx yolo11n_coco.onnx; do
  if [ -f "$models/$f" ]; then detector=$models/$f; break; fi
done
if [ -n "$detector" ]; then
  echo "== opennav detect: the bundled RGB-D frame, prompt \"book\" ($detector) =="
  target/release/opennav detect \
    --rgb $fx/rgb.png --depth $fx/depth_mm.png --calibration $fx/calibration.json \
    --prompt "book" --score-threshold 0.15 --models "$models" --out out/demo --format text "$@"
else
  echo "== opennav detect skipped: it needs yolo11n_coco.onnx (or yolo_world.onnx) in $models; models/README.md says how to get it (or set OPENNAV_MODELS) =="
fi
echo
if [ -n "${OPENNAV_DEMO_WAV:-}" ]; then
  echo "== opennav run --sim: the simulated living room at the wall clock's pace, listening to $OPENNAV_DEMO_WAV =="
  cargo build --release --quiet --features voice
  OPENNAV_VOICE__CONFIRM=never target/release/opennav run --sim --clock realtime \
    --voice-wav "$OPENNAV_DEMO_WAV" --exit-on-arrival --max-duration 60s --no-stdin > out/demo/run.json
else
  echo "== opennav run --sim: the simulated living room on the virtual clock, word \"chair\" =="
  target/release/opennav run --sim --prompt chair --exit-on-arrival --max-duration 120s --no-stdin > out/demo/run.json
fi
python3 - out/demo/run.json <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
w = r["sim"]["world"]
print(f"outcome: {r['outcome']} after {r['duration_s']:.1f} s; said: {' / '.join(r['said'])}")
d = r['sim']['distance_to_goal_object_m']
print(f"travelled {w['distance_travelled_m']:.2f} m, collisions {w['collision_steps']}, "
      f"closest approach to anything {w['min_clearance_m']:.2f} m"
      + (f", {d:.2f} m from the goal at the end" if d is not None else ""))
print(f"R-Net frames sent {r['actuator']['sent']}, period p50 {r['actuator']['period']['p50_us']/1000:.2f} ms")
PY
