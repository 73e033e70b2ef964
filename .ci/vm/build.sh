#!/usr/bin/env bash
# Builds the guest programs as static x86_64 binaries and stages them for run-in-vm.sh.
#
#   .ci/vm/build.sh [OUT_DIR]          (default OUT_DIR: target/vm-guest)
#
# Output: OUT_DIR/bin/<name>   stripped static executables:
#           every [[bin]] of jointlab-tests (vcan-up, vcan-echo, ...) and
#           every integration test tests/tests/vcan_*.rs (as vcan_<name>, no hash)
#         OUT_DIR/tests.list   the test executables' names, one a line
#
# It uses its own target dir (JOINTLAB_VM_TARGET_DIR, default target/vm-static) because
# RUSTFLAGS=+crt-static would otherwise invalidate the normal build cache. `--target` is
# given explicitly so build scripts and proc macros stay dynamic (only the target is static).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-target/vm-guest}
TRIPLE=x86_64-unknown-linux-gnu
export CARGO_TARGET_DIR=${JOINTLAB_VM_TARGET_DIR:-target/vm-static}
export RUSTFLAGS="-C target-feature=+crt-static"
export CARGO_TERM_COLOR=${CARGO_TERM_COLOR:-never}

rustup target list --installed 2>/dev/null | grep -qx "$TRIPLE" || rustup target add "$TRIPLE"

cargo build --release --target "$TRIPLE" -p jointlab-tests --bins
JSON=$CARGO_TARGET_DIR/vm-tests.json
cargo test --release --target "$TRIPLE" -p jointlab-tests --test 'vcan_*' --no-run \
  --message-format=json-render-diagnostics >"$JSON"

rm -rf "$OUT"
mkdir -p "$OUT/bin"
# Bins: target/<triple>/release/<name> for every bin target of jointlab-tests.
for src in tests/src/bin/*.rs; do
  name=$(basename "$src" .rs)
  cp "$CARGO_TARGET_DIR/$TRIPLE/release/$name" "$OUT/bin/$name"
done
# Tests: the executables cargo reported for test targets named vcan_*.
python3 - "$JSON" "$OUT" <<'PY'
import json, shutil, sys
src, out = sys.argv[1], sys.argv[2]
names = []
for line in open(src):
    try:
        m = json.loads(line)
    except ValueError:
        continue
    if m.get("reason") != "compiler-artifact" or not m.get("executable"):
        continue
    t = m["target"]
    if "test" in t["kind"] and t["name"].startswith("vcan_"):
        shutil.copy(m["executable"], f"{out}/bin/{t['name']}")
        names.append(t["name"])
if not names:
    sys.exit("vm/build: cargo reported no vcan_* test executables")
open(f"{out}/tests.list", "w").write("".join(n + "\n" for n in sorted(set(names))))
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
