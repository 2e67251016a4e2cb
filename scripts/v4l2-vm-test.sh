#!/usr/bin/env bash
# Runs the V4L2 driver tests against the kernel's vivid test driver inside a
# qemu VM (TCG; KVM stalled on the lab machines), because no host here has a
# capture device or the vivid module loaded.
#
#   scripts/v4l2-vm-test.sh TEST_BINARY WORK_DIR [gtest arguments...]
#
# WORK_DIR (CTest passes <build>/v4l2-vm) caches Debian's kernel package
# (fetched once with `apt-get download`, no root needed) and holds the
# initramfs and the serial console log of the last run. The VM boots the
# package's vmlinuz with an initramfs of busybox, the test binary and its
# shared libraries, loads the media modules with insmod in dependency order,
# runs the tests against /dev/video0 and prints
#   PHOTORIG-VM-RESULT: PASS rc=0   (or FAIL rc=<gtest exit code>)
# on the serial console. Exit status: the test binary's (0 = pass), 1 when the
# VM never reported, 77 (CTest's SKIP_RETURN_CODE) when qemu, busybox, cpio or
# the kernel package is missing.
set -euo pipefail

if [ $# -lt 2 ]; then
  echo "usage: $0 TEST_BINARY WORK_DIR [gtest arguments...]" >&2
  exit 2
fi
test_binary=$(readlink -f "$1")
work=$2
shift 2
gtest_args=("$@")
vm_timeout_s=${PHOTORIG_VM_TIMEOUT_S:-150}
skip_code=77

skip() {
  echo "v4l2-vm-test: skipped: $*"
  exit "$skip_code"
}

# Media core first, vivid last: each module needs the ones before it.
modules=(mc videodev v4l2-dv-timings videobuf2-common videobuf2-v4l2 videobuf2-memops
         videobuf2-dma-contig videobuf2-vmalloc rc-core cec v4l2-tpg vivid)
# Two vivid instances with one webcam input each: /dev/video0 single-planar
# (what the driver streams from), /dev/video1 multi-planar only (must be refused).
vivid_params="n_devs=2 node_types=0x1,0x1 multiplanar=1,2 num_inputs=1,1 input_types=0,0"

[ -x "$test_binary" ] || { echo "v4l2-vm-test: no test binary at $test_binary" >&2; exit 2; }
command -v qemu-system-x86_64 >/dev/null || skip "qemu-system-x86_64 not found (scripts/install-deps.sh installs qemu-system-x86)"
command -v cpio >/dev/null || skip "cpio not found (scripts/install-deps.sh installs it)"
busybox=$(command -v busybox || true)
[ -n "$busybox" ] || skip "busybox not found (scripts/install-deps.sh installs busybox-static)"

mkdir -p "$work/cache"
work=$(readlink -f "$work")

# --- the kernel: Debian's linux-image package, downloaded once ---------------
deb=$(ls "$work"/cache/linux-image-*-amd64_*.deb 2>/dev/null | sort -V | tail -n 1 || true)
if [ -z "$deb" ]; then
  package=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
  [ -n "$package" ] || skip "apt-cache does not know linux-image-amd64 (run apt-get update, or scripts/install-deps.sh)"
  echo "v4l2-vm-test: downloading $package into $work/cache"
  if ! (cd "$work/cache" && apt-get download -q "$package" >"$work/cache/download.log" 2>&1); then
    skip "apt-get download $package failed: $(tail -n 1 "$work/cache/download.log")"
  fi
  deb=$(ls "$work"/cache/linux-image-*-amd64_*.deb 2>/dev/null | sort -V | tail -n 1 || true)
  [ -n "$deb" ] || skip "apt-get download $package left no .deb in $work/cache"
fi

# Only the kernel image and the media modules are unpacked (dpkg -x would
# write the whole 400 MB tree).
kernel_dir="$work/kernel/$(basename "$deb" .deb)"
if [ ! -f "$kernel_dir/.unpacked" ]; then
  rm -rf "$kernel_dir"
  mkdir -p "$kernel_dir"
  if ! dpkg-deb --fsys-tarfile "$deb" |
    tar -x -C "$kernel_dir" --wildcards './boot/vmlinuz-*' './lib/modules/*/kernel/drivers/media/*'; then
    rm -f "$deb"  # fetched again next time
    echo "v4l2-vm-test: FAIL: cannot unpack $deb (damaged download? removed)" >&2
    exit 1
  fi
  touch "$kernel_dir/.unpacked"
fi
vmlinuz=$(ls "$kernel_dir"/boot/vmlinuz-* | head -n 1)
media_dir=$(ls -d "$kernel_dir"/lib/modules/*/kernel/drivers/media)

# --- the initramfs ----------------------------------------------------------
root="$work/initramfs"
rm -rf "$root"
mkdir -p "$root"/{bin,dev,proc,sys,tmp,modules,test}

copy_with_libraries() {  # FILE DEST: the file plus every shared library ldd names, at the same paths
  cp -L "$1" "$2"
  local libs lib
  libs=$(ldd "$1" 2>/dev/null | grep -o '/[^ ]*' || true)  # none for a static busybox
  for lib in $libs; do
    [ -f "$lib" ] || continue
    mkdir -p "$root$(dirname "$lib")"
    cp -L "$lib" "$root$lib"
  done
}
copy_with_libraries "$busybox" "$root/bin/busybox"
copy_with_libraries "$test_binary" "$root/test/$(basename "$test_binary")"

for m in "${modules[@]}"; do
  found=$(find "$media_dir" \( -name "$m.ko" -o -name "$m.ko.xz" -o -name "$m.ko.zst" \) | head -n 1)
  [ -n "$found" ] || { echo "v4l2-vm-test: $(basename "$deb") has no module $m" >&2; exit 1; }
  case "$found" in  # busybox insmod reads plain .ko only
    *.xz) xz -dc "$found" >"$root/modules/$m.ko" ;;
    *.zst) zstd -qdc "$found" >"$root/modules/$m.ko" ;;
    *) cp "$found" "$root/modules/$m.ko" ;;
  esac
done

{
  printf '%s\n' '#!/bin/busybox sh'
  printf '%s\n' '/bin/busybox --install -s /bin'
  printf '%s\n' 'export PATH=/bin'
  printf '%s\n' 'mount -t devtmpfs dev /dev || mount -t tmpfs dev /dev'
  # An initramfs built without root has no /dev/console node for the kernel to open.
  printf '%s\n' 'exec </dev/console >/dev/console 2>&1'
  printf '%s\n' 'mount -t proc proc /proc; mount -t sysfs sys /sys'
  printf '%s\n' 'report() { [ "$1" = 0 ] && v=PASS || v=FAIL; echo "PHOTORIG-VM-RESULT: $v rc=$1"; sync; poweroff -f; }'
  printf 'for m in %s; do\n' "${modules[*]}"
  printf '  params=; [ "$m" = vivid ] && params="%s"\n' "$vivid_params"
  printf '%s\n' '  insmod /modules/$m.ko $params || { echo "PHOTORIG-VM: insmod $m failed"; report 125; }'
  printf '%s\n' 'done'
  printf '%s\n' 'i=0; while [ ! -e /dev/video0 ] && [ $i -lt 50 ]; do sleep 0.1; i=$((i + 1)); done'
  printf '%s\n' '[ -e /dev/video0 ] || { echo "PHOTORIG-VM: /dev/video0 did not appear"; report 125; }'
  printf '%s\n' 'echo "PHOTORIG-VM: vivid loaded after $(cut -d" " -f1 /proc/uptime) s"'
  printf 'PHOTORIG_V4L2_DEVICE=/dev/video0 PHOTORIG_V4L2_MPLANE_DEVICE=/dev/video1 /test/%s --gtest_color=no' "$(basename "$test_binary")"
  for a in "${gtest_args[@]}"; do printf " '%s'" "${a//\'/\'\\\'\'}"; done
  printf '\n%s\n' 'report $?'
} >"$root/init"
chmod +x "$root/init"

initrd="$work/initramfs.cpio.gz"
(cd "$root" && find . | cpio -o -H newc --quiet | gzip -1 >"$initrd")

# --- boot -------------------------------------------------------------------
log="$work/console.log"
echo "v4l2-vm-test: booting $(basename "$vmlinuz") under qemu (TCG); console in $log"
start_ms=$(($(date +%s%N) / 1000000))
set +e
timeout --kill-after=5 "$vm_timeout_s" qemu-system-x86_64 \
  -accel tcg -cpu max -smp 1 -m 512M \
  -nodefaults -no-user-config -display none -no-reboot \
  -serial stdio -monitor none \
  -kernel "$vmlinuz" -initrd "$initrd" \
  -append "console=ttyS0 rdinit=/init panic=-1 quiet loglevel=3" </dev/null | tr -d '\r' | tee "$log"
qemu_rc=${PIPESTATUS[0]}
set -e
elapsed_ms=$(($(date +%s%N) / 1000000 - start_ms))
elapsed_s=$((elapsed_ms / 1000)).$((elapsed_ms % 1000 / 100))

result=$(grep -ao 'PHOTORIG-VM-RESULT: [A-Z]* rc=[0-9]*' "$log" | tail -n 1 | sed 's/.*rc=//')
if [ -z "$result" ]; then
  if [ "$qemu_rc" = 124 ] || [ "$qemu_rc" = 137 ]; then
    echo "v4l2-vm-test: FAIL: the VM did not report within ${vm_timeout_s} s (console in $log)"
  else
    echo "v4l2-vm-test: FAIL: qemu exited with $qemu_rc before the tests reported (console in $log)"
  fi
  exit 1
fi
if [ "$result" = 0 ]; then
  echo "v4l2-vm-test: PASS in ${elapsed_s} s (boot, module load and tests)"
  exit 0
fi
echo "v4l2-vm-test: FAIL: the tests in the VM exited with $result after ${elapsed_s} s"
exit 1
