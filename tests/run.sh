#!/usr/bin/env bash
# The test command: installs what the full suite needs, then runs it.
#   tests/run.sh            everything (format, lint, unit + integration tests)
# Needs: a Rust toolchain and network access to the package registries.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
export OPENNAV_SHARED=${OPENNAV_SHARED:-$repo/../shared}

step() { printf '\n== %s ==\n' "$*"; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "tests/run.sh: need root (or sudo) to run: $*" >&2; return 1; fi
}

step "system packages"
# AVR toolchain + simavr: firmware in the loop; qemu + busybox + cpio: the
# vcan HIL VM (tests/vcan/run-vm.sh; binutils for objcopy); systemd +
# iproute2: `systemd-analyze verify/security` on the units (tests/systemd_units.rs);
# espeak-ng: the chair's spoken sentences (src/speech.rs); PocketSphinx:
# speech recognition (the `voice` feature), sox to prepare test speech;
# sphinxtrain, sphinxbase-utils, pocketsphinx: `opennav voice enroll` (the
# person's voice, src/voice/enroll.rs)
apt_pkgs=(make gcc binutils gcc-avr avr-libc simavr libsimavr-dev libelf-dev qemu-system-x86 busybox-static cpio systemd iproute2 espeak-ng
  libpocketsphinx-dev libsphinxbase-dev pocketsphinx-en-us sox sphinxtrain sphinxbase-utils pocketsphinx)
# a python3 with venv already on PATH (pyenv, say) is enough; else Debian's
python3 -c 'import venv, ensurepip' 2>/dev/null || apt_pkgs+=(python3 python3-venv python3-pip)
missing=()
for p in "${apt_pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
fi
echo "ok"

step "ONNX Runtime library"
lib=$(scripts/fetch-onnxruntime.sh)
export ORT_DYLIB_PATH=$lib
echo "$ORT_DYLIB_PATH"

step "Python packages for fixtures"
if [ ! -x .venv/bin/python ]; then python3 -m venv .venv; fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check -r tests/fixtures/requirements.txt

step "test assets"
for f in "$OPENNAV_SHARED/models/yolo11n_coco.onnx" "$OPENNAV_SHARED/data/images/bus.jpg"; do
  if [ ! -f "$f" ]; then
    echo "tests/run.sh: MISSING TEST ASSET $f (the shared folder belongs beside the checkout, or set OPENNAV_SHARED)" >&2
    exit 1
  fi
done
.venv/bin/python tests/fixtures/generate.py "$OPENNAV_SHARED" tests/fixtures/generated

step "vcan HIL VM kernel"
# Debian's kernel (pinned, cached in ~/.cache/opennav/vm) for the CAN tests
bash tests/vcan/run-vm.sh --fetch-only

# One build from scratch: incremental state would only add gigabytes
export CARGO_INCREMENTAL=${CARGO_INCREMENTAL:-0}
df -h "$repo" | awk 'NR==2 {print "disk before the build: " $4 " free"}'

step "format"
cargo fmt --all -- --check

step "lint"
# Every feature this machine can build: the default set (ONNX Runtime is
# loaded at run time; CUDA/TensorRT providers are compiled in), voice and
# ros2. The
# `realsense` feature links librealsense2, which no registry ships: its
# source is type-checked without the library (realsense-rust/docs-only
# skips the link step), not linked.
cargo clippy --all-targets --features voice,ros2 -- -D warnings
cargo clippy --lib --bins --features realsense,realsense-rust/docs-only -- -D warnings

step "tests"
# the `voice` feature too (PocketSphinx, installed above), and the ROS 2
# bridge (tested against Cyclone DDS from requirements.txt). DDS discovery
# is multicast: loopback gets it too where we may set it (a machine whose
# only other interface has none still finds its own peers).
if ip link show lo | grep -q MULTICAST; then :
elif ip link set lo multicast on 2>/dev/null; then echo "loopback: multicast on (DDS discovery)"
else echo "loopback: multicast off and not settable here; DDS discovery uses the other interfaces"
fi
cargo test --no-fail-fast --features voice,ros2 2>&1 | tee target/test-output.txt
du -sh target | awk '{print "build folder: " $1}'
df -h "$repo" | awk 'NR==2 {print "disk after the tests: " $4 " free"}'
