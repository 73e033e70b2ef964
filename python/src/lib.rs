//! `jointlab._jointlab`: the workbench library as a Python extension module.
//!
//! Each function calls the library functions the `hil-host` CLI calls for the same command,
//! and returns the JSON object the CLI's `--json` prints (as text; the pure-Python package
//! `jointlab` turns it into dataclasses). Nothing here computes a figure of its own, so the
//! numbers are the CLI's.
//!
//! Errors carry the workbench's message, which names what is wrong and where (file or
//! `<arrays>`, line or index, column). What the data, a model file or a fit holds raises a
//! subclass of [`JointlabError`] (itself a `ValueError`) by the workbench's error type, the
//! cases the CLI exits 1 for; an argument the call cannot use raises a plain `ValueError`,
//! the CLI's usage error (exit 2).

use std::path::PathBuf;

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::json;
use sim_plant::effects::Intersample;

use jointlab_workbench::data::{self, Arrays, Columns};
use jointlab_workbench::dataset::Dataset;
use jointlab_workbench::diagnose::{self, Options};
use jointlab_workbench::fit;
use jointlab_workbench::metrics;
use jointlab_workbench::model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::{self, Mode, PrepareError, Prepared};
use jointlab_workbench::schema;

create_exception!(
    jointlab,
    JointlabError,
    PyValueError,
    "What a recording, a model file or a fit holds is wrong (the CLI's exit 1)."
);
create_exception!(
    jointlab,
    DataError,
    JointlabError,
    "A recording or its arrays: a missing column, a value that is not finite or out of \
     range, a time that does not increase, a record too short, a signal out of range after \
     differentiation."
);
create_exception!(
    jointlab,
    ModelError,
    JointlabError,
    "A model file or text that does not parse, a model the workbench cannot fit, or a fitted \
     model that no model file can hold."
);
create_exception!(
    jointlab,
    FitError,
    JointlabError,
    "A fit that cannot be made: too few samples, nothing free, a result that overflowed."
);

/// A bad argument as a plain Python `ValueError` (the CLI's usage error).
fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A recording's error as [`DataError`].
fn data_error(e: data::DataError) -> PyErr {
    DataError::new_err(e.to_string())
}

/// A model file's error as [`ModelError`].
fn model_error(e: model::ModelError) -> PyErr {
    ModelError::new_err(e.to_string())
}

/// A fit's error as [`FitError`], after `context` when there is one.
fn fit_error(context: &str, e: fit::FitError) -> PyErr {
    if context.is_empty() {
        FitError::new_err(e.to_string())
    } else {
        FitError::new_err(format!("{context}: {e}"))
    }
}

/// `value` of argument `name` unless it is finite (and above 0 when `positive`).
fn check(name: &str, value: f64, positive: bool) -> PyResult<f64> {
    if value.is_finite() && (!positive || value > 0.0) {
        Ok(value)
    } else if positive {
        Err(value_error(format!(
            "{name}={value}: must be a finite number above 0"
        )))
    } else {
        Err(value_error(format!(
            "{name}={value}: must be a finite number"
        )))
    }
}

/// A gain (`input_gain`, `load_gain`) unless it is not finite or 0: a NaN or infinite gain
/// would reach the fit as NaN, and a zero one erases the column (as the CLI's flags).
fn gain(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() && value != 0.0 {
        Ok(value)
    } else {
        Err(value_error(format!(
            "{name}={value}: must be a finite number other than 0"
        )))
    }
}

/// The diagnosis options, each checked as the CLI's flags are.
fn options(alpha: f64, min_err: f64, min_rho: f64) -> PyResult<Options> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(value_error(format!(
            "alpha={alpha}: not a probability strictly between 0 and 1"
        )));
    }
    Ok(Options {
        alpha,
        min_err: check("min_err", min_err, false)?,
        min_rho: check("min_rho", min_rho, false)?,
        ..Options::default()
    })
}

/// A model file (`Model.load`, `Model.from_toml`): the workbench's model, read and written as
/// the sim-plant TOML the CLI's `--model` and `--save-model` use.
#[pyclass(frozen, module = "jointlab._jointlab")]
#[derive(Debug, Clone)]
struct Model {
    inner: model::Model,
}

#[pymethods]
impl Model {
    /// The default baseline: a rigid inertia with viscous friction, both free.
    #[staticmethod]
    fn baseline() -> Self {
        Model {
            inner: model::Model::baseline(),
        }
    }

    /// Read a model TOML file.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        model::Model::load(&path)
            .map(|inner| Model { inner })
            .map_err(model_error)
    }

    /// Parse model TOML text; `name` labels it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, name = "<toml>"))]
    fn from_toml(text: &str, name: &str) -> PyResult<Self> {
        model::Model::from_toml_str(text, name)
            .map(|inner| Model { inner })
            .map_err(model_error)
    }

    /// The TOML text `save` writes (refused, with why, if a parameter is not physical).
    fn to_toml(&self) -> PyResult<String> {
        self.inner.to_toml_string("<toml>").map_err(model_error)
    }

    /// Write the model TOML file.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner.save(&path).map_err(model_error)
    }

    /// The model's name (what it holds).
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The parameter table (owner, name, value, 1σ) as JSON text.
    fn params_json(&self) -> String {
        json!(refine::param_rows(&self.inner)).to_string()
    }

    fn __repr__(&self) -> String {
        format!("Model({:?})", self.inner.name)
    }
}

/// A recording in SI units, loaded from a CSV file or built from arrays: the workbench's
/// `Recording`, with its checks, window and resampling.
#[pyclass(frozen, module = "jointlab._jointlab")]
#[derive(Debug)]
struct Recording {
    inner: data::Recording,
}

/// The columns' names and the recording options, checked as the CLI checks its flags.
#[allow(clippy::too_many_arguments)]
fn columns(
    time: String,
    input: String,
    output: String,
    load_output: Option<String>,
    input_times: Option<String>,
    input_gain: f64,
    load_gain: f64,
    window: Option<(Option<f64>, Option<f64>)>,
    intersample: &str,
    gear_ratio: f64,
) -> PyResult<Columns> {
    let window = match window {
        Some((from, to)) if from.is_some() || to.is_some() => {
            let end = |name: &str, x: Option<f64>, open: f64| {
                x.map(|x| check(name, x, false))
                    .transpose()
                    .map(|x| x.unwrap_or(open))
            };
            Some((
                end("window start", from, f64::NEG_INFINITY)?,
                end("window stop", to, f64::INFINITY)?,
            ))
        }
        _ => None,
    };
    Ok(Columns {
        time,
        input,
        output,
        load_output,
        input_times,
        input_gain: gain("input_gain", input_gain)?,
        load_gain: gain("load_gain", load_gain)?,
        window,
        intersample: intersample
            .parse::<Intersample>()
            .map_err(|e| value_error(format!("intersample={intersample:?}: {e}")))?,
        gear_ratio: check("gear_ratio", gear_ratio, true)?,
        input_unit: None,
    })
}

#[pymethods]
impl Recording {
    /// Load a CSV file (the CLI's loader: units from the column-name suffixes; a column not
    /// named is found from the header, as the CLI finds it).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (path, *, time = None, input = None, output = None, load_output = None,
        input_times = None, input_gain = 1.0, load_gain = 1.0, window = None, intersample = "zoh",
        gear_ratio = 1.0))]
    fn from_csv(
        path: PathBuf,
        time: Option<String>,
        input: Option<String>,
        output: Option<String>,
        load_output: Option<String>,
        input_times: Option<String>,
        input_gain: f64,
        load_gain: f64,
        window: Option<(Option<f64>, Option<f64>)>,
        intersample: &str,
        gear_ratio: f64,
    ) -> PyResult<Self> {
        let header = if time.is_none() || input.is_none() || output.is_none() {
            data::header(&path).map_err(data_error)?
        } else {
            Vec::new()
        };
        let pick = |named: Option<String>, role: data::Role| match named {
            Some(n) => Ok(n),
            None => data::detect(&path, &header, role).map_err(data_error),
        };
        let cols = columns(
            pick(time, data::Role::Time)?,
            pick(input, data::Role::Input)?,
            pick(output, data::Role::Output)?,
            load_output,
            input_times,
            input_gain,
            load_gain,
            window,
            intersample,
            gear_ratio,
        )?;
        data::load(&path, &cols)
            .map(|inner| Recording { inner })
            .map_err(data_error)
    }

    /// Load the CSV a dataset file (TOML) names, read as the file says: the CLI's
    /// `hil-host diagnose data.toml`.
    #[staticmethod]
    fn from_dataset(path: PathBuf) -> PyResult<Self> {
        let d = Dataset::load(&path).map_err(|e| DataError::new_err(e.to_string()))?;
        let cols = d.columns(&d.file, true).map_err(data_error)?;
        data::load(&d.file, &cols)
            .map(|inner| Recording { inner })
            .map_err(data_error)
    }

    /// Build one from arrays; the names label the arrays (and give their units by suffix,
    /// as a CSV's column names do).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (t, u, q, *, time, input, output, load = None, load_output = None,
        times = None, input_times = None, input_gain = 1.0, load_gain = 1.0, window = None,
        intersample = "zoh", gear_ratio = 1.0))]
    fn from_arrays(
        t: Vec<f64>,
        u: Vec<f64>,
        q: Vec<f64>,
        time: String,
        input: String,
        output: String,
        load: Option<Vec<f64>>,
        load_output: Option<String>,
        times: Option<Vec<f64>>,
        input_times: Option<String>,
        input_gain: f64,
        load_gain: f64,
        window: Option<(Option<f64>, Option<f64>)>,
        intersample: &str,
        gear_ratio: f64,
    ) -> PyResult<Self> {
        let cols = columns(
            time,
            input,
            output,
            load_output,
            input_times,
            input_gain,
            load_gain,
            window,
            intersample,
            gear_ratio,
        )?;
        let arrays = Arrays {
            time: &t,
            input: &u,
            output: &q,
            load_output: load.as_deref(),
            input_times: times.as_deref(),
        };
        data::Recording::from_arrays(arrays, &cols)
            .map(|inner| Recording { inner })
            .map_err(data_error)
    }

    /// Number of samples.
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// The (uniform) sample period, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt
    }

    /// Time, s (on the uniform clock if the record was resampled).
    #[getter]
    fn time(&self) -> Vec<f64> {
        self.inner.time.clone()
    }

    /// The input in force/torque units (after gains).
    #[getter]
    fn input(&self) -> Vec<f64> {
        self.inner.input.clone()
    }

    /// The output position in SI units.
    #[getter]
    fn output(&self) -> Vec<f64> {
        self.inner.output.clone()
    }

    /// How an irregular clock was made uniform (JSON text, `null` if it was not).
    fn resampled_json(&self) -> String {
        json!(self.inner.resampled).to_string()
    }

    fn __repr__(&self) -> String {
        format!(
            "Recording({}, {} samples, dt {} s)",
            self.inner.path.display(),
            self.inner.len(),
            self.inner.dt
        )
    }
}

/// The recording differentiated, with the CLI's checks: a cut-off the record cannot carry
/// is a bad argument, a signal out of range after differentiation a [`DataError`].
fn prepared(rec: &Recording, cutoff: Option<f64>) -> PyResult<Prepared> {
    Prepared::checked(&rec.inner, cutoff).map_err(prepare_error)
}

/// A validation recording, read in the estimation's band `band` (its default when `cutoff`,
/// the caller's, is `None`).
fn validation(
    val: &Recording,
    est: &Recording,
    band: f64,
    cutoff: Option<f64>,
) -> PyResult<Prepared> {
    let default_of = cutoff.is_none().then_some(est.inner.path.as_path());
    Prepared::checked_in_band(&val.inner, band, default_of).map_err(prepare_error)
}

fn prepare_error(e: PrepareError) -> PyErr {
    match e {
        PrepareError::Cutoff(e) => value_error(e),
        PrepareError::Data(e) => data_error(e),
    }
}

/// A [`FitError`] unless the score's fit % and RMS are finite (a NaN score would read as
/// "nothing missing").
fn finite_score(rec: &Recording, fit_percent: f64, rms: f64) -> PyResult<()> {
    for (what, value) in [("fit %", fit_percent), ("RMS", rms)] {
        if !value.is_finite() {
            let e = fit::FitError::NonFiniteScore {
                what,
                record: "estimation",
                value,
            };
            return Err(fit_error(&rec.inner.path.display().to_string(), e));
        }
    }
    Ok(())
}

/// `schema_version` and the record's units into `j`, as the CLI's `--json` has them.
fn stamp(j: &mut serde_json::Value, rec: &Recording, mode: Mode) -> PyResult<()> {
    let units = schema::RecordUnits::of(&rec.inner.columns, mode).map_err(value_error)?;
    schema::stamp(j, &units);
    Ok(())
}

/// `model` (or the baseline) with its free parameters fitted to `p`, as `diagnose` starts.
fn fitted(rec: &Recording, m: Option<&Model>, p: &Prepared) -> PyResult<model::Model> {
    let mut m = m.map_or_else(model::Model::baseline, |m| m.inner.clone());
    m.on_axis(p.axis, &p.input_unit).map_err(model_error)?;
    if m.params().iter().any(|q| q.free) {
        refine::refit_all(&mut m, p).map_err(|e| fit_error("fitting the free parameters", e))?;
    }
    let s = refine::score(&m, p);
    finite_score(rec, s.fit_percent, s.rms)?;
    Ok(m)
}

/// `diagnose --json`.
#[pyfunction]
#[pyo3(name = "diagnose", signature = (rec, model = None, *, cutoff = None, alpha = 0.05, min_err = 0.01, min_rho = 0.25))]
fn py_diagnose(
    py: Python<'_>,
    rec: &Recording,
    model: Option<&Model>,
    cutoff: Option<f64>,
    alpha: f64,
    min_err: f64,
    min_rho: f64,
) -> PyResult<String> {
    let opts = options(alpha, min_err, min_rho)?;
    py.detach(|| {
        let p = prepared(rec, cutoff)?;
        let m = fitted(rec, model, &p)?;
        let mut j = diagnose::diagnose(&m, &p, &opts).to_json();
        j["resampled"] = json!(rec.inner.resampled);
        stamp(&mut j, rec, Mode::Equation)?;
        Ok(j.to_string())
    })
}

/// `diagnose --auto --json`, and the final model.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(name = "auto", signature = (rec, model = None, *, validate = None, cutoff = None, alpha = 0.05,
    min_err = 0.01, min_rho = 0.25, max_steps = 6))]
fn py_auto(
    py: Python<'_>,
    rec: &Recording,
    model: Option<&Model>,
    validate: Option<&Recording>,
    cutoff: Option<f64>,
    alpha: f64,
    min_err: f64,
    min_rho: f64,
    max_steps: usize,
) -> PyResult<(String, Model)> {
    let opts = options(alpha, min_err, min_rho)?;
    py.detach(|| {
        let p = prepared(rec, cutoff)?;
        let mut m = fitted(rec, model, &p)?;
        let val = validate
            .map(|v| validation(v, rec, p.cutoff_hz, cutoff))
            .transpose()?;
        let run = refine::auto(&mut m, &p, val.as_ref(), &opts, max_steps)
            .map_err(|e| fit_error("", e))?;
        let mut j = json!({
            "residual_mode": run.last.residual_mode,
            "steps": run.steps,
            "stop": run.stop,
            "final": run.last.to_json(),
            "model": m.to_sim(),
            "resampled": rec.inner.resampled,
            "notes": refine::extrapolation_notes(&m, &p, val.as_ref()),
        });
        stamp(&mut j, rec, Mode::Equation)?;
        Ok((j.to_string(), Model { inner: m }))
    })
}

/// `fit --json` (without `model_file`: the fitted model is returned, `save` writes it).
#[pyfunction]
#[pyo3(name = "fit", signature = (rec, model = None, *, add = None, validate = None, cutoff = None))]
fn py_fit(
    py: Python<'_>,
    rec: &Recording,
    model: Option<&Model>,
    add: Option<&str>,
    validate: Option<&Recording>,
    cutoff: Option<f64>,
) -> PyResult<(String, Model)> {
    let mut m = model.map_or_else(model::Model::baseline, |m| m.inner.clone());
    let kind = match add {
        Some(n) => {
            let k = jointlab_workbench::names::effect(n)
                .map_err(|e| value_error(format!("add={n:?}: {e}")))?;
            if m.has(k) {
                return Err(value_error(format!(
                    "add={n:?}: the model already contains `{n}`"
                )));
            }
            Some(k)
        }
        None => None,
    };
    py.detach(|| {
        let p = prepared(rec, cutoff)?;
        m.on_axis(p.axis, &p.input_unit).map_err(model_error)?;
        let val = validate
            .map(|v| validation(v, rec, p.cutoff_hz, cutoff))
            .transpose()?;
        let as_given = model.map(|_| {
            json!({
                "estimation": refine::score(&m, &p),
                "validation": val.as_ref().map(|v| refine::score(&m, v)),
            })
        });
        let r = refine::fit_add(&mut m, &p, kind, val.as_ref()).map_err(|e| fit_error("", e))?;
        let mut j = json!({
            "report": r,
            "as_given": as_given,
            "resampled": rec.inner.resampled,
            "notes": refine::extrapolation_notes(&m, &p, val.as_ref()),
        });
        stamp(&mut j, rec, Mode::Equation)?;
        Ok((j.to_string(), Model { inner: m }))
    })
}

/// `compare --json` (no report directory: `report` is null), plus the residual's series
/// (`time`, `measured`, `predicted`, `residual`) for plotting.
#[pyfunction]
#[pyo3(name = "compare", signature = (rec, model = None, *, residual = "equation", period = None, refit = false,
    cutoff = None))]
fn py_compare(
    py: Python<'_>,
    rec: &Recording,
    model: Option<&Model>,
    residual: &str,
    period: Option<f64>,
    refit: bool,
    cutoff: Option<f64>,
) -> PyResult<String> {
    let mode = match residual {
        "equation" => Mode::Equation,
        "output" => Mode::Output,
        other => {
            return Err(value_error(format!(
                "residual={other:?}: one of \"equation\", \"output\""
            )))
        }
    };
    let period = period.map(|x| check("period", x, true)).transpose()?;
    py.detach(|| {
        let p = prepared(rec, cutoff)?;
        let m = match (model, refit) {
            (Some(m), false) => {
                let mut m = m.inner.clone();
                m.on_axis(p.axis, &p.input_unit).map_err(model_error)?;
                m
            }
            _ => fitted(rec, model, &p)?,
        };
        let res = match mode {
            Mode::Equation => residual::equation_error(&m, &p),
            Mode::Output => residual::output_error(&m, &p),
        };
        if let Some(k) = res.predicted.iter().position(|y| !y.is_finite()) {
            return Err(value_error(format!(
                "residual=\"output\": the model's simulation from the measured input diverged \
                 at t = {:.4} s — the model is not stable open loop on this input; the \
                 equation-error residual (the default) has no such limit",
                res.time.get(k).copied().unwrap_or(f64::NAN)
            )));
        }
        let metrics = metrics::compute(&res, period);
        finite_score(rec, metrics.fit_percent, metrics.rms)?;
        let mut j = json!({
            "metrics": metrics,
            "params": refine::param_rows(&m),
            "report": null,
            "residual_csv": null,
            "resampled": rec.inner.resampled,
            "series": {
                "time": res.time,
                "measured": res.measured,
                "predicted": res.predicted,
                "residual": res.residual,
            },
        });
        stamp(&mut j, rec, mode)?;
        Ok(j.to_string())
    })
}

/// The extension module.
#[pymodule]
fn _jointlab(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("JointlabError", py.get_type::<JointlabError>())?;
    m.add("DataError", py.get_type::<DataError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("FitError", py.get_type::<FitError>())?;
    m.add_class::<Model>()?;
    m.add_class::<Recording>()?;
    m.add_function(wrap_pyfunction!(py_diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(py_auto, m)?)?;
    m.add_function(wrap_pyfunction!(py_fit, m)?)?;
    m.add_function(wrap_pyfunction!(py_compare, m)?)?;
    Ok(())
}
