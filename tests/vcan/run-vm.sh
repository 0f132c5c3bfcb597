#!/usr/bin/env bash
# Boots a small VM with real SocketCAN (Debian's kernel, modules can,
# can-raw, can-dev, vcan) and runs a command on vcan0 inside it. For hosts
# whose kernel has no CAN (this project's CI). Usage:
#
#   tests/vcan/run-vm.sh BINARY [ARGS...]
#   tests/vcan/run-vm.sh --fetch-only    (download and cache the kernel)
#
# BINARY and every absolute path among ARGS that names an executable file
# are copied into the VM's initramfs (with the shared libraries they need)
# at the same path. The VM prints `OPENNAV-VM-EXIT <rc>` when the command
# ends; this script exits with that rc (or 3 when the VM failed to run it).
#
# Needs: qemu-system-x86_64, busybox (static), cpio, apt-get (Debian 12).
# The kernel package is pinned and cached in $OPENNAV_VM_CACHE
# (default ~/.cache/opennav/vm).
set -euo pipefail

# The pinned kernel: linux-image-amd64's target on Debian 12 when this was
# written. If the mirror no longer has it, the current one is used (loudly).
KVER_PINNED="6.1.0-56-amd64"
PKGVER_PINNED="6.1.192-2"
# CAN for the R-Net tests; evdev + uinput for the switch tests (a virtual
# input device read through /dev/input/event*)
MODULES="kernel/net/can/can.ko kernel/drivers/net/can/dev/can-dev.ko kernel/net/can/can-raw.ko kernel/drivers/net/can/vcan.ko kernel/drivers/input/evdev.ko kernel/drivers/input/misc/uinput.ko"

die() { echo "run-vm: $*" >&2; exit 3; }
[ $# -ge 1 ] || die "usage: $0 BINARY [ARGS...]"
for tool in qemu-system-x86_64 cpio apt-get dpkg; do
    command -v "$tool" >/dev/null || die "$tool not found (apt-get install qemu-system-x86 busybox-static cpio)"
done
BUSYBOX=""
for b in /bin/busybox /usr/bin/busybox; do
    if [ -x "$b" ] && ! ldd "$b" >/dev/null 2>&1; then BUSYBOX="$b"; break; fi
done
[ -n "$BUSYBOX" ] || die "a static busybox is needed (apt-get install busybox-static)"
BIOS=/usr/share/qemu/qboot.rom
[ -f "$BIOS" ] || BIOS=""

CACHE="${OPENNAV_VM_CACHE:-$HOME/.cache/opennav/vm}"
mkdir -p "$CACHE"

fetch_kernel() { # $1 = kernel version, $2 = package version (or empty)
    local kver="$1" pkg="linux-image-$1" dir="$CACHE/$1"
    # the cache holds the kernel and exactly the modules listed above
    if [ -f "$dir/vmlinuz" ] && [ -f "$dir/ok" ] && [ "$(cat "$dir/ok")" = "$MODULES" ]; then echo "$dir"; return 0; fi
    local tmp; tmp="$(mktemp -d)"
    local spec="$pkg"; [ -n "$2" ] && spec="$pkg=$2"
    if ! (cd "$tmp" && apt-get download "$spec" >/dev/null 2>&1); then
        # the package lists may be stale on a fresh machine
        if [ "$(id -u)" = 0 ]; then apt-get update -qq >/dev/null 2>&1 || true;
        elif command -v sudo >/dev/null; then sudo apt-get update -qq >/dev/null 2>&1 || true; fi
        (cd "$tmp" && apt-get download "$spec" >/dev/null 2>&1) || { rm -rf "$tmp"; return 1; }
    fi
    dpkg -x "$tmp"/*.deb "$tmp/root"
    mkdir -p "$dir/modules"
    cp "$tmp/root/boot/vmlinuz-$kver" "$dir/vmlinuz"
    for m in $MODULES; do
        cp "$tmp/root/lib/modules/$kver/$m" "$dir/modules/" || { rm -rf "$tmp"; return 1; }
    done
    printf '%s' "$MODULES" > "$dir/ok"
    rm -rf "$tmp"
    echo "$dir"
}

if ! KDIR="$(fetch_kernel "$KVER_PINNED" "$PKGVER_PINNED")"; then
    CUR="$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-/{sub("linux-image-","",$2); print $2; exit}')"
    [ -n "$CUR" ] || die "cannot find the pinned kernel linux-image-$KVER_PINNED ($PKGVER_PINNED) nor linux-image-amd64's target"
    echo "run-vm: WARNING: pinned kernel $KVER_PINNED ($PKGVER_PINNED) is gone from the mirror; using $CUR — update KVER_PINNED in $0" >&2
    KDIR="$(fetch_kernel "$CUR" "")" || die "cannot download linux-image-$CUR"
fi

if [ "$1" = "--fetch-only" ]; then echo "kernel cached in $KDIR"; exit 0; fi

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
ROOT="$WORK/root"
mkdir -p "$ROOT"/{bin,proc,sys,dev,tmp,lib/modules}
cp "$BUSYBOX" "$ROOT/bin/busybox"
cp "$KDIR"/modules/*.ko "$ROOT/lib/modules/"

add_binary() { # copies an executable and its shared libraries, same paths
    local f="$1"
    mkdir -p "$ROOT$(dirname "$f")"
    # debug info is not needed in the VM and would bloat the initramfs
    objcopy --strip-debug "$f" "$ROOT$f" 2>/dev/null || cp "$f" "$ROOT$f"
    chmod +x "$ROOT$f"
    ldd "$f" 2>/dev/null | grep -o '/[^ ]*' | while read -r lib; do
        [ -f "$lib" ] || continue
        mkdir -p "$ROOT$(dirname "$lib")"
        [ -f "$ROOT$lib" ] || cp -L "$lib" "$ROOT$lib"
    done
}
add_binary "$(readlink -f "$1")"
CMD="$(readlink -f "$1")"
shift
for a in "$@"; do
    if [[ "$a" == /* ]] && [ -f "$a" ] && [ -x "$a" ]; then add_binary "$a"; fi
    CMD="$CMD $(printf '%q' "$a")"
done

cat > "$ROOT/init" <<EOF
#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in can can-dev can-raw vcan evdev uinput; do insmod /lib/modules/\$m.ko || echo "insmod \$m failed"; done
ip link add vcan0 type vcan && ip link set vcan0 up || echo "vcan0 setup failed"
ip link set lo up
cd /tmp
$CMD
echo "OPENNAV-VM-EXIT \$?"
poweroff -f
EOF
chmod +x "$ROOT/init"
(cd "$ROOT" && find . | cpio -o -H newc --quiet) > "$WORK/initrd.cpio"

ACCEL="tcg"
# KVM only where a hardware-virtualisation module is loaded and usable
if [ -w /dev/kvm ] && grep -qE '^(kvm_intel|kvm_amd) ' /proc/modules 2>/dev/null; then ACCEL="kvm"; fi

# one vCPU: under TCG a second one competes with the first for the host
# and doubles the timer jitter the period test measures
SMP="${OPENNAV_VM_SMP:-1}"
LOG="$WORK/console.log"
set +e
timeout "${OPENNAV_VM_TIMEOUT:-300}" qemu-system-x86_64 \
    -accel "$ACCEL" -cpu max -smp "$SMP" -m 768 -nographic -nodefaults \
    -serial stdio -no-reboot ${BIOS:+-bios "$BIOS"} \
    -kernel "$KDIR/vmlinuz" -initrd "$WORK/initrd.cpio" \
    -append "console=ttyS0 quiet panic=-1" \
    -device isa-debug-exit,iobase=0xf4,iosize=0x04 | tee "$LOG"
set -e
RC="$(grep -a -o 'OPENNAV-VM-EXIT [0-9]*' "$LOG" | tail -1 | awk '{print $2}')"
[ -n "$RC" ] || die "the VM did not report an exit status (see the console output above)"
exit "$RC"
