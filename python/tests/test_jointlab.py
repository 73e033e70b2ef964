"""The Python package against the CLI: the EMPS walk-through (README, docs/workbench.md) run
from Python gives the numbers `hil-host ... --json` prints, run here on the same files; a
DataFrame, arrays and a CSV path give one answer; models round-trip through TOML; bad input
raises a ValueError of its kind (DataError, ModelError, FitError, or a plain one for a bad
argument) naming what and where."""

import contextlib
import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import jointlab

ROOT = Path(__file__).resolve().parents[2]
EMPS = ROOT.parent / "shared" / "data" / "real" / "emps"
GTAU = "35.15065188248547"
COLS = dict(time="t_s", input="vir_V", output="qm_m", input_gain=float(GTAU))
CLI_COLS = ["--time", "t_s", "--input", "vir_V", "--input-gain", GTAU, "--output", "qm_m"]


@pytest.fixture(scope="session")
def emps():
    """The EMPS directory; skipped when ../shared is absent, unless the CI requires it."""
    if (EMPS / "DATA_EMPS.csv").exists():
        return EMPS
    msg = f"{EMPS / 'DATA_EMPS.csv'} not found"
    if os.environ.get("JOINTLAB_REQUIRE_REAL_DATA"):
        pytest.fail(f"{msg} and JOINTLAB_REQUIRE_REAL_DATA is set: the real-data tests must run")
    pytest.skip(f"SKIPPING REAL-DATA TEST: {msg} (CI must have ../shared)")


@pytest.fixture(scope="session")
def hil_host():
    """The `hil-host` binary cargo builds (JOINTLAB_HIL_HOST overrides)."""
    if os.environ.get("JOINTLAB_HIL_HOST"):
        return os.environ["JOINTLAB_HIL_HOST"]
    subprocess.run(["cargo", "build", "-q", "-p", "hil-host"], cwd=ROOT, check=True)
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    )
    return str(Path(json.loads(meta.stdout)["target_directory"]) / "debug" / "hil-host")


@pytest.fixture(scope="session")
def frames(emps):
    """Both EMPS records as DataFrames, read by pandas (not by the workbench's loader)."""
    pd = pytest.importorskip("pandas")
    return pd.read_csv(emps / "DATA_EMPS.csv"), pd.read_csv(emps / "DATA_EMPS_PULSES.csv")


def cli(hil_host, *args):
    out = subprocess.run(
        [hil_host, *map(str, args), "--json"], check=True, capture_output=True, text=True
    )
    return json.loads(out.stdout)


def assert_same(py, ref, path="$"):
    """Equal structure and strings; numbers to 1e-9 relative (the two runs share code, not
    the order of every parallel sum)."""
    if isinstance(ref, dict):
        assert isinstance(py, dict) and sorted(py) == sorted(ref), f"{path}: keys {py} vs {ref}"
        for k in ref:
            assert_same(py[k], ref[k], f"{path}.{k}")
    elif isinstance(ref, list):
        assert isinstance(py, list) and len(py) == len(ref), f"{path}: {py} vs {ref}"
        for k, (a, b) in enumerate(zip(py, ref)):
            assert_same(a, b, f"{path}[{k}]")
    elif isinstance(ref, float) or isinstance(py, float):
        assert isinstance(py, (int, float)) and not isinstance(py, bool), f"{path}: {py!r}"
        assert math.isclose(py, ref, rel_tol=1e-9, abs_tol=1e-300), f"{path}: {py} vs {ref}"
    else:
        assert py == ref, f"{path}: {py!r} vs {ref!r}"


def test_emps_diagnose_from_a_dataframe_and_a_path_is_the_clis(emps, hil_host, frames):
    ref = cli(hil_host, "diagnose", emps / "DATA_EMPS.csv", *CLI_COLS)
    from_frame = jointlab.diagnose(frames[0], **COLS)
    from_path = jointlab.diagnose(emps / "DATA_EMPS.csv", **COLS)
    assert_same(from_frame.to_json(), ref)
    assert_same(from_path.to_json(), ref)
    # The dataclasses carry the same values as the JSON.
    assert from_frame.verdict.add == ref["verdict"]["add"] == "coulomb"
    assert from_frame.baseline.fit_percent == ref["baseline"]["fit_percent"]
    assert [c.effect for c in from_frame.candidates] == [c["effect"] for c in ref["candidates"]]
    assert from_frame.candidates[0].rank == 1 and from_frame.resampled is None


def test_emps_fit_chain_and_compare_are_the_clis(emps, hil_host, frames, tmp_path):
    est, val = frames
    m1_cli = tmp_path / "emps1.toml"
    ref1 = cli(
        hil_host, "fit", emps / "DATA_EMPS.csv", *CLI_COLS, "--add", "coulomb",
        "--save-model", m1_cli,
    )
    f1 = jointlab.fit(est, add="coulomb", **COLS)
    ref1.pop("model_file")
    assert_same(f1.to_json(), ref1)
    assert f1.report.added == "coulomb" and f1.as_given is None
    assert f1.report.after.fit_percent > f1.report.before.fit_percent

    # The CLI's saved model, loaded in Python, carries the parameters Python fitted.
    m1 = jointlab.Model.load(m1_cli)
    assert_same(json.loads(m1.params_json()), json.loads(f1.model.params_json()))

    m2_cli = tmp_path / "emps2.toml"
    ref2 = cli(
        hil_host, "fit", emps / "DATA_EMPS.csv", *CLI_COLS, "--model", m1_cli, "--add",
        "offset", "--validate", emps / "DATA_EMPS_PULSES.csv", "--save-model", m2_cli,
    )
    f2 = jointlab.fit(est, model=m1, add="offset", validate=val, **COLS)
    ref2.pop("model_file")
    assert_same(f2.to_json(), ref2)
    assert f2.as_given is not None and f2.report.after_validation is not None
    assert [p.owner for p in f2.report.params][:1] == ["inertia"]

    m2_py = tmp_path / "emps2-py.toml"
    f2.model.save(m2_py)
    ref_c = cli(
        hil_host, "compare", emps / "DATA_EMPS_PULSES.csv", *CLI_COLS, "--model", m2_py,
        "--out", tmp_path / "report",
    )
    c = jointlab.compare(val, model=jointlab.Model.load(m2_py), **COLS)
    out = c.to_json()
    assert out.pop("report") is None and ref_c.pop("report")
    # The CLI writes its series to a file; the library returns them (`series`).
    assert out.pop("residual_csv") is None and ref_c.pop("residual_csv")
    assert_same(out, ref_c)
    assert len(c.residual) == len(c.time) == len(c.measured) == len(c.predicted) > 20_000
    rms = float(np.sqrt(np.mean(c.residual**2)))
    assert math.isclose(rms, c.metrics["rms"], rel_tol=1e-9)


def test_emps_auto_with_validation_is_the_clis(emps, hil_host, frames, tmp_path):
    ref = cli(
        hil_host, "diagnose", emps / "DATA_EMPS.csv", *CLI_COLS, "--auto", "--validate",
        emps / "DATA_EMPS_PULSES.csv", "--save-model", tmp_path / "auto.toml",
    )
    # The CLI keeps its model in a file; the library returns it.
    assert ref.pop("model_file") == str(tmp_path / "auto.toml")
    run = jointlab.auto(frames[0], validate=frames[1], **COLS)
    assert_same(run.to_json(), ref)
    added = [s.added for s in run.steps if s.added]
    assert added[:2] == ["coulomb", "offset"], added
    assert run.stop == ref["stop"]
    assert run.final.verdict.text == ref["final"]["verdict"]["text"]


def synthetic(n=3000, dt=1e-3):
    """A mass (2 kg) with viscous (5 N·s/m) and Coulomb (1.5 N) friction on a 1 µm encoder."""
    t = np.arange(n) * dt
    w1, w2 = 2 * np.pi * 1.3, 2 * np.pi * 3.1
    x = 0.1 * np.sin(w1 * t) + 0.03 * np.sin(w2 * t)
    v = 0.1 * w1 * np.cos(w1 * t) + 0.03 * w2 * np.cos(w2 * t)
    a = -0.1 * w1**2 * np.sin(w1 * t) - 0.03 * w2**2 * np.sin(w2 * t)
    rng = np.random.default_rng(7)
    u = 2.0 * a + 5.0 * v + 1.5 * np.sign(v) + 0.02 * rng.standard_normal(n)
    return t, u, np.round(x * 1e6) / 1e6


def test_a_dataset_file_and_a_suffixed_header_are_the_clis(emps, hil_host, tmp_path):
    ds = tmp_path / "emps.toml"
    ds.write_text(
        f'file = "{(emps / "DATA_EMPS.csv").as_posix()}"\ntime = "t_s"\ninput = "vir_V"\n'
        f'input_gain = {GTAU}\noutput = "qm_m"\n'
    )
    ref = cli(hil_host, "diagnose", emps / "DATA_EMPS.csv", *CLI_COLS)
    assert_same(jointlab.diagnose(ds).to_json(), ref)
    assert_same(cli(hil_host, "diagnose", ds), ref)
    with pytest.raises(ValueError, match="in the file instead"):
        jointlab.recording(ds, input_gain=2.0)
    bad = tmp_path / "bad.toml"
    bad.write_text('file = "x.csv"\ninptu = "u"\n')
    with pytest.raises(jointlab.DataError, match="inptu"):
        jointlab.recording(bad)


def test_arrays_a_dataframe_and_a_csv_give_one_diagnosis(tmp_path):
    pd = pytest.importorskip("pandas")
    t, u, q = synthetic()
    d = jointlab.diagnose(t, u, q)
    assert d.verdict.add == "coulomb", d.verdict.text
    df = pd.DataFrame({"time_s": t, "force_N": u, "pos_m": q})
    from_df = jointlab.diagnose(df, input="force_N", output="pos_m")
    path = tmp_path / "rec.csv"
    df.to_csv(path, index=False, float_format="%.17g")
    from_csv = jointlab.diagnose(path, input="force_N", output="pos_m")
    # Unnamed arrays have no units; named columns do, and that is all that differs.
    assert (d.units.input, d.units.position, d.units.velocity) == ("", "", "1/s")
    assert (from_df.units.input, from_df.units.velocity) == ("N", "m/s")
    unitless = {**d.to_json(), "units": from_df.to_json()["units"]}
    assert_same(from_df.to_json(), unitless)
    assert_same(from_csv.to_json(), unitless)
    # The header's suffixes name the columns when no argument does.
    assert_same(jointlab.diagnose(path).to_json(), unitless)
    # A unit suffix converts arrays as it does a CSV column: millimetres in, metres inside.
    in_mm = jointlab.recording(t, u, q * 1e3, output="pos_mm")
    assert np.allclose(in_mm.output, q, rtol=1e-12, atol=0)


def test_a_fitted_model_round_trips_through_toml_and_diagnoses_from_there(tmp_path):
    t, u, q = synthetic()
    f = jointlab.fit(t, u, q, add="coulomb")
    params = {(p.owner, p.name): p.value for p in f.report.params}
    assert abs(params[("inertia", "inertia")] - 2.0) < 0.05, params
    text = f.model.to_toml()
    again = jointlab.Model.from_toml(text)
    assert again.to_toml() == text
    path = tmp_path / "m.toml"
    f.model.save(path)
    assert path.read_text() == text
    loaded = jointlab.Model.load(path)
    assert loaded.params_json() == f.model.params_json()
    assert "coulomb" in repr(loaded)
    # Diagnosed with the loaded model: it starts from it and no longer offers Coulomb.
    d = jointlab.diagnose(t, u, q, model=loaded)
    assert d.baseline.model == loaded.name == f.model.name
    assert "coulomb" not in [c.effect for c in d.candidates]
    assert d.baseline.fit_percent > jointlab.diagnose(t, u, q).baseline.fit_percent


@contextlib.contextmanager
def usage_error(match):
    """A plain ``ValueError`` (a bad argument, the CLI's exit 2), not a ``JointlabError``."""
    with pytest.raises(ValueError, match=match) as info:
        yield
    assert not isinstance(info.value, jointlab.JointlabError), repr(info.value)


def test_bad_input_raises_the_error_of_its_kind_naming_it():
    t, u, q = synthetic(500)
    bad = u.copy()
    bad[17] = np.nan
    # What the data holds: DataError (a ValueError), naming the array and the index.
    assert issubclass(jointlab.DataError, jointlab.JointlabError)
    assert issubclass(jointlab.JointlabError, ValueError)
    with pytest.raises(jointlab.DataError, match=r"<arrays>:17: column `input`: value is NaN"):
        jointlab.diagnose(t, bad, q)
    with pytest.raises(jointlab.DataError, match=r"`output` holds 499 values, `time` 500"):
        jointlab.diagnose(t, u, q[:-1])
    with pytest.raises(jointlab.DataError, match=r"time 0\.01 does not increase"):
        jointlab.diagnose(np.where(np.arange(500) == 11, 0.01, t), u, q)
    with pytest.raises(jointlab.DataError, match=r"only 10 data rows; need at least 50"):
        jointlab.diagnose(t[:10], u[:10], q[:10])
    # Finite cells out of range once scaled, or once differentiated: named, not a NaN fit.
    with pytest.raises(jointlab.DataError, match=r"<arrays>:\d+: column `input`: .*out of range"):
        jointlab.diagnose(t, u * 1e200, q)
    jump = q.copy()
    # Below the load check's 1e154 and above what the record's band differentiates in range
    # (the band follows the position's noise, which this jump sets to its lowest).
    jump[250] = 1e153
    with pytest.raises(jointlab.DataError, match=r"(velocity|acceleration) after differentiation|position after"):
        jointlab.diagnose(t, u, jump)
    with pytest.raises(jointlab.DataError, match=r"column `output_km`: unknown unit suffix `_km`"):
        jointlab.diagnose(t, u, q, output="output_km")
    # An argument the call cannot use: a plain ValueError, as the CLI's usage error.
    with usage_error(r"u: a 1-D array is needed"):
        jointlab.diagnose(t, np.stack([u, u]), q)
    with usage_error(r"unknown effect `cowlomb` .did you mean `coulomb`.*; known: "):
        jointlab.fit(t, u, q, add="cowlomb")
    with usage_error(r"alpha=2"):
        jointlab.diagnose(t, u, q, alpha=2.0)
    with usage_error(r"input_gain=NaN: must be a finite number"):
        jointlab.diagnose(t, u, q, input_gain=float("nan"))
    with usage_error(r"input_gain=0: must be a finite number other than 0"):
        jointlab.diagnose(t, u, q, input_gain=0.0)
    with usage_error(r"--cutoff 600: .*Nyquist"):
        jointlab.diagnose(t, u, q, cutoff=600.0)
    # A validation record sampled too slowly for the estimation record's default band (a
    # linear axis at 1 kHz: 100 Hz), and the cut-off that reads both.
    tl, ul, ql = synthetic(3000)
    slow = (tl[::20], ul[::20], ql[::20])
    with usage_error(r"Nyquist frequency \(25\.0000 Hz\) is below .* pass a cut-off below 25\.0000 Hz"):
        jointlab.fit(tl, ul, ql, validate=slow)
    assert jointlab.fit(tl, ul, ql, validate=slow, cutoff=10.0).report.after_validation is not None
    with usage_error(r"intersample=\"hold\""):
        jointlab.diagnose(t, u, q, intersample="hold")
    # A model file or text: ModelError, naming it and the line.
    with pytest.raises(jointlab.ModelError, match=r"<toml>:\d+:\d+"):
        jointlab.Model.from_toml("[plant]\ninertia = \n")
    with pytest.raises(jointlab.ModelError, match=r"no such file|cannot read|No such file"):
        jointlab.Model.load("/nonexistent/model.toml")
    # A fit that cannot be made: FitError.
    fitted = jointlab.fit(t, u, q).model.to_toml()
    fixed = jointlab.Model.from_toml(fitted.replace("free = true", "free = false"))
    with pytest.raises(jointlab.FitError, match=r"no free parameter"):
        jointlab.fit(t, u, q, model=fixed)


def test_a_dataframe_missing_a_column_or_holding_text_is_refused():
    pd = pytest.importorskip("pandas")
    t, u, q = synthetic(100)
    df = pd.DataFrame({"time_s": t, "force_N": u, "pos_m": q})
    with pytest.raises(jointlab.DataError, match=r"no column `torque_Nm` \(have: time_s, force_N, pos_m\)"):
        jointlab.diagnose(df, input="torque_Nm", output="pos_m")
    df["pos_m"] = df["pos_m"].astype(object)
    df.loc[5, "pos_m"] = "n/a"
    with pytest.raises(ValueError, match=r"DataFrame column `pos_m`: not an array of numbers"):
        jointlab.diagnose(df, input="force_N", output="pos_m")
