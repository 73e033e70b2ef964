#!/usr/bin/env bash
# Installs what the vcan-in-a-VM stage needs, only if something is missing.
#   qemu-system-x86  -> qemu-system-x86_64 (TCG; KVM hangs on the CI machines, see toolchain.md §3)
#   linux-image-amd64 -> /boot/vmlinuz-<kver> and /lib/modules/<kver> with can-dev/vcan/can/can-raw
#   busybox-static   -> /bin/busybox for the guest's initramfs
#   cpio             -> packs the initramfs
#   can-utils        -> candump/canplayer, run in the guest to check the candump -L format
#   lib*-dev         -> static archives for linking hil-host (plotters: fontconfig/freetype and
#                       their png/zlib/bzip2/brotli/expat dependencies) as a static binary
# --no-install-recommends matters: without it apt pulls ~165 GUI/audio packages and has replaced
# a preinstalled qemu-utils backport before (toolchain.md §0).
set -euo pipefail

have_kernel() {
  local k
  for k in /boot/vmlinuz-*; do
    [ -e "$k" ] || continue
    local v=${k#/boot/vmlinuz-}
    [ -e "/lib/modules/$v/kernel/drivers/net/can/vcan.ko" ] && return 0
  done
  return 1
}

have_static() {
  local l
  for l in "$@"; do
    [ -e "/usr/lib/x86_64-linux-gnu/lib$l.a" ] || return 1
  done
}

if command -v qemu-system-x86_64 >/dev/null && [ -x /bin/busybox ] && command -v cpio >/dev/null \
  && [ -x /usr/bin/candump ] && [ -x /usr/bin/canplayer ] && have_kernel \
  && have_static fontconfig freetype png16 z bz2 brotlidec brotlicommon expat; then
  echo "vm/install: qemu-system-x86_64, busybox, cpio, can-utils and a kernel with vcan are present"
  exit 0
fi

SUDO=
if [ "$(id -u)" != 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive
# Another job may hold the dpkg lock (shared machines): wait for it instead of failing.
$SUDO apt-get -o DPkg::Lock::Timeout=600 update
$SUDO apt-get -o DPkg::Lock::Timeout=600 install -y --no-install-recommends \
  qemu-system-x86 linux-image-amd64 busybox-static cpio can-utils \
  libfontconfig-dev libfreetype-dev libpng-dev zlib1g-dev libbz2-dev libbrotli-dev libexpat1-dev
have_kernel || { echo "vm/install: no /boot/vmlinuz-* with a matching vcan.ko after install" >&2; exit 1; }
