#!/usr/bin/env bash
# The vcan-in-a-VM CI stage: one entry point.
#
#   .ci/vm/run-vcan-tests.sh
#
# 1. installs qemu-system-x86, linux-image-amd64, busybox-static, cpio, can-utils if missing
#    (install.sh)
# 2. builds static guest binaries: jointlab-tests' bins and its tests/tests/vcan_*.rs (build.sh)
# 3. boots a QEMU/TCG guest with a real vcan0 and runs every vcan_* test binary in it with
#    JOINTLAB_REQUIRE_VCAN=1 (a missing/broken vcan0 fails instead of skipping) and
#    JOINTLAB_BIN_DIR=/bin (tests find helper processes such as vcan-echo there), with
#    can-utils' candump and canplayer (+ their libc) copied in and JOINTLAB_REQUIRE_CANUTILS=1
# 4. exits with the guest's status (missing GUEST_RC line = failure)
#
# Extra arguments are passed to every test binary (e.g. a name filter, --nocapture).
set -euo pipefail
cd "$(dirname "$0")/../.."
T0=$SECONDS
step() { printf '\n--- vm stage: %s (%ss)\n' "$1" "$((SECONDS - T0))"; }

step "install (only if missing)"
.ci/vm/install.sh

step "build static guest binaries"
OUT=${JOINTLAB_VM_OUT:-target/vm-guest}
.ci/vm/build.sh "$OUT" -p hil-host --bin hil-host

step "boot the guest and run the vcan tests"
GUEST_SCRIPT=$(mktemp)
trap 'rm -f "$GUEST_SCRIPT"' EXIT
{
  echo 'fail=0'
  while read -r t; do
    [ -n "$t" ] || continue
    printf 'echo "=== guest: %s ==="\n' "$t"
    printf '%s --test-threads=2 %s || { echo "=== guest: %s FAILED ==="; fail=1; }\n' "$t" "$*" "$t"
  done <"$OUT/tests.list"
  echo 'exit $fail'
} >"$GUEST_SCRIPT"

set +e
.ci/vm/run-in-vm.sh -d "$OUT/bin" -D /usr/bin/candump -D /usr/bin/canplayer \
  -e JOINTLAB_REQUIRE_VCAN=1 -e JOINTLAB_REQUIRE_CANUTILS=1 -e JOINTLAB_BIN_DIR=/bin \
  -e RUST_BACKTRACE=1 -t "${JOINTLAB_VM_TIMEOUT:-600}" -x "$GUEST_SCRIPT"
RC=$?
set -e
step "done: guest status $RC"
exit "$RC"
