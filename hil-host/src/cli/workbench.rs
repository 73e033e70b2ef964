//! `compare`, `diagnose`, `fit`: the workbench commands.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use sim_plant::effects::{EffectKind, Intersample};

use jointlab_workbench::data::{self, Columns, Resampled};
use jointlab_workbench::dataset::{self, Dataset};
use jointlab_workbench::diagnose::{self, Options};
use jointlab_workbench::fit::FitError;
use jointlab_workbench::metrics;
use jointlab_workbench::model::Model;
use jointlab_workbench::refine::{self, AutoStep, FitReport, Score};
use jointlab_workbench::report::{self, Chart, Series};
use jointlab_workbench::residual::{self, Mode, PrepareError, Prepared, Residual};
use jointlab_workbench::schema;

/// Examples for `compare --help`.
pub const COMPARE_EXAMPLES: &str = "Examples:
  # EMPS's validation record (a dataset file names the CSV and its columns), report in report/
  hil-host compare datasets/emps-pulses.toml --model emps2.toml --report report
  # a CSV whose header has unit suffixes needs no column flags; output error, PNGs as well
  hil-host compare run.csv --model fitted.toml --residual output --png
  # or name the columns
  hil-host compare run.csv --time t_s --input cmd_V --input-gain 12.5 --output q_rad --model fitted.toml";

/// Examples for `diagnose --help`.
pub const DIAGNOSE_EXAMPLES: &str = "Examples:
  hil-host diagnose datasets/emps.toml --json
  # add effects until nothing significant is left, validated on the dataset's `validate`
  hil-host diagnose datasets/emps.toml --auto --save-model auto.toml --report auto-report
  hil-host diagnose run.csv --input torque_Nm --output q_rad --auto --validate val.csv";

/// Examples for `fit --help`.
pub const FIT_EXAMPLES: &str = "Examples:
  hil-host fit datasets/emps.toml --add coulomb --save-model emps1.toml
  hil-host fit datasets/emps.toml --model emps1.toml --add offset --save-model emps2.toml
  hil-host fit run.csv --input torque_Nm --output q_rad --add ripple --validate val.csv";

/// Residual choice.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ResidualArg {
    /// Inverse dynamics: predicted vs measured input.
    Equation,
    /// Simulation: simulated vs measured position.
    Output,
}

/// Recording and model options shared by every workbench command. The column and gain flags
/// override a dataset file's values; what neither names is found from the CSV's header.
#[derive(Debug, Args)]
pub struct DataArgs {
    /// Recording: a CSV with a header row, or a dataset file (.toml) that names one and how to
    /// read it (docs/workbench.md, *Dataset files*).
    pub file: PathBuf,
    /// Input column (force/torque, or a command scaled by --input-gain). Default: the one
    /// column whose suffix is a force or torque (`_N`, `_Nm`).
    #[arg(long)]
    pub input: Option<String>,
    /// Output (position) column. Default: the one column whose suffix is a position (`_rad`,
    /// `_deg`, `_m`, `_mm`).
    #[arg(long)]
    pub output: Option<String>,
    /// Optional load-side position column (an output encoder): backlash is then fitted on the
    /// measured deflection output − load instead of an estimate from the output alone.
    #[arg(long)]
    pub load_output: Option<String>,
    /// Gain from the load column to the output column's axis, e.g. the gear ratio N when the
    /// load encoder is at the joint's output and --output is the motor shaft (default 1).
    #[arg(long, value_parser = gain, allow_negative_numbers = true)]
    pub load_gain: Option<f64>,
    /// Time column. Default: the first of time_s, t_s, time, t, time_ms, t_ms in the header.
    #[arg(long)]
    pub time: Option<String>,
    /// Gain from the input column to force/torque (e.g. EMPS gtau = 35.15065188248547 N/V;
    /// default 1).
    #[arg(long, value_parser = gain, allow_negative_numbers = true)]
    pub input_gain: Option<f64>,
    /// The input's unit after --input-gain, as reports label it (e.g. `N`).
    #[arg(long)]
    pub input_unit: Option<String>,
    /// A column the input is multiplied by, row by row (e.g. the measured supply voltage when
    /// --input is a PWM duty in −1…1: duty × volts is the applied voltage).
    #[arg(long)]
    pub input_times: Option<String>,
    /// Use only the rows from this time on (s, in the time column after its unit suffix). A
    /// --validate file, where the command has one, is used whole.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub from: Option<f64>,
    /// Use only the rows up to this time (s). A --validate file is used whole.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub to: Option<f64>,
    /// Model TOML; without it the baseline is a rigid inertia with viscous friction, both
    /// fitted. `compare` takes several (`--model a.toml --model b.toml`) and overlays them.
    #[arg(long)]
    pub model: Vec<PathBuf>,
    /// Differentiator cut-off, Hz. Default: on a rotary axis, the band where the record's own
    /// encoder noise reaches the acceleration as a 2¹⁶-count encoder's does at 40 Hz and
    /// 1 kHz (23 Hz for 2¹⁴ counts at 1 kHz, 70 Hz for 2¹⁸), within a tenth of the sample rate
    /// and 100 Hz; on a linear axis that upper limit. `diagnose` prints the band it used; a
    /// transmission mode above it needs a higher one. A --validate file is read in the same band.
    #[arg(long)]
    pub cutoff: Option<f64>,
    /// What the input did between samples: `zoh` (a drive's log: position sampled when the
    /// command was computed, the command then held — a half-sample lag the baseline accounts
    /// for, so `delay` means a delay beyond the hold; the default), `foh` (linear between
    /// samples), `mid` (command held, position logged mid-hold), `bl` (band-limited samples).
    /// Also applies to a --validate file.
    #[arg(long, value_parser = intersample)]
    pub intersample: Option<Intersample>,
    /// The output column is the motor shaft of an N:1 gear: gravity acts on the joint's output
    /// angle, position/N (default 1: the column is the output's angle).
    #[arg(long, value_parser = positive)]
    pub gear_ratio: Option<f64>,
}

impl DataArgs {
    /// What the flags say, as a dataset of `file`.
    fn flags(&self, file: PathBuf) -> Dataset {
        Dataset {
            file,
            description: None,
            time: self.time.clone(),
            input: self.input.clone(),
            output: self.output.clone(),
            load_output: self.load_output.clone(),
            load_gain: self.load_gain,
            input_gain: self.input_gain,
            input_unit: self.input_unit.clone(),
            input_times: self.input_times.clone(),
            from: self.from,
            to: self.to,
            intersample: self.intersample.map(|i| i.name().to_string()),
            gear_ratio: self.gear_ratio,
            validate: None,
        }
    }
    /// The recording's description: the flags over the dataset file `path` when it is one.
    fn dataset_of(&self, path: &Path) -> anyhow::Result<Dataset> {
        if !dataset::is_dataset(path) {
            return Ok(self.flags(path.to_path_buf()));
        }
        let d = Dataset::load(path)?;
        let merged = self.flags(d.file.clone()).or(d);
        merged.check(Path::new("<command line>"))?;
        Ok(merged)
    }
    /// The recording's description.
    pub fn dataset(&self) -> anyhow::Result<Dataset> {
        self.dataset_of(&self.file)
    }
    /// The CSV the recording is read from (the dataset file's `file`, or the argument).
    pub fn csv(&self) -> anyhow::Result<PathBuf> {
        Ok(self.dataset()?.file)
    }
    /// The columns of the recording, with the --from/--to window when `windowed` (the
    /// recording itself, not a --validate file — which may be the same file, validated on all
    /// of it).
    fn columns(&self, windowed: bool) -> anyhow::Result<Columns> {
        let d = self.dataset()?;
        Ok(d.columns(&d.file, windowed)?)
    }
    /// The validation file to use: `--validate` if given, else the dataset file's `validate`.
    fn validate_file(&self, flag: Option<&PathBuf>) -> anyhow::Result<Option<PathBuf>> {
        match flag {
            Some(f) => Ok(Some(f.clone())),
            None => Ok(self.dataset()?.validate),
        }
    }
    /// A --validate recording: the whole file, no window, read with the recording's columns
    /// (or, for a dataset file, with its own, under the same flags). The recording itself,
    /// unwindowed, is estimation data scored again, and the note says so. It is
    /// differentiated in the estimation record's band (`cutoff_hz`), so both are read alike.
    fn validation(&self, file: &Path, cutoff_hz: f64) -> anyhow::Result<Prepared> {
        let d = self.dataset()?;
        let v = if dataset::is_dataset(file) {
            self.dataset_of(file)?
        } else {
            Dataset {
                file: file.to_path_buf(),
                ..d.clone()
            }
        };
        if v.file == d.file && d.from.is_none() && d.to.is_none() {
            eprintln!(
                "note: --validate {} is the recording itself: its scores are the estimation \
                 scores again (--from/--to hold out part of it)",
                v.file.display()
            );
        }
        let cols = v.columns(&v.file, false)?;
        let default_of = self.cutoff.is_none().then_some(d.file.as_path());
        load_in(&v.file, &cols, |rec| {
            Prepared::checked_in_band(rec, cutoff_hz, default_of)
        })
        .map(|(p, _)| p)
    }
    /// The recording (inside the --from/--to window), and how it was resampled.
    fn recording(&self) -> anyhow::Result<(Prepared, Option<Resampled>)> {
        let d = self.dataset()?;
        let cols = d.columns(&d.file, true)?;
        load_prepared(&d.file, &cols, self.cutoff)
    }
    /// The units of the recording's signals for the equation error (what `diagnose` and `fit`
    /// score), as every `--json` names them.
    fn units(&self) -> anyhow::Result<schema::RecordUnits> {
        Ok(schema::RecordUnits::of(
            &self.columns(true)?,
            Mode::Equation,
        )?)
    }
    /// The one model file a command other than `compare` takes.
    fn model_file(&self) -> anyhow::Result<Option<&PathBuf>> {
        match self.model.as_slice() {
            [] => Ok(None),
            [f] => Ok(Some(f)),
            _ => Err(anyhow::anyhow!(
                "--model is given {} times: only `compare` takes several models",
                self.model.len()
            )),
        }
    }
    /// The model, with its free parameters fitted to `p`.
    fn model(&self, p: &Prepared) -> anyhow::Result<Model> {
        self.model_fitted(self.model_file()?, p)
    }
    /// The model in `file` (the baseline if none), with its free parameters fitted to `p`.
    fn model_fitted(&self, file: Option<&PathBuf>, p: &Prepared) -> anyhow::Result<Model> {
        let mut m = match file {
            Some(f) => Model::load(f)?,
            None => Model::baseline(),
        };
        m.on_axis(p.axis, &p.input_unit)
            .context(self.csv()?.display().to_string())?;
        if m.params().iter().any(|q| q.free) {
            refine::refit_all(&mut m, p).context("fitting the free parameters")?;
        }
        let s = refine::score(&m, p);
        finite_score(s.fit_percent, s.rms, &self.csv()?)?;
        Ok(m)
    }
}

/// An error naming `csv` unless a model's fit % and RMS on it are finite: a model that scores
/// NaN would be diagnosed as "nothing missing" with exit 0.
fn finite_score(fit_percent: f64, rms: f64, csv: &Path) -> anyhow::Result<()> {
    for (what, value) in [("fit %", fit_percent), ("RMS", rms)] {
        if !value.is_finite() {
            return Err(anyhow::Error::new(FitError::NonFiniteScore {
                what,
                record: "estimation",
                value,
            })
            .context(csv.display().to_string()));
        }
    }
    Ok(())
}

/// `file` read with `cols` and differentiated, and how it was resampled, if it was (for a
/// report; the note is printed on stderr either way).
fn load_prepared(
    file: &Path,
    cols: &Columns,
    cutoff: Option<f64>,
) -> anyhow::Result<(Prepared, Option<Resampled>)> {
    load_in(file, cols, |rec| Prepared::checked(rec, cutoff))
}

/// [`load_prepared`] with the preparation `prepare` (a validation record's is in the
/// estimation record's band).
fn load_in(
    file: &Path,
    cols: &Columns,
    prepare: impl FnOnce(&data::Recording) -> Result<Prepared, PrepareError>,
) -> anyhow::Result<(Prepared, Option<Resampled>)> {
    let rec = data::load(file, cols)?;
    // On stderr: `--json` keeps exactly one object on stdout.
    if cols.window.is_some() {
        eprintln!(
            "note: {}: the {} rows from {:.4} to {:.4} s (--from/--to)",
            file.display(),
            rec.len(),
            rec.time.first().copied().unwrap_or(f64::NAN),
            rec.time.last().copied().unwrap_or(f64::NAN)
        );
    }
    if let Some(r) = &rec.resampled {
        eprintln!("{}", r.note(file));
    }
    // A cut-off the record cannot carry is the command's fault (exit 2), a signal out of
    // range the data's (exit 1): see `exit_code`.
    let p = prepare(&rec).map_err(|e| match e {
        PrepareError::Cutoff(e) => anyhow::Error::new(e),
        PrepareError::Data(e) => anyhow::Error::new(e),
    })?;
    Ok((p, rec.resampled))
}

/// Where a command writes its model: the path named with --save-model (replaced if it exists:
/// the user named it), else `stem.toml`, or the first free `stem-2.toml`, `stem-3.toml`, … so
/// an earlier run's model is never silently lost.
fn model_path(named: Option<&PathBuf>, stem: &str) -> PathBuf {
    if let Some(p) = named {
        return p.clone();
    }
    (1u32..)
        .map(|k| match k {
            1 => PathBuf::from(format!("{stem}.toml")),
            k => PathBuf::from(format!("{stem}-{k}.toml")),
        })
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from(format!("{stem}.toml")))
}

/// A probability strictly between 0 and 1 (`--alpha`).
fn probability(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("`{s}`: {e}"))?;
    if x > 0.0 && x < 1.0 {
        Ok(x)
    } else {
        Err(format!("{x} is not a probability strictly between 0 and 1"))
    }
}

/// `--intersample`: one of the names of [`Intersample`].
fn intersample(s: &str) -> Result<Intersample, String> {
    s.parse()
}

/// A finite number (`--from`, `--to`).
fn finite(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("`{s}`: {e}"))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{x} is not a finite time"))
    }
}

/// A finite, nonzero number (`--input-gain`, `--load-gain`): a NaN or infinite gain would
/// reach the fit as NaN, and a zero one erases the column.
fn gain(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("`{s}`: {e}"))?;
    if x.is_finite() && x != 0.0 {
        Ok(x)
    } else {
        Err(format!("{x} must be a finite number other than 0"))
    }
}

/// A finite number above 0 (`--period`).
fn positive(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("`{s}`: {e}"))?;
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(format!("{x} must be a finite number above 0"))
    }
}

/// `compare` options.
#[derive(Debug, Args)]
pub struct CompareArgs {
    #[command(flatten)]
    /// Data and model.
    pub data: DataArgs,
    /// Residual to report.
    #[arg(long, value_enum, default_value = "equation")]
    pub residual: ResidualArg,
    /// Period for folding the residual over position (default: travel / 10).
    #[arg(long, value_parser = positive)]
    pub period: Option<f64>,
    /// Directory for the plots and report.html (`--out` is the older name).
    #[arg(long = "report", alias = "out", default_value = "workbench-report")]
    pub report: PathBuf,
    /// Also write PNGs beside the report's SVGs.
    #[arg(long)]
    pub png: bool,
    /// Refit the free parameters of `--model` on this recording first (by default a given
    /// model is compared as it is — e.g. a fitted model on validation data; the default
    /// baseline is always fitted).
    #[arg(long)]
    pub refit: bool,
    /// Print the metrics as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `diagnose` options.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    #[command(flatten)]
    /// Data and model.
    pub data: DataArgs,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Repeat rank → add → refit until nothing significant is left.
    #[arg(long)]
    pub auto: bool,
    /// Validation recording (same columns, or a dataset file) scored at every `--auto` step;
    /// default: the dataset file's `validate`.
    #[arg(long, requires = "auto")]
    pub validate: Option<PathBuf>,
    /// Family-wise error rate.
    #[arg(long, default_value_t = 0.05, value_parser = probability)]
    pub alpha: f64,
    /// Smallest fraction of residual variance an effect must explain to be added.
    #[arg(long, default_value_t = 0.01)]
    pub min_err: f64,
    /// Smallest RMS an effect must explain, in units of the noise floor.
    #[arg(long, default_value_t = 0.25)]
    pub min_rho: f64,
    /// Most effects `--auto` adds.
    #[arg(long, default_value_t = 6, requires = "auto")]
    pub max_steps: usize,
    /// Write the `--auto` model here (default `auto-model.toml`, or `auto-model-2.toml`, …
    /// when that exists: an earlier model is never replaced unless named here).
    #[arg(long, requires = "auto")]
    pub save_model: Option<PathBuf>,
    /// Directory for the `--auto` plot and report.html (`--out` is the older name).
    #[arg(long = "report", alias = "out", requires = "auto")]
    pub report: Option<PathBuf>,
    /// Also write PNGs beside the report's SVGs.
    #[arg(long, requires = "report")]
    pub png: bool,
}

/// `fit` options.
#[derive(Debug, Args)]
pub struct FitArgs {
    #[command(flatten)]
    /// Data and model.
    pub data: DataArgs,
    /// Effect to add (offset, viscous, coulomb, asymmetry, stribeck, backlash, compliance,
    /// ripple, cogging, gravity, deadband, delay, quantization). Without it: refit only.
    #[arg(long)]
    pub add: Option<String>,
    /// Validation recording (same columns, or a dataset file); default: the dataset file's
    /// `validate`.
    #[arg(long)]
    pub validate: Option<PathBuf>,
    /// Where to write the fitted model TOML (default `fitted-model.toml`, or
    /// `fitted-model-2.toml`, … when that exists: an earlier model is never replaced unless
    /// named here).
    #[arg(long)]
    pub save_model: Option<PathBuf>,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run `compare`.
pub fn compare(a: CompareArgs) -> anyhow::Result<()> {
    let (p, resampled) = a.data.recording()?;
    let csv = a.data.csv()?;
    let cols = a.data.columns(true)?;
    let mode = match a.residual {
        ResidualArg::Equation => Mode::Equation,
        ResidualArg::Output => Mode::Output,
    };
    // The models in order: each file as it is (or refitted on this record with --refit), the
    // fitted baseline when none is named.
    let files: Vec<Option<&PathBuf>> = if a.data.model.is_empty() {
        vec![None]
    } else {
        a.data.model.iter().map(Some).collect()
    };
    let mut models = Vec::new();
    for f in &files {
        let model = match (f, a.refit) {
            (Some(f), false) => {
                let mut m = Model::load(f)?;
                m.on_axis(p.axis, &p.input_unit)
                    .context(csv.display().to_string())?;
                m
            }
            _ => a.data.model_fitted(*f, &p)?,
        };
        let res = match mode {
            Mode::Equation => residual::equation_error(&model, &p),
            Mode::Output => residual::output_error(&model, &p),
        };
        if let Some(k) = res.predicted.iter().position(|y| !y.is_finite()) {
            bail!(
                "--residual output: model `{}`'s simulation from the measured input diverged \
                 at t = {:.4} s — the model is not stable open loop on this input (a \
                 closed-loop record needs its controller around the model); the \
                 equation-error residual (the default) has no such limit",
                model.name,
                res.time.get(k).copied().unwrap_or(f64::NAN)
            );
        }
        let m = metrics::compute(&res, a.period);
        finite_score(m.fit_percent, m.rms, &csv)?;
        models.push((model, res, m));
    }
    // Two files may hold models of one name: the legend tells them apart by file.
    let names: Vec<String> = models
        .iter()
        .zip(&files)
        .map(|((model, _, _), f)| {
            let twice = models.iter().filter(|o| o.0.name == model.name).count() > 1;
            match f {
                Some(f) if twice => format!("{} ({})", model.name, f.display()),
                _ => model.name.clone(),
            }
        })
        .collect();
    let position_unit = jointlab_workbench::units::unit_of(&cols.output)?
        .0
        .to_string();
    let units = report::Units {
        signal: if mode == Mode::Equation {
            data::input_unit(&cols)
        } else {
            position_unit.clone()
        },
        position: position_unit,
    };
    let compared: Vec<report::Compared<'_>> = models
        .iter()
        .zip(&names)
        .map(|((_, res, m), name)| report::Compared {
            name,
            residual: res,
            metrics: m,
        })
        .collect();
    let mut finding = report::finding(&compared);
    if !finding.contains("nothing more") {
        finding.push_str(" `diagnose` ranks which effect explains what is left.");
    }
    let charts = report::charts(&compared, &units);
    let mut sections = Vec::new();
    if let Some(r) = &resampled {
        sections.push(("resampling".to_string(), r.note(&csv)));
    }
    for ((model, _, m), name) in models.iter().zip(&names) {
        sections.push((format!("{name}: metrics"), m.to_text()));
        sections.push((
            format!("{name}: parameters"),
            param_text(&refine::param_rows(model)),
        ));
    }
    let mut inputs = vec![a.data.file.clone(), csv.clone()];
    inputs.extend(a.data.model.iter().cloned());
    let provenance =
        report::page::Provenance::now(concat!("hil-host ", env!("CARGO_PKG_VERSION")), &inputs)?;
    let model_texts: Vec<(String, String)> = models
        .iter()
        .zip(&names)
        .map(|((model, _, _), name)| (name.clone(), model.to_sim().to_toml_string()))
        .collect();
    let zoom = zoom_view(&compared, &units);
    let html = report::page::write(
        &a.report,
        &report::page::Page {
            title: &format!("compare: {} on {}", names.join(", "), csv.display()),
            finding: &finding,
            provenance: &provenance,
            sections: &sections,
            charts: &charts,
            zoom: Some(&zoom),
            models: &model_texts,
        },
        a.png,
    )?;
    let record_units = schema::RecordUnits::of(&cols, mode)?;
    let series: Vec<&Residual> = models.iter().map(|(_, res, _)| res).collect();
    let data = write_residual_csv(&a.report, &series, &record_units)?;
    let (model, _, m) = &models[0];
    if a.json {
        let mut j = serde_json::json!({
            "metrics": m,
            "params": refine::param_rows(model),
            "report": html,
            "residual_csv": data,
            "resampled": resampled,
        });
        if models.len() > 1 {
            j["models"] = models
                .iter()
                .zip(&names)
                .map(|((model, _, m), name)| {
                    serde_json::json!({
                        "name": name,
                        "metrics": m,
                        "params": refine::param_rows(model),
                    })
                })
                .collect();
        }
        schema::stamp(&mut j, &record_units);
        println!("{j}");
    } else {
        for ((model, _, m), name) in models.iter().zip(&names) {
            println!("model: {name}\n{}", param_text(&refine::param_rows(model)));
            print!("{}", m.to_text());
            if mode == Mode::Output && m.fit_percent < 0.0 {
                println!(
                    "note: fit below 0 %: the model simulated open loop from the measured \
                     input drifts away from the record. On closed-loop data (a controller \
                     closed the loop while recording) the output error needs that controller \
                     around the model; the equation error (the default) does not."
                );
            }
        }
        println!("finding: {finding}");
        println!("report: {}", html.display());
        println!("residual data: {}", data.display());
    }
    Ok(())
}

/// The compared series as data (MATLAB's `resid` returns them too): `residual.csv` in the
/// report's directory, one row per sample of the prepared record — time, the smoothed
/// position and velocity, the measured signal, and each model's prediction and residual
/// (`m2_…` for the second model, in the order given). Headers carry unit suffixes, so the file
/// reads back into the workbench and into any CSV tool.
fn write_residual_csv(
    dir: &Path,
    series: &[&Residual],
    units: &schema::RecordUnits,
) -> anyhow::Result<PathBuf> {
    let Some(first) = series.first() else {
        bail!("no model to write the residual of");
    };
    let suffix = |unit: &str| -> String {
        if unit.is_empty() {
            String::new()
        } else {
            format!("_{}", unit.replace('·', "").replace('/', "_per_"))
        }
    };
    let sig = suffix(&units.residual);
    let mut header = vec![
        "time_s".to_string(),
        format!("position{}", suffix(&units.position)),
        format!("velocity{}", suffix(&units.velocity)),
        format!("measured{sig}"),
    ];
    for k in 1..=series.len() {
        let tag = if series.len() == 1 {
            String::new()
        } else {
            format!("m{k}_")
        };
        header.push(format!("{tag}predicted{sig}"));
        header.push(format!("{tag}residual{sig}"));
    }
    let path = dir.join("residual.csv");
    let mut w =
        csv::Writer::from_path(&path).with_context(|| format!("writing {}", path.display()))?;
    w.write_record(&header)?;
    let n = series.iter().map(|r| r.time.len()).min().unwrap_or(0);
    for i in 0..n {
        let at = |v: &[f64]| v.get(i).copied().unwrap_or(f64::NAN);
        let mut row = vec![
            at(&first.time),
            at(&first.position),
            at(&first.velocity),
            at(&first.measured),
        ];
        for r in series {
            row.push(at(&r.predicted));
            row.push(at(&r.residual));
        }
        w.write_record(row.iter().map(|x| format!("{x}")))?;
    }
    w.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// The report's zoomable view: the measurement and each model's prediction, and each model's
/// residual, over time (at most 200 000 samples: a longer record is thinned evenly).
fn zoom_view(models: &[report::Compared<'_>], units: &report::Units) -> report::page::ZoomView {
    use report::page::{Panel, Trace, ZoomView};
    let Some(first) = models.first() else {
        return ZoomView {
            x_label: "time [s]".into(),
            time: Vec::new(),
            panels: Vec::new(),
        };
    };
    let n = first.residual.time.len();
    let step = n.div_ceil(200_000).max(1);
    let thin = |v: &[f64]| v.iter().copied().step_by(step).collect::<Vec<_>>();
    let trace = |name: &str, y: &[f64], reference| Trace {
        name: name.to_string(),
        y: y.iter().step_by(step).map(|v| *v as f32).collect(),
        reference,
    };
    let what = if first.residual.mode == Mode::Equation {
        "input"
    } else {
        "position"
    };
    let mut top = vec![trace("measured", &first.residual.measured, true)];
    top.extend(
        models
            .iter()
            .map(|c| trace(c.name, &c.residual.predicted, false)),
    );
    ZoomView {
        x_label: "time [s]".into(),
        time: thin(&first.residual.time),
        panels: vec![
            Panel {
                y_label: format!("{what} [{}]", units.signal),
                series: top,
            },
            Panel {
                y_label: format!("residual [{}]", units.signal),
                series: models
                    .iter()
                    .map(|c| trace(c.name, &c.residual.residual, false))
                    .collect(),
            },
        ],
    }
}

/// A model's parameters ± 1σ, one per line, for the HTML reports.
fn param_text(rows: &[refine::ParamRow]) -> String {
    let head = format!(
        "{:<12} {:<14} {:>12}   {:<10} {}\n",
        "owner", "parameter", "value", "1σ", "unit"
    );
    head + &rows
        .iter()
        .map(|r| {
            format!(
                "{:<12} {:<14} {:>12} ± {:<10} {}\n",
                r.owner,
                r.name,
                report::eng(r.value),
                report::eng(r.sigma),
                r.unit
            )
        })
        .collect::<String>()
}

/// The `--auto` table: one row per step.
fn auto_text(steps: &[AutoStep]) -> String {
    let label = |st: &AutoStep| match (&st.added, &st.replaced) {
        (Some(a), Some(r)) => format!("{a} (for {r})"),
        (Some(a), None) => match &st.chosen_over {
            Some(o) => format!("{a} (over {o})"),
            None => a.clone(),
        },
        (None, Some(r)) => format!("(remove {r})"),
        _ => "(start)".into(),
    };
    // The "added" column is as wide as its longest entry (a swap reads "x + y (for z)").
    let w = steps
        .iter()
        .map(|st| label(st).chars().count())
        .max()
        .unwrap_or(0)
        .max(13);
    // Each row's multiple is against its own model's floor (`Score::floor_ratio`): the number
    // `diagnose --model`, `compare` and `fit` print for that model on this record.
    let mut s = format!(
        "{:>4}  {:<w$} {:>9} {:>12} {:>7} {:>10} {:>12} {:>10} {:>10}\n",
        "step", "added", "fit %", "RMS", "×floor", "Holm p", "val RMS", "val fit %", "val gain"
    );
    let mut prev_val: Option<f64> = None;
    for st in steps {
        // What the step bought on the validation record: its RMS's relative fall.
        let gain = match (prev_val, st.validation) {
            (Some(a), Some(v)) => format!("{:.2} %", 100.0 * (a - v.rms) / a),
            _ => String::new(),
        };
        prev_val = st.validation.map(|v| v.rms);
        s.push_str(&format!(
            "{:>4}  {:<w$} {:>9.3} {:>12} {:>7.2} {:>10} {:>12} {:>10} {:>10}\n",
            st.step,
            label(st),
            st.score.fit_percent,
            report::eng(st.score.rms),
            st.score.floor_ratio(),
            st.p_value.map(|p| format!("{p:.2e}")).unwrap_or_default(),
            st.validation
                .map(|v| report::eng(v.rms))
                .unwrap_or_default(),
            st.validation
                .map(|v| format!("{:.3}", v.fit_percent))
                .unwrap_or_default(),
            gain,
        ));
    }
    s
}

/// Run `diagnose`.
pub fn diagnose(a: DiagnoseArgs) -> anyhow::Result<()> {
    let (p, resampled) = a.data.recording()?;
    let mut model = a.data.model(&p)?;
    let opts = Options {
        alpha: a.alpha,
        min_err: a.min_err,
        min_rho: a.min_rho,
        ..Options::default()
    };
    if !a.auto {
        let d = diagnose::diagnose(&model, &p, &opts);
        if a.json {
            let mut j = d.to_json();
            j["resampled"] = serde_json::json!(resampled);
            schema::stamp(&mut j, &a.data.units()?);
            println!("{j}");
        } else {
            print!("{}", d.to_text());
        }
        return Ok(());
    }
    let save = model_path(a.save_model.as_ref(), "auto-model");
    let val = match a.data.validate_file(a.validate.as_ref())? {
        Some(f) => Some(a.data.validation(&f, p.cutoff_hz)?),
        None => None,
    };
    // Each step refits its leading candidates in full (minutes on a long record): a spinner
    // on stderr with the steps so far (drawn only on a terminal, so pipes and --json are clean).
    let spinner = indicatif::ProgressBar::new(a.max_steps as u64);
    if let Ok(st) =
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} step {pos}/{len}: {msg}")
    {
        spinner.set_style(st);
    }
    spinner.set_message("ranking the library's effects and refitting the leading candidates");
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    let run = refine::auto_observed(
        &mut model,
        &p,
        val.as_ref(),
        &opts,
        a.max_steps,
        &mut |s: &AutoStep| {
            let what = match (&s.added, &s.replaced) {
                (Some(e), Some(r)) => format!("{e} replaces {r}"),
                (None, Some(r)) => format!("remove {r}"),
                (Some(e), None) => format!("add {e}"),
                (None, None) => "start".into(),
            };
            spinner.println(format!(
                "step {}: {what}, fit {:.3} %, RMS {}",
                s.step,
                s.score.fit_percent,
                report::eng(s.score.rms)
            ));
            spinner.set_position((s.step as u64).min(a.max_steps as u64));
            spinner.set_message("ranking what is left and refitting the leading candidates");
        },
    );
    // Cleared before an error is printed too, so no spinner line is left above it.
    spinner.finish_and_clear();
    let run = run?;
    model.save(&save)?;
    let table = auto_text(&run.steps);
    let mut report_path = None;
    if let Some(dir) = &a.report {
        let mut series = vec![Series::line(
            "estimation RMS",
            run.steps
                .iter()
                .map(|s| (s.step as f64, s.score.rms))
                .collect(),
        )];
        if val.is_some() {
            series.push(Series::line(
                "validation RMS",
                run.steps
                    .iter()
                    .filter_map(|s| s.validation.map(|v| (s.step as f64, v.rms)))
                    .collect(),
            ));
        }
        let chart = Chart {
            id: "auto_error".into(),
            title: "equation-error RMS after each added effect".into(),
            x_label: "step".into(),
            y_label: format!("RMS [{}]", data::input_unit(&a.data.columns(true)?)),
            series,
        };
        let res = residual::equation_error(&model, &p);
        let m = metrics::compute(&res, None);
        let cols = a.data.columns(true)?;
        let units = report::Units {
            signal: data::input_unit(&cols),
            position: jointlab_workbench::units::unit_of(&cols.output)?
                .0
                .to_string(),
        };
        let compared = [report::Compared {
            name: &model.name,
            residual: &res,
            metrics: &m,
        }];
        let mut charts = vec![chart];
        charts.extend(report::charts(&compared, &units));
        let added: Vec<&str> = run
            .steps
            .iter()
            .filter_map(|s| s.added.as_deref())
            .collect();
        let finding = format!(
            "Added {} and stopped: {}. Final diagnosis: {}. {}",
            if added.is_empty() {
                "nothing".to_string()
            } else {
                added.join(", then ")
            },
            run.stop,
            run.last.verdict.text,
            report::finding(&compared)
        );
        let csv = a.data.csv()?;
        let mut inputs = vec![a.data.file.clone(), csv];
        inputs.extend(a.data.model.iter().cloned());
        if let Some(v) = a.data.validate_file(a.validate.as_ref())? {
            inputs.push(v.clone());
            if dataset::is_dataset(&v) {
                inputs.push(a.data.dataset_of(&v)?.file);
            }
        }
        let provenance = report::page::Provenance::now(
            concat!("hil-host ", env!("CARGO_PKG_VERSION")),
            &inputs,
        )?;
        report_path = Some(report::page::write(
            dir,
            &report::page::Page {
                title: "diagnose --auto",
                finding: &finding,
                provenance: &provenance,
                sections: &[
                    ("steps".into(), table.clone()),
                    (
                        "final diagnosis".into(),
                        format!("stopped: {}\n{}", run.stop, run.last.to_text()),
                    ),
                    (
                        "final model".into(),
                        param_text(&refine::param_rows(&model)),
                    ),
                    ("final metrics".into(), m.to_text()),
                ],
                charts: &charts,
                zoom: Some(&zoom_view(&compared, &units)),
                models: &[(model.name.clone(), model.to_sim().to_toml_string())],
            },
            a.png,
        )?);
    }
    let extrapolated = refine::extrapolation_notes(&model, &p, val.as_ref());
    if a.json {
        let mut j = serde_json::json!({
            "residual_mode": run.last.residual_mode,
            "steps": run.steps,
            "stop": run.stop,
            "final": run.last.to_json(),
            "model": model.to_sim(),
            "model_file": save,
            "resampled": resampled,
            "notes": extrapolated,
        });
        schema::stamp(&mut j, &a.data.units()?);
        println!("{j}");
    } else {
        print!("{table}");
        println!("stopped: {}", run.stop);
        println!("final diagnosis: {}", run.last.verdict.text);
        for n in run.last.notes.iter().chain(&extrapolated) {
            println!("note: {n}");
        }
        if let Some(r) = report_path {
            println!("report: {}", r.display());
        }
        println!("model written to {}", save.display());
    }
    Ok(())
}

fn fit_text(r: &FitReport) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "added: {}\n",
        r.added.map_or("(nothing, refit only)", |k| k.name())
    ));
    s.push_str(&param_text(&r.params));
    let line = |name: &str, b: &Score, a: &Score| {
        format!(
            "{name}: fit {:.3} % → {:.3} %, RMS {} → {} ({:.2} → {:.2}× the noise floor), \
             rel. error {:.3} % → {:.3} %\n",
            b.fit_percent,
            a.fit_percent,
            report::eng(b.rms),
            report::eng(a.rms),
            b.floor_ratio(),
            a.floor_ratio(),
            b.relative_error_percent,
            a.relative_error_percent
        )
    };
    s.push_str(&line("estimation", &r.before, &r.after));
    if let (Some(b), Some(a)) = (r.before_validation, r.after_validation) {
        s.push_str(&line("validation", &b, &a));
        if a.rms > b.rms && r.after.rms <= r.before.rms {
            s.push_str(&format!(
                "note: the validation error rose ({:.1} % in RMS) while the estimation error fell: \
                 the refit does not carry to the validation record — a shape the estimation \
                 record does not pin down, or conditions it lacks (speeds, rests, loads). \
                 `compare --model` on the validation file shows where the error lives.\n",
                100.0 * (a.rms / b.rms - 1.0)
            ));
        }
    }
    s
}

/// The scores of a model file's own values, before `fit` refits them.
#[derive(Debug, Clone, Copy, serde::Serialize)]
struct AsGiven {
    estimation: Score,
    validation: Option<Score>,
}

impl AsGiven {
    /// A line for the model as given, when its error differs from the refitted "before" by
    /// more than 0.1 % of RMS (a model fitted on this very record matches it, and the line
    /// would only repeat it).
    fn text(&self, r: &FitReport) -> Option<String> {
        let differs = |g: &Score, b: &Score| (g.rms - b.rms).abs() > 1e-3 * b.rms;
        let val = self.validation.zip(r.before_validation);
        if !differs(&self.estimation, &r.before) && !val.is_some_and(|(g, b)| differs(&g, &b)) {
            return None;
        }
        let one = |name: &str, g: &Score| {
            format!(
                "{name} fit {:.3} %, RMS {} ({:.2}× the noise floor)",
                g.fit_percent,
                report::eng(g.rms),
                g.floor_ratio()
            )
        };
        let mut s = format!(
            "model as given (its file's values, not refitted): {}",
            one("estimation", &self.estimation)
        );
        if let Some(v) = &self.validation {
            s.push_str(&format!("; {}", one("validation", v)));
        }
        s.push_str(
            "\n(\"before\" below is that model refitted on this record without the new effect)\n",
        );
        Some(s)
    }
}

/// What to do next after a fit, from where its error sits against the noise floor. Kept out
/// of [`fit_text`] because it needs to know the record (a load encoder or not) and the
/// saved model's path.
fn fit_advice(r: &FitReport, load_encoder: bool, model_file: &Path) -> Option<String> {
    let left = r.after.floor_ratio();
    if !left.is_finite() || left <= diagnose::AT_FLOOR {
        return None;
    }
    let mut s = format!(
        "note: the estimation error is still {left:.2}× its noise floor; `diagnose --model {}` \
         ranks what the model still lacks.",
        model_file.display()
    );
    if r.added == Some(EffectKind::Backlash) && !load_encoder {
        s.push_str(
            " From the motor encoder alone the load's path through the gap is inferred (a play \
             operator); a light motor that chatters against the load within one encoder count \
             leaves that above the floor whatever the fit. A load-side encoder \
             (`--load-output COL`) measures the deflection instead (docs/workbench.md, \
             *Record*).",
        );
    }
    s.push('\n');
    Some(s)
}

/// Run `fit`.
pub fn fit(a: FitArgs) -> anyhow::Result<()> {
    let save = model_path(a.save_model.as_ref(), "fitted-model");
    let (p, resampled) = a.data.recording()?;
    let mut model = match a.data.model_file()? {
        Some(f) => Model::load(f)?,
        None => Model::baseline(),
    };
    model
        .on_axis(p.axis, &p.input_unit)
        .context(a.data.csv()?.display().to_string())?;
    let kind = match &a.add {
        Some(n) => {
            let k = jointlab_workbench::names::effect(n)?;
            if model.has(k) {
                bail!("the model already contains `{n}`");
            }
            Some(k)
        }
        None => None,
    };
    let val = match a.data.validate_file(a.validate.as_ref())? {
        Some(f) => Some(a.data.validation(&f, p.cutoff_hz)?),
        None => None,
    };
    // A model file's own values, scored before `fit` refits them: "before" is the model
    // refitted on this record (the best it does without the new effect), which is not what
    // `compare --model` printed for a model fitted on another record.
    let as_given = a.data.model_file()?.map(|_| AsGiven {
        estimation: refine::score(&model, &p),
        validation: val.as_ref().map(|v| refine::score(&model, v)),
    });
    let r = refine::fit_add(&mut model, &p, kind, val.as_ref())?;
    model.save(&save)?;
    let extrapolated = refine::extrapolation_notes(&model, &p, val.as_ref());
    if a.json {
        let mut j = serde_json::json!({
            "report": r,
            "as_given": as_given,
            "model_file": save,
            "resampled": resampled,
            "notes": extrapolated,
        });
        schema::stamp(&mut j, &a.data.units()?);
        println!("{j}");
    } else {
        if let Some(g) = as_given.as_ref().and_then(|g| g.text(&r)) {
            print!("{g}");
        }
        print!("{}", fit_text(&r));
        for n in &extrapolated {
            println!("note: {n}");
        }
        for (q, (lo, hi)) in model.params().iter().zip(model.fit_bounds()) {
            let at = lo
                .filter(|lo| q.value <= *lo)
                .or(hi.filter(|hi| q.value >= *hi));
            if let Some(b) = at.filter(|_| q.free && q.sigma.is_none()) {
                let why = if q.bound_reached().is_some() {
                    "the model file's min/max"
                } else {
                    "its physical range"
                };
                println!(
                    "note: {} is held at its bound {b:e} ({why}): the fit would take it \
                     beyond, so it has no 1σ",
                    q.name
                );
            }
        }
        println!("model written to {}", save.display());
        if let Some(n) = fit_advice(&r, !p.load_position.is_empty(), &save) {
            print!("{n}");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointlab_workbench::refine::Score;

    fn score(rms: f64) -> Score {
        Score {
            fit_percent: 100.0 - rms,
            rms,
            relative_error_percent: rms,
            noise_floor_rms: 1.0,
        }
    }

    fn report(est: (f64, f64), val: (f64, f64)) -> FitReport {
        FitReport {
            added: Some(EffectKind::Stribeck),
            before: score(est.0),
            after: score(est.1),
            before_validation: Some(score(val.0)),
            after_validation: Some(score(val.1)),
            params: Vec::new(),
        }
    }

    /// `fit` points at `diagnose` only while the error is above its floor, and at a
    /// load-side encoder only for backlash fitted without one.
    #[test]
    fn fit_advice_follows_the_floor_and_the_encoders() {
        let f = Path::new("m.toml");
        assert!(fit_advice(&report((2.0, 1.1), (2.0, 1.1)), false, f).is_none());
        let n = fit_advice(&report((2.0, 1.5), (2.0, 1.5)), false, f).expect("above the floor");
        assert!(
            n.contains("1.50× its noise floor") && n.contains("diagnose --model m.toml"),
            "{n}"
        );
        assert!(!n.contains("--load-output"), "{n}");
        let mut b = report((2.0, 1.8), (2.0, 1.8));
        b.added = Some(EffectKind::Backlash);
        let n = fit_advice(&b, false, f).expect("above the floor");
        assert!(n.contains("--load-output"), "{n}");
        let n = fit_advice(&b, true, f).expect("above the floor");
        assert!(!n.contains("--load-output"), "{n}");
        let t = fit_text(&b);
        assert!(t.contains("(2.00 → 1.80× the noise floor)"), "{t}");
    }

    /// A model file's own values get a line only when they score differently from the
    /// refitted "before" (on either record).
    #[test]
    fn as_given_line_only_when_the_file_differs_from_its_refit() {
        let r = report((2.0, 1.0), (3.0, 1.5));
        let same = AsGiven {
            estimation: score(2.0),
            validation: Some(score(3.0)),
        };
        assert!(same.text(&r).is_none());
        let other = AsGiven {
            estimation: score(2.0),
            validation: Some(score(4.0)),
        };
        let t = other.text(&r).expect("validation differs");
        assert!(
            t.contains("estimation fit 98.000 %") && t.contains("validation fit 96.000 %"),
            "{t}"
        );
        let est_only = AsGiven {
            estimation: score(2.5),
            validation: None,
        };
        assert!(est_only.text(&r).is_some());
    }

    /// Each `--auto` row's multiple is against its own model's floor — the number `diagnose`
    /// prints for that model — even where the floor moved more than the RMS.
    #[test]
    fn auto_rows_use_their_own_floor() {
        let step = |k: usize, rms: f64, floor: f64| AutoStep {
            step: k,
            added: (k > 0).then(|| "coulomb".to_string()),
            replaced: None,
            score: Score {
                fit_percent: 90.0,
                rms,
                relative_error_percent: rms,
                noise_floor_rms: floor,
            },
            validation: None,
            chosen_over: None,
            p_value: None,
            verdict: String::new(),
        };
        let t = auto_text(&[step(0, 4.0, 2.0), step(1, 3.0, 1.0)]);
        let ratio = |row: usize| -> f64 {
            let line = t.lines().nth(row + 1).expect("row");
            line.split_whitespace()
                .nth(4)
                .and_then(|x| x.parse().ok())
                .expect("×floor")
        };
        assert_eq!((ratio(0), ratio(1)), (2.0, 3.0), "{t}");
    }

    /// A refit that lowers the estimation error but raises the validation error says so;
    /// one that lowers both does not.
    #[test]
    fn fit_text_flags_a_refit_that_does_not_carry_to_validation() {
        let t = fit_text(&report((2.0, 1.0), (2.0, 2.5)));
        assert!(t.contains("validation error rose (25.0 % in RMS)"), "{t}");
        let t = fit_text(&report((2.0, 1.0), (2.0, 1.5)));
        assert!(!t.contains("validation error rose"), "{t}");
    }
}
