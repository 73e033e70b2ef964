#!/usr/bin/env python3
"""Fetch the EMPS benchmark data and convert it into the CSVs jointlab's dataset files read.

EMPS (Electro-Mechanical Positioning System) is a measured prismatic drive from
nonlinearbenchmark.org. Its data carry no licence to redistribute, so they are not in this
repository: this script downloads the benchmark's EMPS.zip (or takes a zip or a directory
you already have), checks the two .mat files against the sha256 recorded when the data were
first copied, and writes

    DATA_EMPS.csv         t_s,qm_m,qg_m,vir_V
    DATA_EMPS_PULSES.csv  t_s,qm_m,qg_m,vir_V,pulses_V

with the .mat files (and the authors' PDF, when the source has it) into
../shared/data/real/emps/, beside the repository (--dest elsewhere). Every value is
written as the float64 repr of the .mat's number, so it reads back bit for bit and two runs
give the same bytes. A file that exists and differs is never overwritten without --force.

Cite the data as: A. Janot, M. Gautier, M. Brunot, "Data Set and Reference Models of EMPS",
2019 Workshop on Nonlinear System Identification Benchmarks, Eindhoven, The Netherlands,
April 10-12, 2019.

Needs numpy and scipy.
"""

from __future__ import annotations

import argparse
import hashlib
import http.client
import io
import os
import sys
import tempfile
import urllib.error
import urllib.request
import zipfile
from pathlib import Path

import numpy as np
from scipy.io import loadmat

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DEST = ROOT.parent / "shared" / "data" / "real" / "emps"

BENCHMARK_PAGE = "https://www.nonlinearbenchmark.org/benchmarks/emps"
# The benchmark site's official loader (the nonlinear_benchmarks package, EMPS()) fetches
# EMPS.zip from this Google Drive id; the old site's path comes second in case it is ever
# served again.
URLS = (
    "https://drive.google.com/uc?export=download&id=1zwoXYa9-3f8NQ0ohzmjpF7UxbNgRTHkS",
    "http://www.nonlinearbenchmark.org/FILES/BENCHMARKS/EMPS/EMPS.zip",
)
TIMEOUT_S = 60
MAX_ZIP_BYTES = 64 << 20  # EMPS.zip is about 1.9 MB; anything far larger is not it

# From ../shared/data/real/emps/README.md, the files as first copied. Kept here because a
# fresh download has no README to read them from.
SHA256 = {
    "DATA_EMPS.mat": "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e",
    "DATA_EMPS_PULSES.mat": "0eab75bb1f6b16228ee78791343a88bf9bfd9a51036ac9807d7b5fc11c0e1704",
}
# CSV column <- .mat variable. pulses_N is a 0/5 square wave added before the drive gain,
# so it is in volts (see the data's README); it is stored as uint8 and written as float.
COLUMNS = {
    "DATA_EMPS": [("t_s", "t"), ("qm_m", "qm"), ("qg_m", "qg"), ("vir_V", "vir")],
    "DATA_EMPS_PULSES": [
        ("t_s", "t"),
        ("qm_m", "qm"),
        ("qg_m", "qg"),
        ("vir_V", "vir"),
        ("pulses_V", "pulses_N"),
    ],
}
PDF = "EMPS_Description.pdf"


class FetchError(Exception):
    """A failure reported as one line, exit status 1."""


def download(urls) -> bytes:
    """The first URL that answers with a zip; every failure is named in the error."""
    failures = []
    for url in urls:
        req = urllib.request.Request(url, headers={"User-Agent": "jointlab-fetch-emps"})
        try:
            with urllib.request.urlopen(req, timeout=TIMEOUT_S) as resp:
                body = resp.read(MAX_ZIP_BYTES + 1)
        except urllib.error.HTTPError as e:
            failures.append(f"{url}: HTTP {e.code} {e.reason}")
            continue
        except urllib.error.URLError as e:
            failures.append(f"{url}: {e.reason}")
            continue
        except (OSError, http.client.HTTPException) as e:  # a timeout or a cut connection
            failures.append(f"{url}: {type(e).__name__}: {e}")
            continue
        if len(body) > MAX_ZIP_BYTES:
            failures.append(f"{url}: more than {MAX_ZIP_BYTES} bytes, not EMPS.zip")
        elif not zipfile.is_zipfile(io.BytesIO(body)):
            # Drive answers a moved or quota-limited file with an HTML page, status 200.
            failures.append(f"{url}: the answer is not a zip ({len(body)} bytes)")
        else:
            print(f"downloaded {url} ({len(body)} bytes)")
            return body
    raise FetchError(
        "could not download EMPS.zip ("
        + "; ".join(failures)
        + f"); download it by hand from {BENCHMARK_PAGE} and pass --zip FILE"
    )


def from_zip(data: bytes, origin: str) -> dict[str, bytes]:
    """The two .mat files (and the description PDF if present) from the zip, found by name
    wherever they sit in it; macOS resource forks (__MACOSX/, ._*) are not them."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile as e:
        raise FetchError(f"{origin}: not a zip file ({e})") from None
    wanted = [*SHA256, PDF]
    found: dict[str, list[str]] = {name: [] for name in wanted}
    for member in zf.namelist():
        parts = member.split("/")
        if parts[-1] in found and "__MACOSX" not in parts:
            found[parts[-1]].append(member)
    out = {}
    for name in wanted:
        members = found[name]
        if len(members) > 1:
            raise FetchError(f"{origin}: {name} appears more than once ({', '.join(members)})")
        if members:
            out[name] = zf.read(members[0])
        elif name != PDF:
            raise FetchError(f"{origin}: no {name} in the zip")
    return out


def from_dir(src: Path) -> dict[str, bytes]:
    out = {}
    for name in [*SHA256, PDF]:
        path = src / name
        if path.is_file():
            out[name] = path.read_bytes()
        elif name != PDF:
            need = " and ".join(SHA256)
            raise FetchError(f"{path} not found (--from needs a directory holding {need})")
    return out


def verify(files: dict[str, bytes]) -> None:
    for name, expected in SHA256.items():
        actual = hashlib.sha256(files[name]).hexdigest()
        if actual != expected:
            raise FetchError(
                f"{name}: sha256 mismatch: expected {expected}, got {actual}"
                " (a different or damaged file; --no-verify converts it anyway)"
            )


def to_csv(name: str, mat: bytes) -> bytes:
    """One CSV from one .mat: floats written with repr, which round-trips every float64."""
    try:
        m = loadmat(io.BytesIO(mat))
    except Exception as e:  # scipy raises several types for a damaged file
        raise FetchError(f"{name}.mat: cannot be read as a MATLAB file ({e})") from None
    cols = []
    for col, var in COLUMNS[name]:
        if var not in m:
            raise FetchError(f"{name}.mat: no variable {var!r} (for column {col})")
        a = np.asarray(m[var])
        if a.ndim != 2 or 1 not in a.shape or a.dtype.kind not in "fiu":
            raise FetchError(f"{name}.mat: {var} is {a.dtype} {a.shape}, not a numeric column")
        # uint8 and float64 convert to Python floats exactly; tolist() yields plain floats,
        # whose repr is the shortest string that reads back to the same double.
        cols.append(a.astype(np.float64).ravel().tolist())
    n = {len(c) for c in cols}
    if len(n) != 1:
        raise FetchError(f"{name}.mat: columns of different lengths {sorted(n)}")
    lines = [",".join(col for col, _ in COLUMNS[name])]
    lines += [",".join(map(repr, row)) for row in zip(*cols)]
    return ("\n".join(lines) + "\n").encode("ascii")


def write_all(dest: Path, outputs: dict[str, bytes], force: bool) -> None:
    """Refuse before writing anything if a file exists and differs (unless force), so a
    refused run changes nothing; write each file through a temporary and a rename."""
    plan = []
    for name, data in outputs.items():
        path = dest / name
        if path.is_file():
            if path.read_bytes() == data:
                print(f"unchanged {path}")
                continue
            if not force:
                raise FetchError(
                    f"{path} exists and differs from the conversion; --force replaces it"
                )
        plan.append((path, data))
    dest.mkdir(parents=True, exist_ok=True)
    for path, data in plan:
        fd, tmp = tempfile.mkstemp(dir=dest, prefix=f".{path.name}.")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        print(f"wrote {path} ({len(data)} bytes)")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description="Download EMPS.zip from nonlinearbenchmark.org, check the .mat files' "
        "sha256 and convert them into DATA_EMPS.csv and DATA_EMPS_PULSES.csv.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--zip", type=Path, metavar="FILE", help="use an EMPS.zip already downloaded")
    src.add_argument("--from", dest="src", type=Path, metavar="DIR",
                     help="use a directory that holds the two .mat files")
    src.add_argument("--url", action="append", metavar="URL",
                     help="download from URL instead (repeatable, tried in order)")
    p.add_argument("--dest", type=Path, default=DEFAULT_DEST, metavar="DIR",
                   help="where to write (default: %(default)s)")
    p.add_argument("--no-verify", action="store_true",
                   help="skip the sha256 check of the .mat files")
    p.add_argument("--force", action="store_true", help="replace existing files that differ")
    args = p.parse_args(argv)

    try:
        if args.src is not None:
            files = from_dir(args.src)
        elif args.zip is not None:
            files = from_zip(args.zip.read_bytes(), str(args.zip))
        else:
            files = from_zip(download(args.url or URLS), "EMPS.zip")
        if args.no_verify:
            print("warning: --no-verify: the .mat files' sha256 is not checked", file=sys.stderr)
        else:
            verify(files)
        outputs = dict(files)
        for name in COLUMNS:
            outputs[f"{name}.csv"] = to_csv(name, files[f"{name}.mat"])
        write_all(args.dest.resolve(), outputs, args.force)
    except (FetchError, OSError) as e:
        print(f"fetch-emps: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
