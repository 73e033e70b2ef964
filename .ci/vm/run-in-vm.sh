#!/usr/bin/env bash
# Boots a throwaway QEMU guest (Debian kernel + busybox initramfs) with a real vcan0 and
# runs a command in it; exits with the command's exit status.
#
#   .ci/vm/run-in-vm.sh [options] -- COMMAND [ARG...]
#   .ci/vm/run-in-vm.sh [options] -x SCRIPT
#
# Options:
#   -f HOST_PATH[:NAME]  copy a static executable (or any file) to /bin/NAME in the guest;
#                        repeat for several binaries (card, plant, supervisor, tests, ...)
#   -d HOST_DIR          copy every file of HOST_DIR to /bin (e.g. the output of build.sh)
#   -D HOST_BIN          copy a dynamically linked host program to /bin together with the
#                        shared libraries `ldd` lists (e.g. -D /usr/bin/candump)
#   -e NAME=VALUE        export an environment variable to the command
#   -i IFACE             create this vcan interface (repeatable; default: vcan0)
#   -x SCRIPT            run this host shell script (busybox sh) instead of COMMAND
#   -t SECONDS           hard timeout for the whole boot (default 300)
#   -m MB                guest memory (default 512);  -s N  vCPUs (default 1: under TCG a
#                        wake-up across vCPUs costs ~4 ms, on one vCPU a cross-process
#                        CAN round trip is ~0.2-0.6 ms; measured, see the FIGURE lines)
#   -l LOGFILE           also keep the full console log here
# Env: JOINTLAB_VM_ACCEL (default tcg), JOINTLAB_VM_APPEND (extra kernel command line).
#
# The guest: loads the CAN modules (can-dev, vcan, can, can-raw and their dependencies,
# resolved with modinfo from the newest /lib/modules kernel that has vcan.ko), creates the
# vcan interfaces with the static `vcan-up` helper (netlink; it must be among the copied
# files), runs the command from /tmp with PATH=/bin, then prints `GUEST_RC=<status>` and
# powers off. qemu itself always exits 0, so the status comes only from that line: a
# missing line (guest crash, timeout, kernel panic) is a failure (exit 125).
#
# Accel: TCG (`-accel tcg`). KVM hangs in early boot on the nested CI machines
# (toolchain.md §3); override with JOINTLAB_VM_ACCEL=kvm where it works.
set -euo pipefail

FILES=() ; DYN=() ; ENVS=() ; IFACES=() ; SCRIPT= ; TMO=300 ; MEM=512 ; SMP=1 ; LOG=
while getopts "f:d:D:e:i:x:t:m:s:l:h" o; do
  case $o in
    f) FILES+=("$OPTARG") ;;
    d) for p in "$OPTARG"/*; do [ -f "$p" ] && FILES+=("$p"); done ;;
    D) DYN+=("$OPTARG") ;;
    e) ENVS+=("$OPTARG") ;;
    i) IFACES+=("$OPTARG") ;;
    x) SCRIPT=$OPTARG ;;
    t) TMO=$OPTARG ;;
    m) MEM=$OPTARG ;;
    s) SMP=$OPTARG ;;
    l) LOG=$OPTARG ;;
    h) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    *) exit 2 ;;
  esac
done
shift $((OPTIND - 1))
[ "${1:-}" = "--" ] && shift
if [ -z "$SCRIPT" ] && [ $# -eq 0 ]; then
  echo "run-in-vm: give -x SCRIPT or -- COMMAND (see -h)" >&2; exit 2
fi
[ ${#IFACES[@]} -gt 0 ] || IFACES=(vcan0)

# ---- kernel and modules -------------------------------------------------------------------
KVER=
for d in $(ls -1 /lib/modules 2>/dev/null | sort -V -r); do
  if [ -e "/boot/vmlinuz-$d" ] && find "/lib/modules/$d/kernel/drivers/net/can" -name 'vcan.ko*' 2>/dev/null | grep -q .; then
    KVER=$d; break
  fi
done
if [ -z "$KVER" ]; then
  echo "run-in-vm: no /boot/vmlinuz-* with a vcan module; run .ci/vm/install.sh" >&2; exit 2
fi
command -v qemu-system-x86_64 >/dev/null || { echo "run-in-vm: qemu-system-x86_64 missing; run .ci/vm/install.sh" >&2; exit 2; }
[ -x /bin/busybox ] || { echo "run-in-vm: /bin/busybox missing; run .ci/vm/install.sh" >&2; exit 2; }

W=$(mktemp -d "${TMPDIR:-/tmp}/jointlab-vm.XXXXXX")
trap 'rm -rf "$W"' EXIT
R=$W/root
mkdir -p "$R"/{bin,lib/modules,proc,sys,dev,tmp}
cp /bin/busybox "$R/bin/busybox"

# Module closure in load order (dependencies first).
declare -A SEEN=()
ORDER=()
modpath() { modinfo -k "$KVER" -n "$1"; }
addmod() {
  local m=$1 dep
  [ -n "${SEEN[$m]:-}" ] && return 0
  SEEN[$m]=1
  for dep in $(modinfo -k "$KVER" -F depends "$m" | tr ',' ' '); do addmod "$dep"; done
  ORDER+=("$m")
}
for m in can-dev vcan can can-raw; do addmod "$m"; done
for m in "${ORDER[@]}"; do
  p=$(modpath "$m")
  case $p in
    *.ko) cp "$p" "$R/lib/modules/$m.ko" ;;
    *.ko.xz) xz -dc "$p" >"$R/lib/modules/$m.ko" ;;
    *.ko.zst) zstd -qdc "$p" >"$R/lib/modules/$m.ko" ;;
    *.ko.gz) gzip -dc "$p" >"$R/lib/modules/$m.ko" ;;
    *) echo "run-in-vm: unexpected module file $p" >&2; exit 2 ;;
  esac
done

# ---- payload ------------------------------------------------------------------------------
for spec in "${FILES[@]}"; do
  src=${spec%%:*}; name=${spec#*:}
  [ "$name" = "$spec" ] && name=$(basename "$src")
  [ -f "$src" ] || { echo "run-in-vm: no such file: $src" >&2; exit 2; }
  cp "$src" "$R/bin/$name"; chmod +x "$R/bin/$name"
done
for b in "${DYN[@]}"; do
  [ -f "$b" ] || { echo "run-in-vm: no such program: $b" >&2; exit 2; }
  cp "$b" "$R/bin/"
  for lib in $(ldd "$b" | grep -o '/[^ ]*'); do
    mkdir -p "$R$(dirname "$lib")"
    cp -L "$lib" "$R$lib"
  done
done
[ -x "$R/bin/vcan-up" ] || { echo "run-in-vm: the vcan-up helper must be among the copied files (.ci/vm/build.sh stages it)" >&2; exit 2; }
if [ -n "$SCRIPT" ]; then cp "$SCRIPT" "$R/cmd.sh"; else printf '%s\n' "$*" >"$R/cmd.sh"; fi
{
  for e in "${ENVS[@]}"; do printf 'export %q\n' "$e"; done
} >"$R/env.sh"

cat >"$R/init" <<EOI
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin HOME=/tmp TMPDIR=/tmp
mount -t proc proc /proc; mount -t sysfs sys /sys; mount -t devtmpfs dev /dev; mount -t tmpfs tmp /tmp
for m in ${ORDER[*]}; do insmod /lib/modules/\$m.ko || echo "GUEST: insmod \$m failed"; done
ip link set lo up
vcan-up ${IFACES[*]} || echo "GUEST: vcan-up failed"
. /env.sh
cd /tmp
sh /cmd.sh </dev/null
echo "GUEST_RC=\$?"
sync
poweroff -f
EOI
chmod +x "$R/init"
(cd "$R" && find . | cpio -o -H newc 2>/dev/null | gzip -1) >"$W/initrd.gz"

# ---- boot ---------------------------------------------------------------------------------
ACCEL=${JOINTLAB_VM_ACCEL:-tcg}
echo "run-in-vm: kernel $KVER, accel $ACCEL, ${SMP} vCPU, ${MEM} MB, initramfs $(du -h "$W/initrd.gz" | cut -f1), modules: ${ORDER[*]}"
CONSOLE=$W/console.log
set +e
timeout "$TMO" qemu-system-x86_64 -accel "$ACCEL" -m "$MEM" -smp "$SMP" -nographic -no-reboot \
  -kernel "/boot/vmlinuz-$KVER" -initrd "$W/initrd.gz" \
  -append "console=ttyS0 quiet loglevel=3 panic=-1 rdinit=/init ${JOINTLAB_VM_APPEND:-}" </dev/null 2>&1 \
  | tr -d '\r' | tee "$CONSOLE" \
  | sed -E 's/\x1b(\[[0-9;?=]*[a-zA-Z]|c)//g' \
  | grep -avE '^\s*$|SeaBIOS|iPXE|Press Ctrl-B|Booting from|Probing EDD'
QRC=${PIPESTATUS[0]}
set -e
[ -n "$LOG" ] && cp "$CONSOLE" "$LOG"
RC=$(grep -a '^GUEST_RC=' "$CONSOLE" | tail -1 | cut -d= -f2 | tr -dc '0-9' || true)
if [ -z "$RC" ]; then
  if [ "$QRC" = 124 ]; then
    echo "run-in-vm: FAILED: guest timed out after ${TMO}s (no GUEST_RC line)" >&2
  else
    echo "run-in-vm: FAILED: no GUEST_RC line (qemu exit $QRC; guest crashed or panicked?)" >&2
  fi
  exit 125
fi
echo "run-in-vm: GUEST_RC=$RC"
exit "$RC"
