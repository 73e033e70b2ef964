"""scripts/fetch-emps.py against the EMPS copy in ../shared: converting its .mat files gives
the shipped CSVs byte for byte, a damaged .mat is refused by name, and a CSV that differs is
replaced only with --force. The download itself needs the network and is not run here."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EMPS = ROOT.parent / "shared" / "data" / "real" / "emps"
SCRIPT = ROOT / "scripts" / "fetch-emps.py"
MATS = ["DATA_EMPS.mat", "DATA_EMPS_PULSES.mat"]
CSVS = ["DATA_EMPS.csv", "DATA_EMPS_PULSES.csv"]


@pytest.fixture(scope="module")
def emps():
    """The EMPS directory; skipped when ../shared is absent, unless the CI requires it."""
    missing = [EMPS / f for f in MATS + CSVS if not (EMPS / f).exists()]
    if not missing:
        return EMPS
    msg = f"{missing[0]} not found"
    if os.environ.get("JOINTLAB_REQUIRE_REAL_DATA"):
        pytest.fail(f"{msg} and JOINTLAB_REQUIRE_REAL_DATA is set: the real-data tests must run")
    pytest.skip(f"SKIPPING REAL-DATA TEST: {msg} (CI must have ../shared)")


def fetch(*args):
    return subprocess.run(
        [sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True
    )


def test_converts_to_the_shipped_csvs_byte_for_byte(emps, tmp_path):
    out = fetch("--from", emps, "--dest", tmp_path)
    assert out.returncode == 0, out.stderr
    for name in CSVS:
        assert (tmp_path / name).read_bytes() == (emps / name).read_bytes(), name
        assert f"wrote {tmp_path / name}" in out.stdout


def test_a_damaged_mat_is_refused_by_name(emps, tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for name in MATS:
        shutil.copyfile(emps / name, src / name)
    damaged = src / "DATA_EMPS_PULSES.mat"
    data = bytearray(damaged.read_bytes())
    data[len(data) // 2] ^= 0x01
    damaged.write_bytes(bytes(data))

    out = fetch("--from", src, "--dest", tmp_path / "out")
    assert out.returncode == 1
    assert "DATA_EMPS_PULSES.mat" in out.stderr and "sha256 mismatch" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not (tmp_path / "out").exists()  # refused before writing anything


def test_a_differing_csv_is_replaced_only_with_force(emps, tmp_path):
    assert fetch("--from", emps, "--dest", tmp_path).returncode == 0
    edited = tmp_path / "DATA_EMPS.csv"
    edited.write_text(edited.read_text().replace("t_s,", "time,", 1))

    out = fetch("--from", emps, "--dest", tmp_path)
    assert out.returncode == 1
    assert str(edited) in out.stderr and "--force" in out.stderr

    out = fetch("--from", emps, "--dest", tmp_path, "--force")
    assert out.returncode == 0, out.stderr
    assert edited.read_bytes() == (emps / "DATA_EMPS.csv").read_bytes()
