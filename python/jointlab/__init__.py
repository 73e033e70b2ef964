"""jointlab's model-vs-measurement workbench from Python.

``diagnose``, ``fit``, ``auto`` and ``compare`` are the ``hil-host`` commands of the same
names: they call the same Rust library and return what ``--json`` prints, as frozen
dataclasses (``to_json()`` gives the CLI's object back). A recording is given as

* arrays: ``diagnose(t, u, q)`` (numpy arrays or sequences; names default to ``time``,
  ``input``, ``output`` and may carry a unit suffix such as ``_deg`` as a CSV column does),
* a pandas DataFrame and column names: ``diagnose(df, time="t_s", input="vir_V",
  output="qm_m")``,
* a CSV path and column names, read by the CLI's own loader.

Models load and save as the model TOML the CLI's ``--model`` and ``--save-model`` use
(``Model.load``, ``Model.save``, ``Model.from_toml``, ``Model.to_toml``).

Errors carry the workbench's message, naming what is wrong and where (the file or
``<arrays>``, the line or 0-based index, the column). They are all ``ValueError``:

* :class:`DataError` — the recording (a missing column, a value not finite or out of range
  after its unit and gains, time not increasing, too few rows, a signal out of range after
  differentiation),
* :class:`ModelError` — a model file or text (does not parse, cannot be fitted, or a fitted
  model no file can hold),
* :class:`FitError` — a fit that cannot be made (too few samples, nothing free, overflow),

all three subclasses of :class:`JointlabError`: what the CLI exits 1 for. An argument the
call cannot use (``alpha=2``, a ``cutoff`` above the record's Nyquist frequency, an unknown
effect name) raises a plain ``ValueError``, the CLI's usage error (exit 2).
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from typing import Any, Optional, Sequence

import numpy as np

from . import _jointlab
from ._jointlab import DataError, FitError, JointlabError, Model, ModelError, Recording

__all__ = [
    "JointlabError",
    "DataError",
    "ModelError",
    "FitError",
    "Model",
    "Recording",
    "recording",
    "diagnose",
    "fit",
    "auto",
    "compare",
    "Diagnosis",
    "FitResult",
    "AutoResult",
    "CompareResult",
    "Units",
]


def _build(cls, d: dict):
    """``cls`` from the JSON object ``d``, whose keys must be exactly its fields: a field the
    Rust side adds or drops fails here (and in the test suite) instead of vanishing."""
    names = [f.name for f in dataclasses.fields(cls) if f.name != "json"]
    if set(d) - set(names) or set(names) - set(d) - _OPTIONAL.get(cls, set()):
        raise RuntimeError(
            f"jointlab: {cls.__name__} fields {sorted(names)} do not match the workbench's "
            f"JSON keys {sorted(d)}"
        )
    return cls(**{n: d.get(n) for n in names})


@dataclass(frozen=True)
class Resampled:
    """How an irregular clock was put on a uniform one (intervals in s)."""

    min_step_s: float
    max_step_s: float
    median_step_s: float
    dt_s: float


@dataclass(frozen=True)
class Baseline:
    """The current model's numbers on the record (equation error)."""

    fit_percent: float
    rms: float
    noise_floor_rms: float
    input_noise_rms: float
    encoder_noise_rms: float
    ljung_box_p: float
    model: str


@dataclass(frozen=True)
class Candidate:
    """One candidate effect, ranked (1 = most likely missing)."""

    effect: str
    rank: int
    statistic: float
    p_value: float
    p_raw: float
    err: float
    df: int
    grid: int
    significant: bool


@dataclass(frozen=True)
class Verdict:
    """The effect to add (``None``: nothing), what it is hard to tell apart from."""

    add: Optional[str]
    ambiguous_with: list
    text: str
    experiment: Optional[str] = None


@dataclass(frozen=True)
class Diagnosis:
    """What ``diagnose --json`` prints."""

    residual_mode: str
    intersample: str
    cutoff_hz: float  # the differentiator's band (Hz): ``cutoff``, or the record's default
    baseline: Baseline
    candidates: list
    verdict: Verdict
    untestable: list
    notes: list
    resampled: Optional[Resampled]
    schema_version: Optional[int] = None
    units: Optional[Units] = None
    json: dict = dataclasses.field(repr=False, compare=False, default_factory=dict)

    @classmethod
    def _of(cls, raw: dict) -> "Diagnosis":
        d = dict(raw)
        d.setdefault("resampled", None)  # absent in --auto's "final"
        out = _build(cls, d)
        return dataclasses.replace(
            out,
            baseline=_build(Baseline, d["baseline"]),
            candidates=[_build(Candidate, c) for c in d["candidates"]],
            verdict=_build(Verdict, d["verdict"]),
            resampled=_resampled(d["resampled"]),
            units=_units(d.get("units")),
            json=raw,
        )

    def to_json(self) -> dict:
        """The JSON object, as ``diagnose --json`` prints it."""
        return self.json


@dataclass(frozen=True)
class Score:
    """Fit %, RMS, relative error and noise floor of a model on one record."""

    fit_percent: float
    rms: float
    relative_error_percent: float
    noise_floor_rms: float

    def floor_ratio(self) -> float:
        """RMS over the noise floor (1 = nothing left but noise)."""
        return self.rms / self.noise_floor_rms


@dataclass(frozen=True)
class Param:
    """One fitted parameter ± 1σ, in ``unit`` (as the model's axis names it: N·s/m on a
    linear axis, N·m·s/rad on a joint)."""

    owner: str
    name: str
    value: float
    sigma: float
    unit: str


@dataclass(frozen=True)
class Units:
    """The units of a record's signals, and of every number reported about it (``residual``
    is the residual's, RMS's and noise floor's)."""

    time: str
    input: str
    position: str
    velocity: str
    acceleration: str
    residual: str


@dataclass(frozen=True)
class FitReport:
    """Before and after adding an effect, on estimation (and validation) data."""

    added: Optional[str]
    before: Score
    after: Score
    before_validation: Optional[Score]
    after_validation: Optional[Score]
    params: list


@dataclass(frozen=True)
class AsGiven:
    """A given model's own values, scored before ``fit`` refits them."""

    estimation: Score
    validation: Optional[Score]


def _score(d):
    return None if d is None else _build(Score, d)


def _resampled(d):
    return None if d is None else _build(Resampled, d)


def _units(d):
    return None if d is None else _build(Units, d)


@dataclass(frozen=True)
class FitResult:
    """What ``fit --json`` prints (its ``model_file`` is ``model``, to ``save``)."""

    report: FitReport
    as_given: Optional[AsGiven]
    resampled: Optional[Resampled]
    model: Model
    schema_version: int
    units: Units
    notes: list = dataclasses.field(default_factory=list)
    json: dict = dataclasses.field(repr=False, compare=False, default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object of ``fit --json`` without ``model_file``."""
        return self.json


@dataclass(frozen=True)
class AutoStep:
    """One step of ``--auto``."""

    step: int
    added: Optional[str]
    score: Score
    validation: Optional[Score]
    p_value: Optional[float]
    verdict: str
    replaced: Optional[str] = None
    chosen_over: Optional[str] = None


@dataclass(frozen=True)
class AutoResult:
    """What ``diagnose --auto --json`` prints; ``model`` is the final model."""

    residual_mode: str
    steps: list
    stop: str
    final: Diagnosis
    model: Model
    resampled: Optional[Resampled]
    schema_version: int
    units: Units
    notes: list = dataclasses.field(default_factory=list)
    json: dict = dataclasses.field(repr=False, compare=False, default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object, as ``diagnose --auto --json`` prints it."""
        return self.json


@dataclass(frozen=True)
class CompareResult:
    """What ``compare --json`` prints, and the residual's series to plot."""

    metrics: dict
    params: list
    resampled: Optional[Resampled]
    schema_version: int
    units: Units
    time: np.ndarray = dataclasses.field(repr=False)
    measured: np.ndarray = dataclasses.field(repr=False)
    predicted: np.ndarray = dataclasses.field(repr=False)
    residual: np.ndarray = dataclasses.field(repr=False)
    json: dict = dataclasses.field(repr=False, compare=False, default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object of ``compare --json`` (``report`` is null: no report directory)."""
        return self.json


# Fields a JSON object may leave out (serde skips them when empty).
_OPTIONAL = {
    Verdict: {"experiment"},
    Diagnosis: {"schema_version", "units"},  # absent in --auto's "final"
    AutoStep: {"replaced", "chosen_over"},
}


def _array(name: str, x: Any) -> list:
    """``x`` as a list of floats, or a ``ValueError`` naming the argument."""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: not an array of numbers ({e})") from None
    if a.ndim != 1:
        raise ValueError(f"{name}: a 1-D array is needed, got shape {a.shape}")
    return a.tolist()


def _is_frame(x: Any) -> bool:
    return hasattr(x, "columns") and hasattr(x, "__getitem__") and hasattr(x, "to_numpy")


def _column(df: Any, name: str) -> list:
    """The DataFrame's column ``name`` as floats; a :class:`DataError` if it has none, as the
    CSV loader's for a missing column."""
    if name not in df.columns:
        raise DataError(
            f"DataFrame: no column `{name}` (have: {', '.join(map(str, df.columns))})"
        )
    return _array(f"DataFrame column `{name}`", df[name].to_numpy())


def recording(
    data: Any,
    u: Any = None,
    q: Any = None,
    *,
    time: Optional[str] = None,
    input: Optional[str] = None,
    output: Optional[str] = None,
    load_output: Any = None,
    input_times: Any = None,
    input_gain: float = 1.0,
    load_gain: float = 1.0,
    window: Optional[tuple] = None,
    intersample: str = "zoh",
    gear_ratio: float = 1.0,
) -> Recording:
    """A :class:`Recording` from arrays ``(t, u, q)``, a DataFrame, a CSV path, or a dataset
    file (``.toml``, the CLI's: it names the CSV and its columns, so nothing else is passed).

    With a DataFrame or a path, ``time`` (default ``time_s``), ``input`` and ``output`` name
    columns, and so do ``load_output`` and ``input_times``; for a CSV path, a column not named
    is found from the header's unit suffixes as the CLI finds it. With arrays they are optional
    labels (a unit suffix converts, as in a CSV), and ``load_output``/``input_times`` are
    arrays. ``window=(from, to)`` keeps the rows in that time span (either end ``None``).
    """
    opts = dict(
        input_gain=input_gain,
        load_gain=load_gain,
        window=window,
        intersample=intersample,
        gear_ratio=gear_ratio,
    )
    if isinstance(data, (str, os.PathLike)) and os.fspath(data).lower().endswith(".toml"):
        given = [k for k, v in dict(time=time, input=input, output=output,
                                    load_output=load_output, input_times=input_times,
                                    window=window).items() if v is not None]
        given += [k for k, v, d in (("input_gain", input_gain, 1.0), ("load_gain", load_gain, 1.0),
                                    ("intersample", intersample, "zoh"),
                                    ("gear_ratio", gear_ratio, 1.0)) if v != d]
        if u is not None or q is not None or given:
            raise ValueError(
                f"{os.fspath(data)}: a dataset file says how to read its CSV; "
                f"set {', '.join(given) or 'u, q'} in the file instead"
            )
        return Recording.from_dataset(os.fspath(data))
    if isinstance(data, (str, os.PathLike)) or _is_frame(data):
        if u is not None or q is not None:
            raise ValueError(
                "with a DataFrame or a CSV path, name the columns (input=..., output=...) "
                "instead of passing arrays"
            )
        if _is_frame(data) and (input is None or output is None):
            raise ValueError("input= and output= must name the input and output columns")
        for arg, v in (("load_output", load_output), ("input_times", input_times)):
            if v is not None and not isinstance(v, str):
                raise ValueError(f"{arg}: with a DataFrame or a CSV path, a column name")
        if not _is_frame(data):
            return Recording.from_csv(
                os.fspath(data),
                time=time,
                input=input,
                output=output,
                load_output=load_output,
                input_times=input_times,
                **opts,
            )
        names = dict(
            time=time or "time_s",
            input=input,
            output=output,
            load_output=load_output,
            input_times=input_times,
        )
        return Recording.from_arrays(
            _column(data, names["time"]),
            _column(data, input),
            _column(data, output),
            load=None if load_output is None else _column(data, load_output),
            times=None if input_times is None else _column(data, input_times),
            **names,
            **opts,
        )
    if u is None or q is None:
        raise ValueError("arrays: pass t, u and q (time, input, output)")
    return Recording.from_arrays(
        _array("t", data),
        _array("u", u),
        _array("q", q),
        time=time or "time",
        input=input or "input",
        output=output or "output",
        load=None if load_output is None else _array("load_output", load_output),
        load_output=None if load_output is None else "load_output",
        times=None if input_times is None else _array("input_times", input_times),
        input_times=None if input_times is None else "input_times",
        **opts,
    )


_RECORDING_ARGS = (
    "time",
    "input",
    "output",
    "load_output",
    "input_times",
    "input_gain",
    "load_gain",
    "window",
    "intersample",
    "gear_ratio",
)


def _split(kw: dict) -> tuple:
    """The recording's keyword arguments apart from the command's."""
    rec = {k: kw.pop(k) for k in _RECORDING_ARGS if k in kw}
    return rec, kw


def _rec(data, u, q, rec_kw) -> Recording:
    return data if isinstance(data, Recording) else recording(data, u, q, **rec_kw)


def _validation(validate, rec_kw) -> Optional[Recording]:
    """A validation record: a Recording, a DataFrame or a path with the same columns (no
    window: validation data is used whole, as the CLI's ``--validate``)."""
    if validate is None or isinstance(validate, Recording):
        return validate
    kw = dict(rec_kw, window=None)
    if isinstance(validate, (tuple, list)) and len(validate) == 3:
        return recording(*validate, **kw)
    return recording(validate, **kw)


def diagnose(
    data: Any,
    u: Any = None,
    q: Any = None,
    *,
    model: Optional[Model] = None,
    cutoff: Optional[float] = None,
    alpha: float = 0.05,
    min_err: float = 0.01,
    min_rho: float = 0.25,
    **recording_args: Any,
) -> Diagnosis:
    """Which effect is the model (default: the fitted baseline) missing? ``diagnose --json``.

    ``data, u, q`` and ``recording_args`` are those of :func:`recording` (or ``data`` is a
    :class:`Recording`).
    """
    rec_kw, rest = _split(recording_args)
    _no_extra(rest)
    rec = _rec(data, u, q, rec_kw)
    out = _jointlab.diagnose(
        rec, model, cutoff=cutoff, alpha=alpha, min_err=min_err, min_rho=min_rho
    )
    return Diagnosis._of(json.loads(out))


def fit(
    data: Any,
    u: Any = None,
    q: Any = None,
    *,
    model: Optional[Model] = None,
    add: Optional[str] = None,
    validate: Any = None,
    cutoff: Optional[float] = None,
    **recording_args: Any,
) -> FitResult:
    """Add ``add`` (if given) to ``model`` (default: the baseline) and refit. ``fit --json``.

    ``validate`` is a second record with the same columns (a Recording, a DataFrame, a path,
    or a ``(t, u, q)`` tuple).
    """
    rec_kw, rest = _split(recording_args)
    _no_extra(rest)
    rec = _rec(data, u, q, rec_kw)
    out, fitted = _jointlab.fit(
        rec, model, add=add, validate=_validation(validate, rec_kw), cutoff=cutoff
    )
    d = json.loads(out)
    r = d["report"]
    report = dataclasses.replace(
        _build(FitReport, r),
        before=_score(r["before"]),
        after=_score(r["after"]),
        before_validation=_score(r["before_validation"]),
        after_validation=_score(r["after_validation"]),
        params=[_build(Param, p) for p in r["params"]],
    )
    g = d["as_given"]
    as_given = None
    if g is not None:
        as_given = AsGiven(estimation=_score(g["estimation"]), validation=_score(g["validation"]))
    return FitResult(
        report=report,
        as_given=as_given,
        resampled=_resampled(d["resampled"]),
        model=fitted,
        schema_version=d["schema_version"],
        units=_units(d["units"]),
        notes=list(d["notes"]),
        json=d,
    )


def auto(
    data: Any,
    u: Any = None,
    q: Any = None,
    *,
    model: Optional[Model] = None,
    validate: Any = None,
    cutoff: Optional[float] = None,
    alpha: float = 0.05,
    min_err: float = 0.01,
    min_rho: float = 0.25,
    max_steps: int = 6,
    **recording_args: Any,
) -> AutoResult:
    """Rank → add → refit until nothing significant is left. ``diagnose --auto --json``."""
    rec_kw, rest = _split(recording_args)
    _no_extra(rest)
    rec = _rec(data, u, q, rec_kw)
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 0:
        raise ValueError(f"max_steps={max_steps!r}: a whole number ≥ 0")
    out, final = _jointlab.auto(
        rec,
        model,
        validate=_validation(validate, rec_kw),
        cutoff=cutoff,
        alpha=alpha,
        min_err=min_err,
        min_rho=min_rho,
        max_steps=max_steps,
    )
    d = json.loads(out)
    steps = []
    for s in d["steps"]:
        st = _build(AutoStep, s)
        steps.append(
            dataclasses.replace(st, score=_score(s["score"]), validation=_score(s["validation"]))
        )
    return AutoResult(
        residual_mode=d["residual_mode"],
        steps=steps,
        stop=d["stop"],
        final=Diagnosis._of(d["final"]),
        model=final,
        resampled=_resampled(d["resampled"]),
        schema_version=d["schema_version"],
        units=_units(d["units"]),
        notes=list(d["notes"]),
        json=d,
    )


def compare(
    data: Any,
    u: Any = None,
    q: Any = None,
    *,
    model: Optional[Model] = None,
    residual: str = "equation",
    period: Optional[float] = None,
    refit: bool = False,
    cutoff: Optional[float] = None,
    **recording_args: Any,
) -> CompareResult:
    """Where does the model's error live? ``compare --json``, plus the residual series.

    A given ``model`` is compared as it is (``refit=True`` refits its free parameters first);
    without one the baseline is fitted.
    """
    rec_kw, rest = _split(recording_args)
    _no_extra(rest)
    rec = _rec(data, u, q, rec_kw)
    d = json.loads(
        _jointlab.compare(
            rec, model, residual=residual, period=period, refit=refit, cutoff=cutoff
        )
    )
    series = d.pop("series")
    return CompareResult(
        metrics=d["metrics"],
        params=[_build(Param, p) for p in d["params"]],
        resampled=_resampled(d["resampled"]),
        schema_version=d["schema_version"],
        units=_units(d["units"]),
        time=np.asarray(series["time"]),
        measured=np.asarray(series["measured"]),
        predicted=np.asarray(series["predicted"]),
        residual=np.asarray(series["residual"]),
        json=d,
    )


def _no_extra(rest: dict) -> None:
    if rest:
        raise TypeError(f"unexpected keyword argument(s): {', '.join(sorted(rest))}")
