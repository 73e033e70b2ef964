#!/usr/bin/env python3
"""Check docs/jointlab.dbc against docs/golden-vectors.toml with cantools.

For every [[vector]]: the DBC message of the same kind (id & 0x780 | 1: the DBC describes
node 1, other nodes share the layout) must have the vector's name and length, decoding the
bytes must give every field's physical value (within half the signal's scale; enums by
name), and encoding the values must give back the exact bytes. For every [[checksum]]:
zlib.crc32 over the packed entries must equal the stated CRC. Exits non-zero with a clear
message on the first disagreement; prints how many vectors it checked.

Usage: .venv/bin/python docs/check_dbc.py [--dbc PATH] [--vectors PATH]
"""
import argparse
import pathlib
import struct
import sys
import tomllib
import zlib

import cantools

HERE = pathlib.Path(__file__).resolve().parent
LIMIT_NAMES = ["torque", "velocity", "position", "integrator", "overflow", "wire_saturated"]


def fail(msg):
    print(f"check_dbc: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def expected_signals(vector):
    """Vector fields → {signal: physical value or enum name}."""
    out = {}
    for key, val in vector["fields"].items():
        if key == "limits":
            unknown = set(val) - set(LIMIT_NAMES)
            if unknown:
                fail(f"vector {vector['name']}: unknown limit flags {sorted(unknown)}")
            for n in LIMIT_NAMES:
                out[f"limit_{n}"] = 1 if n in val else 0
        elif isinstance(val, bool):
            out[key] = 1 if val else 0
        else:
            out[key] = val
    return out


def check_vector(db, v):
    name = v["name"]
    frame_id = int(v["id"], 16)
    data = bytes.fromhex(v["data"])
    node = frame_id & 0x7F
    if node != v["node"]:
        fail(f"vector {name}: id {v['id']} carries node {node}, vector says node {v['node']}")
    try:
        msg = db.get_message_by_frame_id((frame_id & 0x780) | 1)
    except KeyError:
        fail(f"vector {name}: no DBC message for kind {frame_id >> 7} (id {v['id']})")
    if msg.name != v["message"]:
        fail(f"vector {name}: id {v['id']} is {msg.name} in the DBC, vector says {v['message']}")
    if msg.length != len(data):
        fail(f"vector {name}: {len(data)} data bytes, DBC {msg.name} has length {msg.length}")

    want = expected_signals(v)
    sig_names = {s.name for s in msg.signals}
    if set(want) != sig_names:
        fail(
            f"vector {name}: fields {sorted(set(want) - sig_names)} not in DBC {msg.name}, "
            f"signals {sorted(sig_names - set(want))} missing from the vector"
        )

    got = msg.decode(data, decode_choices=True, scaling=True)
    for sig in msg.signals:
        exp, dec = want[sig.name], got[sig.name]
        if isinstance(exp, str):
            if str(dec) != exp:
                fail(f"vector {name}: {msg.name}.{sig.name} decodes to {dec!r}, expected {exp!r}")
        else:
            tol = abs(sig.scale) / 2
            if not isinstance(dec, (int, float)) or abs(float(dec) - float(exp)) > tol:
                fail(
                    f"vector {name}: {msg.name}.{sig.name} decodes to {dec!r}, expected {exp!r} "
                    f"(tolerance {tol}) from bytes {v['data']}"
                )

    enc = msg.encode(want, scaling=True, strict=True)
    if enc != data:
        fail(f"vector {name}: DBC encodes the values to {enc.hex(' ').upper()}, vector has {v['data']}")


def check_checksum(c):
    blob = b"".join(struct.pack("<Hi", pid, val) for pid, val in c["entries"])
    crc = zlib.crc32(blob)
    if crc != c["crc"]:
        fail(f"checksum {c['name']}: zlib.crc32 = 0x{crc:08X}, vector says 0x{c['crc']:08X}")
    if len(c["entries"]) != c["count"]:
        fail(f"checksum {c['name']}: {len(c['entries'])} entries, vector says count {c['count']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dbc", default=HERE / "jointlab.dbc")
    ap.add_argument("--vectors", default=HERE / "golden-vectors.toml")
    args = ap.parse_args()

    db = cantools.database.load_file(str(args.dbc), strict=True)
    with open(args.vectors, "rb") as f:
        golden = tomllib.load(f)

    vectors = golden.get("vector", [])
    if not vectors:
        fail(f"no [[vector]] entries in {args.vectors}")
    for v in vectors:
        check_vector(db, v)

    covered = {v["message"] for v in vectors}
    missing = sorted(m.name for m in db.messages if m.name not in covered)
    if missing:
        fail(f"DBC messages without golden vectors: {missing}")

    for c in golden.get("checksum", []):
        check_checksum(c)

    print(
        f"check_dbc: OK: {len(vectors)} vectors over {len(db.messages)} DBC messages agree "
        f"(decode and encode); {len(golden.get('checksum', []))} checksum vectors match zlib.crc32"
    )


if __name__ == "__main__":
    main()
