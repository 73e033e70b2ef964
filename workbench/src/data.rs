//! CSV recordings: column selection, units from the column-name suffix, and errors that say
//! which file, line and column is wrong.
//!
//! A recording is any CSV with a header row. Columns are picked by name; a suffix such as
//! `_s`, `_ms`, `_m`, `_mm`, `_rad`, `_deg`, `_N`, `_Nm`, `_V`, `_rad_s` gives the unit and,
//! where the unit is not SI, the factor that converts it (`_deg` → rad, `_mm` → m, `_ms` → s);
//! a unit-like suffix that is not known is refused ([`crate::units`] holds the table and the
//! rule). HIL recordings are named from the same table, so they load directly.
//!
//! Arrays (the Python package's numpy columns) come in through [`Recording::from_arrays`]:
//! the CSV loader and it hand their columns to one constructor, so a record gets the same
//! checks, window, resampling and noise statistics whichever way it arrived.

use crate::units::{unit_of, UnknownUnit};
use sim_plant::effects::Intersample;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// What went wrong while loading a recording. Every variant names the file, and where it can,
/// the 1-based line (the header is line 1) and the column. A recording built from arrays
/// ([`Recording::from_arrays`]) is named [`ARRAYS`] and its "line" is the 0-based index into
/// the arrays.
#[derive(Debug, Error)]
pub enum DataError {
    /// An array passed to [`Recording::from_arrays`] is not as long as the time array.
    #[error("{file}: `{column}` holds {len} values, `{time}` {expected}: every array needs one value per sample")]
    ArrayLength {
        /// [`ARRAYS`].
        file: PathBuf,
        /// The array's name (its column name in [`Columns`]).
        column: String,
        /// Its length.
        len: usize,
        /// The time array's name.
        time: String,
        /// The time array's length.
        expected: usize,
    },
    /// [`Columns`] names an optional column (`load_output`, `input_times`) that no array was
    /// given for, or an array was given that [`Columns`] does not name.
    #[error("{file}: {what}")]
    ArrayMissing {
        /// [`ARRAYS`].
        file: PathBuf,
        /// Which array, and which way round.
        what: String,
    },
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File.
        file: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A requested column is not in the header.
    #[error("{file}:1: no column `{column}` in the header{hint} (have: {have})")]
    MissingColumn {
        /// File.
        file: PathBuf,
        /// Requested column.
        column: String,
        /// ` (did you mean …?)` when a header name is a near miss, else empty.
        hint: String,
        /// Columns present.
        have: String,
    },
    /// No column was named for a role and the header does not settle which one it is.
    #[error("{file}:1: no {role} column named, and {why}; name it (--{role} COLUMN, or `{role} = \"COLUMN\"` in a dataset file)")]
    Undetected {
        /// File.
        file: PathBuf,
        /// `time`, `input` or `output`.
        role: &'static str,
        /// What the header offered.
        why: String,
    },
    /// A selected column's name ends in a unit-like suffix the table does not know.
    #[error("{file}:1: {source}")]
    UnknownUnit {
        /// File.
        file: PathBuf,
        /// The column and its suffix.
        source: UnknownUnit,
    },
    /// A cell does not parse as a number.
    #[error("{file}:{line}: column `{column}`: `{cell}` is not a number")]
    NotNumeric {
        /// File.
        file: PathBuf,
        /// Line.
        line: u64,
        /// Column.
        column: String,
        /// Offending text.
        cell: String,
    },
    /// A cell is NaN or infinite.
    #[error("{file}:{line}: column `{column}`: value is {value} (NaN/inf not allowed)")]
    NotFinite {
        /// File.
        file: PathBuf,
        /// Line.
        line: u64,
        /// Column.
        column: String,
        /// Value.
        value: f64,
    },
    /// A value is finite in the file but out of scale once converted: not finite after its
    /// unit factor, `--input-gain`, `--input-times` or `--load-gain` (an overflowing
    /// product), or so large that the column's sum of squares — which every fit forms —
    /// overflows double precision.
    #[error(
        "{file}:{line}: column `{column}`: {value:e} after {after} is out of range: {why} \
         (a cell out of scale, or a wrong gain)"
    )]
    OutOfRange {
        /// File.
        file: PathBuf,
        /// Line of the largest value.
        line: u64,
        /// Column.
        column: String,
        /// The value after scaling.
        value: f64,
        /// What scaled it (`its unit`, `--input-gain 1e308`, …).
        after: String,
        /// Not finite, or its square overflows.
        why: &'static str,
    },
    /// A differentiated or filtered signal is out of range (see [`DataError::OutOfRange`]).
    #[error(
        "{file}: the {signal} at t = {time} s is {value:e}: {why} (the position or input \
         jumps by an amount out of scale near there)"
    )]
    Derived {
        /// File.
        file: PathBuf,
        /// Which signal (`velocity after differentiation`, …).
        signal: &'static str,
        /// Time of the largest value (s).
        time: f64,
        /// Its value.
        value: f64,
        /// Not finite, or its square overflows.
        why: &'static str,
    },
    /// A noise statistic of the record (what the significance tests measure a residual
    /// against) is not finite: the differences of the values overflow even where the values
    /// and their derivatives do not.
    #[error(
        "{file}: the {statistic} is {value:e}: the position or input jumps by an amount out of \
         scale (a cell out of scale, or a wrong unit or gain)"
    )]
    Noise {
        /// File.
        file: PathBuf,
        /// Which statistic (`acceleration noise variance`, …).
        statistic: &'static str,
        /// Its value.
        value: f64,
    },
    /// The sample interval is not uniform (a gap, or a jump in the clock).
    #[error(
        "{file}:{line}: column `{column}`: the sample interval {step} s is far from the \
         record's {median} s (over 3× or under a third: a gap or a jump in time); jitter is \
         interpolated away, a gap is not — split the record at the gap"
    )]
    UnevenSampling {
        /// File.
        file: PathBuf,
        /// Line of the sample after the odd interval.
        line: u64,
        /// Time column.
        column: String,
        /// The odd interval (s).
        step: f64,
        /// The record's median interval (s).
        median: f64,
    },
    /// A column holds one value throughout: there is no excitation (or no motion) to fit.
    #[error(
        "{file}: column `{column}` is {value} on every row (after --input-gain and \
         --input-times): nothing moves or drives the joint, so there is nothing to fit"
    )]
    Constant {
        /// File.
        file: PathBuf,
        /// Column.
        column: String,
        /// Its one value.
        value: f64,
    },
    /// Time does not strictly increase.
    #[error("{file}:{line}: column `{column}`: time {value} does not increase (previous {prev})")]
    NonMonotonicTime {
        /// File.
        file: PathBuf,
        /// Line.
        line: u64,
        /// Column.
        column: String,
        /// Value.
        value: f64,
        /// Previous value.
        prev: f64,
    },
    /// A row is malformed (wrong number of fields, bad quoting).
    #[error("{file}:{line}: malformed row: {msg}")]
    Malformed {
        /// File.
        file: PathBuf,
        /// Line.
        line: u64,
        /// Message.
        msg: String,
    },
    /// The `--from`/`--to` window ends where or before it starts.
    #[error("{file}: --from {from} --to {to}: the window must start before it ends")]
    ReversedWindow {
        /// File.
        file: PathBuf,
        /// Window start (s).
        from: f64,
        /// Window end (s).
        to: f64,
    },
    /// The `--from`/`--to` window holds too few rows.
    #[error(
        "{file}: --from {from} --to {to} (s) holds {rows} rows of a record spanning \
         {first:.4}–{last:.4} s; need at least {need}"
    )]
    Window {
        /// File.
        file: PathBuf,
        /// Window start (s).
        from: f64,
        /// Window end (s).
        to: f64,
        /// Rows inside it.
        rows: usize,
        /// The record's first time (s).
        first: f64,
        /// The record's last time (s).
        last: f64,
        /// Needed.
        need: usize,
    },
    /// Too few rows to do anything.
    #[error("{file}: only {rows} data rows; need at least {need}")]
    TooShort {
        /// File.
        file: PathBuf,
        /// Rows.
        rows: usize,
        /// Needed.
        need: usize,
    },
}

/// Which columns to use and how to scale the input.
#[derive(Debug, Clone)]
pub struct Columns {
    /// Input (applied force/torque or a command proportional to it).
    pub input: String,
    /// Measured output position (motor side).
    pub output: String,
    /// Optional load-side position.
    pub load_output: Option<String>,
    /// Time column.
    pub time: String,
    /// Gain applied to the input column (e.g. the drive gain `gtau` in N/V), so the model sees
    /// a force/torque.
    pub input_gain: f64,
    /// A second column the input is multiplied by, row by row, before the gain: the measured
    /// supply voltage for a drive that logs its PWM duty (duty × volts = the applied voltage).
    pub input_times: Option<String>,
    /// Only the rows whose time (s, after the unit suffix) lies in `[from, to]`: a segment of a
    /// record (the drive-on part of a log that switches it off; an estimation half). `None` =
    /// every row.
    pub window: Option<(f64, f64)>,
    /// Gain from the load column to the output column's axis: the gear ratio N when the load
    /// encoder sits at the output and the output column is the motor shaft. The deflection
    /// motor − load is only meaningful with both on one axis.
    pub load_gain: f64,
    /// What the input did between its samples relative to when the position was sampled
    /// (default: zero-order hold, how a drive logs; see `sim_plant::effects::Intersample`).
    pub intersample: Intersample,
    /// Turns of the output (position) column per turn of the joint's output: a gear's ratio N
    /// when the column is the motor shaft (gravity then acts on position/N); 1 by default.
    pub gear_ratio: f64,
    /// The input's unit after `input_gain` (`N` for EMPS's volts × 35.15 N/V), as reports
    /// label it; `None` labels it from the column's suffix and the gain ([`input_unit`]).
    pub input_unit: Option<String>,
}

impl Columns {
    /// Input/output by name, time `time_s`, unit gain.
    pub fn new(input: &str, output: &str) -> Self {
        Columns {
            input: input.into(),
            output: output.into(),
            load_output: None,
            time: "time_s".into(),
            input_gain: 1.0,
            input_times: None,
            window: None,
            load_gain: 1.0,
            intersample: Intersample::default(),
            gear_ratio: 1.0,
            input_unit: None,
        }
    }

    /// The same columns with another intersample behaviour.
    pub fn with_intersample(mut self, intersample: Intersample) -> Self {
        self.intersample = intersample;
        self
    }
}

/// A loaded recording, in SI units.
#[derive(Debug, Clone)]
pub struct Recording {
    /// Where it came from.
    pub path: PathBuf,
    /// Time (s).
    pub time: Vec<f64>,
    /// Input (after `input_gain` and unit conversion).
    pub input: Vec<f64>,
    /// Output position.
    pub output: Vec<f64>,
    /// Load-side position, if requested.
    pub load_output: Option<Vec<f64>>,
    /// Mean sample period (s).
    pub dt: f64,
    /// Units (input, output).
    pub units: (String, String),
    /// Column names, for reports.
    pub columns: Columns,
    /// How the record's irregular clock was made uniform, if it was (see [`Resampled`]).
    pub resampled: Option<Resampled>,
    /// The columns as recorded when the record was resampled (`None` otherwise: they are
    /// `input`, `output` and `load_output` themselves).
    pub recorded: Option<Recorded>,
}

/// A record whose sample intervals vary (a host polling a drive: the XL330 servo logs in
/// `../shared/data/real` step 3.4–7.1 ms around a 5.3 ms median) is put on a uniform clock
/// before anything differentiates it: the differentiator and every fingerprint assume one
/// sample period, and a 15 % longer interval read as the nominal one is a 15 % error in that
/// sample's velocity. Every column is interpolated linearly onto `t0 + k·dt`, k = 0 … N − 1,
/// with the record's own N and mean interval dt, so no samples are invented or dropped.
///
/// Interpolation averages neighbouring samples, which hides both the encoder's step and the
/// noise: the columns *as recorded* are kept ([`Recorded`]) and the noise statistics (the
/// quantisation step, the position's and the input's noise) are taken from them. A record
/// logged at two rates (the XL330's `lift_and_drop`: 5.3 ms with the drive on, 4 ms off) is
/// put on its mean interval without an anti-alias filter, so its faster part is decimated.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Resampled {
    /// Shortest interval in the file (s).
    #[serde(rename = "min_step_s")]
    pub min_step: f64,
    /// Longest interval in the file (s).
    #[serde(rename = "max_step_s")]
    pub max_step: f64,
    /// Median interval in the file (s).
    #[serde(rename = "median_step_s")]
    pub median_step: f64,
    /// The uniform interval now (s): the mean of the file's.
    #[serde(rename = "dt_s")]
    pub dt: f64,
}

/// The input, output and load columns as the file held them, on its own (irregular) clock,
/// in SI units: kept beside a [`Resampled`] record for its noise statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    /// Input.
    pub input: Vec<f64>,
    /// Output position.
    pub output: Vec<f64>,
    /// Load-side position, if requested.
    pub load_output: Option<Vec<f64>>,
}

impl Resampled {
    /// Largest relative departure of an interval from the mean that still counts as uniform
    /// (a clock's rounding; a 1 kHz record written with 9 digits departs by < 10⁻⁵).
    pub const TOLERANCE: f64 = 1e-3;

    /// The one-line note the commands print.
    pub fn note(&self, file: &Path) -> String {
        format!(
            "note: {}: the sample interval varies ({:.3}–{:.3} ms, median {:.3} ms); every \
             column was interpolated linearly onto a uniform {:.4} ms clock",
            file.display(),
            1e3 * self.min_step,
            1e3 * self.max_step,
            1e3 * self.median_step,
            1e3 * self.dt
        )
    }
}

/// `x`, sampled at the increasing times `t`, linearly interpolated at `t[0] + k·dt` for
/// k = 0 … len − 1 (the last point is clamped onto the last sample against rounding).
fn interpolate_uniform(t: &[f64], x: &[f64], dt: f64) -> Vec<f64> {
    let mut j = 0;
    (0..t.len())
        .map(|k| {
            let tk = (t[0] + k as f64 * dt).min(t[t.len() - 1]);
            while j + 2 < t.len() && t[j + 1] <= tk {
                j += 1;
            }
            let w = ((tk - t[j]) / (t[j + 1] - t[j])).clamp(0.0, 1.0);
            x[j] + w * (x[j + 1] - x[j])
        })
        .collect()
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }
}

/// The input's unit as recordings and reports label it: the column's suffix unit, times
/// `--input-gain` when there is one (`V×35.15…` for EMPS). With `--input-times` the unit is
/// the product's (a unitless duty times a `_V` column reads `V`). A name [`load`] would refuse
/// for its suffix reads as unitless here.
pub fn input_unit(cols: &Columns) -> String {
    if let Some(u) = &cols.input_unit {
        return u.clone();
    }
    let label = |c: &str| unit_of(c).map_or("", |u| u.0);
    let base = label(&cols.input);
    let u = match cols.input_times.as_deref().map(label) {
        None | Some("") => base.to_string(),
        Some(t) if base.is_empty() => t.to_string(),
        Some(t) => format!("{base}·{t}"),
    };
    if cols.input_gain != 1.0 {
        format!("{u}×{}", crate::units::eng(cols.input_gain))
    } else {
        u.to_string()
    }
}

/// Where a signal is out of range for a fit, if it is: the index of its first non-finite
/// value, or of its largest value when its sum of squares overflows; with the reason.
pub fn out_of_range(x: &[f64]) -> Option<(usize, &'static str)> {
    if let Some(k) = x.iter().position(|v| !v.is_finite()) {
        return Some((k, "not finite"));
    }
    let energy: f64 = x.iter().map(|v| v * v).sum();
    if energy.is_finite() {
        return None;
    }
    let k = (0..x.len()).max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()))?;
    Some((k, "its square overflows double precision"))
}

/// Fewest rows a recording (or its `--from/--to` window) may hold: below it the
/// differentiator's trimmed edges leave too little to fit.
const MIN_ROWS: usize = 50;

/// The file label of a recording built from arrays ([`Recording::from_arrays`]).
pub const ARRAYS: &str = "<arrays>";

/// The columns a recording reads, in the order [`build`] takes them: time, input, output,
/// then the load column and the `input_times` column when `cols` names them.
fn column_names(cols: &Columns) -> Vec<&str> {
    let mut names = vec![
        cols.time.as_str(),
        cols.input.as_str(),
        cols.output.as_str(),
    ];
    names.extend(cols.load_output.as_deref());
    names.extend(cols.input_times.as_deref());
    names
}

/// The arrays of a recording that is already in memory, as a CSV's columns would hold them:
/// raw numbers, converted by the unit suffix of their name in [`Columns`] and by its gains.
#[derive(Debug, Clone, Copy)]
pub struct Arrays<'a> {
    /// Time (named by [`Columns::time`]).
    pub time: &'a [f64],
    /// Input ([`Columns::input`]).
    pub input: &'a [f64],
    /// Output position ([`Columns::output`]).
    pub output: &'a [f64],
    /// Load-side position ([`Columns::load_output`]), if any.
    pub load_output: Option<&'a [f64]>,
    /// The input's row-by-row factor ([`Columns::input_times`]), if any.
    pub input_times: Option<&'a [f64]>,
}

impl Recording {
    /// A recording from arrays, with every check, the window, the resampling and the noise
    /// statistics of [`load`]: both go through one constructor. `cols` names the arrays (for
    /// reports, errors and the units of their suffixes) and carries the gains, window and
    /// intersample behaviour. Errors name [`ARRAYS`], the array and its 0-based index.
    pub fn from_arrays(arrays: Arrays<'_>, cols: &Columns) -> Result<Recording, DataError> {
        let file = PathBuf::from(ARRAYS);
        let pairs = [
            ("load_output", &cols.load_output, arrays.load_output),
            ("input_times", &cols.input_times, arrays.input_times),
        ];
        for (field, name, array) in pairs {
            let what = match (name, array) {
                (Some(n), None) => format!("Columns::{field} names `{n}` but no array was given"),
                (None, Some(_)) => {
                    format!("an array was given for {field} but Columns::{field} names none")
                }
                _ => continue,
            };
            return Err(DataError::ArrayMissing { file, what });
        }
        let given = [arrays.time, arrays.input, arrays.output]
            .into_iter()
            .chain(arrays.load_output)
            .chain(arrays.input_times);
        let names = column_names(cols);
        let units = column_units(&file, &names)?;
        let mut raw = Vec::with_capacity(names.len());
        for (name, x) in names.iter().zip(given) {
            if x.len() != arrays.time.len() {
                return Err(DataError::ArrayLength {
                    file,
                    column: (*name).into(),
                    len: x.len(),
                    time: cols.time.clone(),
                    expected: arrays.time.len(),
                });
            }
            for (k, &v) in x.iter().enumerate() {
                finite(&file, k as u64, name, v)?;
            }
            raw.push(x.to_vec());
        }
        build(
            file,
            raw,
            (0..arrays.time.len() as u64).collect(),
            &units,
            cols,
        )
    }
}

/// Load a recording. Rejects missing columns, non-numeric cells, NaN/inf and non-increasing
/// time with the file, line and column in the message.
pub fn load(path: &Path, cols: &Columns) -> Result<Recording, DataError> {
    load_bytes(&read_file(path)?, path, cols)
}

/// [`load`] on CSV text already in memory; `path` names it in errors and in the recording.
/// The one parser behind [`load`], callable without a file (the fuzz target feeds it).
pub fn load_bytes(text: &[u8], path: &Path, cols: &Columns) -> Result<Recording, DataError> {
    let names = column_names(cols);
    let units = column_units(path, &names)?;
    let (raw, lines) = parse_numeric(text, path, &names)?;
    build(path.to_path_buf(), raw, lines, &units, cols)
}

/// Every selected column's unit and SI factor, in [`column_names`] order, before any value
/// is read: a unit-like suffix the table does not know is refused rather than read at a
/// factor of 1.
fn column_units(file: &Path, names: &[&str]) -> Result<Vec<(&'static str, f64)>, DataError> {
    names
        .iter()
        .map(|c| unit_of(c))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|source| DataError::UnknownUnit {
            file: file.to_path_buf(),
            source,
        })
}

/// The one constructor of a [`Recording`]: `raw` holds the finite columns of
/// [`column_names`] as recorded, `lines` where each row came from (for errors), `units`
/// their [`column_units`]. Units, gains, the range checks after scaling, the time checks,
/// the window, the sampling checks and the resampling happen here.
fn build(
    file: PathBuf,
    raw: Vec<Vec<f64>>,
    lines: Vec<u64>,
    units: &[(&'static str, f64)],
    cols: &Columns,
) -> Result<Recording, DataError> {
    let times_at = cols
        .input_times
        .as_ref()
        .map(|_| 3 + usize::from(cols.load_output.is_some()));
    let factor = |k: usize| units.get(k).map_or(1.0, |u| u.1);
    let ts = factor(0);
    let us = factor(1);
    let (yu, ys) = units.get(2).copied().unwrap_or(("", 1.0));
    let scale = |k: usize, f: f64| -> Vec<f64> {
        raw.get(k)
            .map(|c| c.iter().map(|v| v * f).collect())
            .unwrap_or_default()
    };
    let time = scale(0, ts);
    for (k, w) in time.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(DataError::NonMonotonicTime {
                file,
                line: lines.get(k + 1).copied().unwrap_or(0),
                column: cols.time.clone(),
                value: w[1],
                prev: w[0],
            });
        }
    }
    let mut input = scale(1, us * cols.input_gain);
    if let Some(k) = times_at {
        for (u, m) in input.iter_mut().zip(scale(k, factor(k))) {
            *u *= m;
        }
    }
    let output = scale(2, ys);
    let load_out = cols
        .load_output
        .as_deref()
        .map(|_| scale(3, factor(3) * cols.load_gain));
    // Every cell is finite (`parse_numeric`); what the scaling made of it is checked here.
    let mut input_by = String::from("its unit");
    if cols.input_gain != 1.0 {
        input_by = format!("--input-gain {:?}", cols.input_gain);
    }
    if let Some(c) = &cols.input_times {
        input_by.push_str(&format!(" and --input-times {c}"));
    }
    let scaled = [
        (&cols.input, Some(&input), input_by),
        (&cols.output, Some(&output), "its unit".to_string()),
        (
            cols.load_output.as_ref().unwrap_or(&cols.output),
            load_out.as_ref(),
            format!("--load-gain {:?}", cols.load_gain),
        ),
    ];
    for (column, x, after) in scaled {
        let Some(x) = x else { continue };
        if let Some((k, why)) = out_of_range(x) {
            return Err(DataError::OutOfRange {
                file,
                line: lines.get(k).copied().unwrap_or(0),
                column: column.clone(),
                value: x[k],
                after,
                why,
            });
        }
    }
    // The window: time increases, so its rows are one contiguous run.
    let (time, input, output, load_out, lines) = match cols.window {
        Some((from, to)) => {
            if from >= to {
                return Err(DataError::ReversedWindow { file, from, to });
            }
            let i0 = time.partition_point(|&t| t < from);
            let i1 = time.partition_point(|&t| t <= to).max(i0);
            if i1 - i0 < MIN_ROWS {
                return Err(DataError::Window {
                    file,
                    from,
                    to,
                    rows: i1 - i0,
                    first: time.first().copied().unwrap_or(f64::NAN),
                    last: time.last().copied().unwrap_or(f64::NAN),
                    need: MIN_ROWS,
                });
            }
            let cut = |x: Vec<f64>| x[i0..i1].to_vec();
            (
                cut(time),
                cut(input),
                cut(output),
                load_out.map(cut),
                lines[i0..i1].to_vec(),
            )
        }
        None => (time, input, output, load_out, lines),
    };
    if time.len() < MIN_ROWS {
        return Err(DataError::TooShort {
            file,
            rows: time.len(),
            need: MIN_ROWS,
        });
    }
    // Uniform sampling: the differentiator and every fingerprint assume one sample period,
    // so a gap (dropped rows) or a jump in the clock would silently bend the fit. Jitter is
    // interpolated away below (the XL330 servo records in ../shared/data/real reach 1.74×
    // their median interval, logged at two rates; see `Resampled`); an interval over 3× the
    // median is a gap that interpolation would bridge with a straight line, and is refused.
    let mut gaps: Vec<f64> = time.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort_by(|a, b| a.total_cmp(b));
    let median = gaps.get(gaps.len() / 2).copied().unwrap_or(0.0);
    for (k, w) in time.windows(2).enumerate() {
        let step = w[1] - w[0];
        if !(median / 3.0..=3.0 * median).contains(&step) {
            return Err(DataError::UnevenSampling {
                file,
                line: lines.get(k + 1).copied().unwrap_or(0),
                column: cols.time.clone(),
                step,
                median,
            });
        }
    }
    for (column, x) in [(&cols.input, &input), (&cols.output, &output)] {
        if x.iter().all(|v| *v == x[0]) {
            return Err(DataError::Constant {
                file,
                column: column.clone(),
                value: x[0],
            });
        }
    }
    let dt = (time[time.len() - 1] - time[0]) / (time.len() - 1) as f64;
    let (min_step, max_step) = (gaps[0], gaps[gaps.len() - 1]);
    let resampled =
        ((max_step - dt).max(dt - min_step) > Resampled::TOLERANCE * dt).then_some(Resampled {
            min_step,
            max_step,
            median_step: median,
            dt,
        });
    let (time, input, output, load_out, recorded) = if resampled.is_some() {
        let on_clock = |x: &[f64]| interpolate_uniform(&time, x, dt);
        (
            (0..time.len()).map(|k| time[0] + k as f64 * dt).collect(),
            on_clock(&input),
            on_clock(&output),
            load_out.as_deref().map(on_clock),
            Some(Recorded {
                input,
                output,
                load_output: load_out,
            }),
        )
    } else {
        (time, input, output, load_out, None)
    };
    Ok(Recording {
        path: file,
        time,
        input,
        output,
        load_output: load_out,
        dt,
        units: (input_unit(cols), yu.to_string()),
        columns: cols.clone(),
        resampled,
        recorded,
    })
}

/// Load named columns as raw numbers (no unit conversion, no resampling), with the same
/// error checks. For extra signals a command needs beside input/output (a reference, a pulse
/// train).
pub fn load_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, DataError> {
    parse_numeric(&read_file(path)?, path, names).map(|(cols, _)| cols)
}

/// `v` of `column` at `line` of `file`, refused if NaN or infinite: the one finiteness check
/// of CSV cells and arrays.
fn finite(file: &Path, line: u64, column: &str, v: f64) -> Result<(), DataError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(DataError::NotFinite {
            file: file.to_path_buf(),
            line,
            column: column.into(),
            value: v,
        })
    }
}

fn read_file(path: &Path) -> Result<Vec<u8>, DataError> {
    std::fs::read(path).map_err(|source| DataError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// The header row of the CSV at `path`: its column names, trimmed.
pub fn header(path: &Path) -> Result<Vec<String>, DataError> {
    header_bytes(&read_file(path)?, path)
}

/// [`header`] of CSV text in memory.
pub fn header_bytes(text: &[u8], path: &Path) -> Result<Vec<String>, DataError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(text);
    Ok(rdr
        .headers()
        .map_err(|e| DataError::Malformed {
            file: path.to_path_buf(),
            line: 1,
            msg: e.to_string(),
        })?
        .iter()
        .map(|s| s.to_string())
        .collect())
}

/// Time-column names tried, in this order, when none is named.
pub const TIME_NAMES: &[&str] = &["time_s", "t_s", "time", "t", "time_ms", "t_ms"];

/// A column [`detect`] finds from the header when the caller names none.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The clock: the first of [`TIME_NAMES`] present.
    Time,
    /// The input: the one column whose suffix is a force or torque (`_N`, `_Nm`).
    Input,
    /// The output: the one column whose suffix is a position (`_rad`, `_deg`, `_m`, `_mm`).
    Output,
}

impl Role {
    /// The role's name in flags and dataset files.
    pub const fn name(self) -> &'static str {
        match self {
            Role::Time => "time",
            Role::Input => "input",
            Role::Output => "output",
        }
    }
    /// The SI units a column in this role may carry (from its suffix).
    const fn units(self) -> &'static [&'static str] {
        match self {
            Role::Time => &["s"],
            Role::Input => &["N", "N·m"],
            Role::Output => &["m", "rad"],
        }
    }
}

/// The column of `header` that plays `role`, when the header settles it: a recording whose
/// names carry the unit suffixes (`time_s, torque_Nm, q_rad`) needs no column flags. Several
/// candidates, or none, is an error that lists what there is.
pub fn detect(file: &Path, header: &[String], role: Role) -> Result<String, DataError> {
    let undetected = |why: String| DataError::Undetected {
        file: file.to_path_buf(),
        role: role.name(),
        why,
    };
    if role == Role::Time {
        return TIME_NAMES
            .iter()
            .find(|n| header.iter().any(|h| h == *n))
            .map(|n| (*n).to_string())
            .ok_or_else(|| {
                undetected(format!(
                    "the header has none of {}{}",
                    TIME_NAMES.join(", "),
                    crate::names::did_you_mean("time_s", header.iter().map(String::as_str))
                ))
            });
    }
    let fits: Vec<&String> = header
        .iter()
        .filter(|h| unit_of(h).is_ok_and(|(u, _)| role.units().contains(&u)))
        .collect();
    match fits.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(undetected(format!(
            "no column has a {} unit suffix (have: {})",
            role.units().join(" or "),
            header.join(", ")
        ))),
        many => Err(undetected(format!(
            "{} columns could be it: {}",
            many.len(),
            many.iter()
                .map(|h| h.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// The named columns as finite numbers, with the CSV line of each row (for later errors).
/// A missing column, a cell that is not a number, NaN or inf is an error naming the file,
/// the line and the column.
fn parse_numeric(
    text: &[u8],
    path: &Path,
    names: &[&str],
) -> Result<(Vec<Vec<f64>>, Vec<u64>), DataError> {
    let file = path.to_path_buf();
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(text);
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| DataError::Malformed {
            file: file.clone(),
            line: 1,
            msg: e.to_string(),
        })?
        .iter()
        .map(|s| s.to_string())
        .collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .ok_or_else(|| DataError::MissingColumn {
                    file: file.clone(),
                    column: (*n).into(),
                    hint: crate::names::did_you_mean(n, header.iter().map(String::as_str)),
                    have: header.join(", "),
                })
        })
        .collect::<Result<_, _>>()?;
    let mut out = vec![Vec::new(); names.len()];
    let mut lines = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| DataError::Malformed {
            file: file.clone(),
            line: e.position().map(|p| p.line()).unwrap_or(0),
            msg: e.to_string(),
        })?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        for ((&i, name), col) in idx.iter().zip(names).zip(out.iter_mut()) {
            let s = rec.get(i).unwrap_or("");
            let v: f64 = s.parse().map_err(|_| DataError::NotNumeric {
                file: file.clone(),
                line,
                column: (*name).into(),
                cell: s.into(),
            })?;
            finite(&file, line, name, v)?;
            col.push(v);
        }
        lines.push(line);
    }
    Ok((out, lines))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Write `csv` to a scratch file named `name`, load it with `cols`, remove the file.
    fn load_text(name: &str, csv: &str, cols: &Columns) -> Recording {
        let dir = std::env::temp_dir().join(format!("jointlab-data-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join(name);
        std::fs::write(&path, csv).expect("write csv");
        let rec = load(&path, cols).expect("load");
        std::fs::remove_dir_all(&dir).ok();
        rec
    }

    /// A geared load encoder is brought onto the output column's axis by `load_gain`, after
    /// its own unit suffix (degrees here), and the other columns are untouched.
    #[test]
    fn load_column_is_scaled_by_its_unit_and_the_load_gain() {
        let mut csv = String::from("time_s,torque_Nm,q_rad,out_deg\n");
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            csv += &format!("{t},{},{},{}\n", 0.5 + t, 30.0 * t, t.to_degrees());
        }
        let cols = Columns {
            load_output: Some("out_deg".into()),
            load_gain: 30.0,
            ..Columns::new("torque_Nm", "q_rad")
        };
        let rec = load_text("geared.csv", &csv, &cols);
        let load = rec.load_output.as_ref().expect("load column");
        for (k, (&q, &l)) in rec.output.iter().zip(load).enumerate() {
            assert!(
                (q - l).abs() < 1e-12,
                "sample {k}: motor {q} vs geared load {l}"
            );
        }
        assert!(rec.input.iter().zip(&rec.time).all(|(&u, &t)| u == 0.5 + t));
    }

    /// A host-polled clock (intervals 4–6.5 ms) is put on a uniform one: the same number of
    /// samples at the mean interval, and a signal linear in time is reproduced exactly at the
    /// new instants (linear interpolation is exact for it). A duty column times a volts
    /// column is the input, in volts.
    #[test]
    fn irregular_clock_is_resampled_and_input_times_multiplies() {
        let mut csv = String::from("t_s,duty,supply_V,q_rad\n");
        let mut t = 0.0;
        let mut times = Vec::new();
        for k in 0..80 {
            times.push(t);
            let volts = 7.0 + 0.01 * k as f64;
            csv += &format!("{t},{},{volts},{}\n", 0.5 - 0.001 * k as f64, 2.0 * t + 1.0);
            t += [4e-3, 6.5e-3, 5e-3, 5.5e-3][k % 4];
        }
        let cols = Columns {
            time: "t_s".into(),
            input_times: Some("supply_V".into()),
            ..Columns::new("duty", "q_rad")
        };
        let rec = load_text("polled.csv", &csv, &cols);
        let r = rec.resampled.expect("an irregular clock is resampled");
        assert!((r.min_step - 4e-3).abs() < 1e-12 && (r.max_step - 6.5e-3).abs() < 1e-12);
        let dt = (times[79] - times[0]) / 79.0;
        assert!((r.dt - dt).abs() < 1e-15 && (rec.dt - dt).abs() < 1e-15);
        assert_eq!(rec.len(), 80);
        for (k, (&tk, &q)) in rec.time.iter().zip(&rec.output).enumerate() {
            assert!((tk - k as f64 * dt).abs() < 1e-12, "sample {k}: t = {tk}");
            assert!((q - (2.0 * tk + 1.0)).abs() < 1e-12, "sample {k}: q = {q}");
        }
        // At the first and last instants (which stay put) the input is duty × volts.
        assert!((rec.input[0] - 0.5 * 7.0).abs() < 1e-12);
        assert!((rec.input[79] - (0.5 - 0.079) * 7.79).abs() < 1e-12);
        assert_eq!(rec.units.0, "V");
        let note = r.note(Path::new("polled.csv"));
        assert!(
            note.contains("polled.csv: the sample interval varies (4.000–6.500 ms"),
            "{note}"
        );
    }

    /// A clock that is uniform up to its digits is left alone (no resampling, no note).
    #[test]
    fn uniform_clock_is_not_resampled() {
        let mut csv = String::from("time_s,torque_Nm,q_rad\n");
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            csv += &format!("{t:.9},{},{}\n", (k % 7) as f64, (k * k) as f64 * 1e-4);
        }
        let rec = load_text("uniform.csv", &csv, &Columns::new("torque_Nm", "q_rad"));
        assert_eq!(rec.resampled, None);
        assert_eq!(rec.output[59], 59.0 * 59.0 * 1e-4);
    }

    /// `--from/--to` keep the rows whose time lies inside, inclusive; a reversed window, or one
    /// that holds too few rows, is an error naming the window (and the record's span).
    #[test]
    fn window_keeps_the_rows_inside_and_refuses_a_thin_one() {
        let mut csv = String::from("time_s,torque_Nm,q_rad\n");
        for k in 0..300 {
            let t = k as f64 * 1e-2;
            csv += &format!("{t},{},{}\n", (k % 5) as f64, t * t);
        }
        let within = |from: f64, to: f64| Columns {
            window: Some((from, to)),
            ..Columns::new("torque_Nm", "q_rad")
        };
        let rec = load_text("window.csv", &csv, &within(0.5, 1.5));
        assert_eq!(rec.len(), 101);
        assert!((rec.time[0] - 0.5).abs() < 1e-12 && (rec.time[100] - 1.5).abs() < 1e-12);
        assert!((rec.output[0] - 0.25).abs() < 1e-12);
        let dir = std::env::temp_dir().join(format!("jointlab-thin-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("thin.csv");
        std::fs::write(&path, &csv).expect("write csv");
        let reversed = load(&path, &within(2.0, 1.0))
            .expect_err("reversed")
            .to_string();
        assert!(reversed.contains("must start before it ends"), "{reversed}");
        let e = load(&path, &within(2.495, 2.805))
            .expect_err("31 rows")
            .to_string();
        std::fs::remove_dir_all(&dir).ok();
        assert!(
            e.contains("--from 2.495 --to 2.805 (s) holds 31 rows")
                && e.contains("0.0000–2.9900 s"),
            "{e}"
        );
    }
}
