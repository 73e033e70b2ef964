#!/usr/bin/env bash
# Builds the guest programs as static x86_64 binaries and stages them for run-in-vm.sh.
#
#   .ci/vm/build.sh [OUT_DIR [EXTRA CARGO BUILD ARGS...]]    (default OUT_DIR: target/vm-guest)
#   e.g. .ci/vm/build.sh target/vm-guest -p hil-host --bin hil-host   (also stage the CLI)
#
# Output: OUT_DIR/bin/<name>   stripped static executables:
#           every [[bin]] of jointlab-tests (vcan-up, vcan-echo, ...),
#           every integration test tests/tests/vcan_*.rs (as vcan_<name>, no hash), and
#           every binary the EXTRA args build
#         OUT_DIR/tests.list   the test executables' names, one a line
#
# It uses its own target dir (JOINTLAB_VM_TARGET_DIR, default target/vm-static) because
# RUSTFLAGS=+crt-static would otherwise invalidate the normal build cache. `--target` is
# given explicitly so build scripts and proc macros stay dynamic (only the target is static).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-target/vm-guest}
shift || true
TRIPLE=x86_64-unknown-linux-gnu
export CARGO_TARGET_DIR=${JOINTLAB_VM_TARGET_DIR:-target/vm-static}
# plotters' font support links fontconfig/freetype statically; their own dependencies must
# follow them on the link line (static archives do not carry their dependencies). Debian's
# static archives are not position-independent, so the executable is a classic static one
# (relocation-model=static), and `-Bstatic` keeps the linker from resolving these -l flags
# against shared libraries (which would crash a static binary at start-up).
export RUSTFLAGS="-C target-feature=+crt-static -C relocation-model=static -C link-arg=-Wl,-Bstatic -C link-arg=-lpng16 -C link-arg=-lz -C link-arg=-lbz2 -C link-arg=-lbrotlidec -C link-arg=-lbrotlicommon -C link-arg=-lexpat"
export CARGO_TERM_COLOR=${CARGO_TERM_COLOR:-never}

rustup target list --installed 2>/dev/null | grep -qx "$TRIPLE" || rustup target add "$TRIPLE"

# Debuginfo is stripped for the guest anyway; not generating it saves build time.
export CARGO_PROFILE_RELEASE_DEBUG=${CARGO_PROFILE_RELEASE_DEBUG:-0}

# One command: building the integration tests also builds the package's [[bin]]s
# (they are what CARGO_BIN_EXE_<name> points at), so vcan-up and vcan-echo come along.
mkdir -p "$CARGO_TARGET_DIR"
JSON=$CARGO_TARGET_DIR/vm-tests.json
cargo test --profile vm --target "$TRIPLE" -p jointlab-tests --test 'vcan_*' --no-run \
  --message-format=json-render-diagnostics >"$JSON"

if [ $# -gt 0 ]; then
  cargo build --profile vm --target "$TRIPLE" "$@" --message-format=json-render-diagnostics >>"$JSON"
fi

rm -rf "$OUT"
mkdir -p "$OUT/bin"
# Stage what cargo reported: test executables of vcan_* targets, and every bin executable.
python3 - "$JSON" "$OUT" <<'PY'
import json, shutil, sys
src, out = sys.argv[1], sys.argv[2]
tests, bins = set(), set()
for line in open(src):
    try:
        m = json.loads(line)
    except ValueError:
        continue
    if m.get("reason") != "compiler-artifact" or not m.get("executable"):
        continue
    t = m["target"]
    if m["profile"]["test"]:
        if t["name"].startswith("vcan_"):
            shutil.copy(m["executable"], f"{out}/bin/{t['name']}")
            tests.add(t["name"])
    elif "bin" in t["kind"]:
        shutil.copy(m["executable"], f"{out}/bin/{t['name']}")
        bins.add(t["name"])
if not tests:
    sys.exit("vm/build: cargo reported no vcan_* test executables")
if "vcan-up" not in bins:
    sys.exit("vm/build: the vcan-up helper was not built")
open(f"{out}/tests.list", "w").write("".join(n + "\n" for n in sorted(tests)))
PY
for f in "$OUT"/bin/*; do
  strip --strip-debug "$f"
  # A dynamic executable names its loader in PT_INTERP; the guest has no libc to load.
  if readelf -l "$f" | grep -q 'program interpreter'; then
    echo "vm/build: $f is not statically linked (it has a PT_INTERP)" >&2
    exit 1
  fi
done
echo "vm/build: staged in $OUT/bin: $(cd "$OUT/bin" && echo *)"
