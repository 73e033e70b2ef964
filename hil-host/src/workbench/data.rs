//! CSV recordings: column selection, units from the column-name suffix, and errors that say
//! which file, line and column is wrong.
//!
//! A recording is any CSV with a header row. Columns are picked by name; a suffix such as
//! `_s`, `_ms`, `_m`, `_mm`, `_rad`, `_deg`, `_N`, `_Nm`, `_V` gives the unit and, where the
//! unit is not SI, the factor that converts it (`_deg` → rad, `_mm` → m, `_ms` → s). HIL
//! recordings use the same convention, so they load directly.

use std::path::{Path, PathBuf};
use thiserror::Error;

/// What went wrong while loading a recording. Every variant names the file, and where it can,
/// the 1-based line (the header is line 1) and the column.
#[derive(Debug, Error)]
pub enum DataError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File.
        file: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A requested column is not in the header.
    #[error("{file}:1: no column `{column}` in the header (have: {have})")]
    MissingColumn {
        /// File.
        file: PathBuf,
        /// Requested column.
        column: String,
        /// Columns present.
        have: String,
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
    /// The sample interval is not uniform (a gap, or a jump in the clock).
    #[error(
        "{file}:{line}: column `{column}`: the sample interval {step} s is far from the \
         record's {median} s (over 3× or under a third: a gap or a jump in time); the \
         workbench needs uniform sampling — resample the record first"
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
        "{file}: column `{column}` is {value} on every row (after --input-gain): nothing moves \
         or drives the joint, so there is nothing to fit"
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

/// Unit and SI conversion factor read from a column-name suffix.
pub fn unit_of(column: &str) -> (&'static str, f64) {
    let suffix = column.rsplit_once('_').map(|(_, s)| s).unwrap_or("");
    match suffix {
        "s" => ("s", 1.0),
        "ms" => ("s", 1e-3),
        "us" => ("s", 1e-6),
        "m" => ("m", 1.0),
        "mm" => ("m", 1e-3),
        "rad" => ("rad", 1.0),
        "deg" => ("rad", std::f64::consts::PI / 180.0),
        "N" => ("N", 1.0),
        "Nm" => ("N·m", 1.0),
        "V" => ("V", 1.0),
        "A" => ("A", 1.0),
        "mps" => ("m/s", 1.0),
        "radps" => ("rad/s", 1.0),
        _ => ("", 1.0),
    }
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
    /// Gain from the load column to the output column's axis: the gear ratio N when the load
    /// encoder sits at the output and the output column is the motor shaft. The deflection
    /// motor − load is only meaningful with both on one axis.
    pub load_gain: f64,
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
            load_gain: 1.0,
        }
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
/// `--input-gain` when there is one (`V×35.15…` for EMPS).
pub fn input_unit(cols: &Columns) -> String {
    let u = unit_of(&cols.input).0;
    if cols.input_gain != 1.0 {
        format!("{u}×{}", cols.input_gain)
    } else {
        u.to_string()
    }
}

/// Load a recording. Rejects missing columns, non-numeric cells, NaN/inf and non-increasing
/// time with the file, line and column in the message.
pub fn load(path: &Path, cols: &Columns) -> Result<Recording, DataError> {
    let file = path.to_path_buf();
    let mut names = vec![
        cols.time.as_str(),
        cols.input.as_str(),
        cols.output.as_str(),
    ];
    if let Some(c) = &cols.load_output {
        names.push(c);
    }
    let (raw, lines) = read_numeric(path, &names)?;
    let (_, ts) = unit_of(&cols.time);
    let (_, us) = unit_of(&cols.input);
    let (yu, ys) = unit_of(&cols.output);
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
    let input = scale(1, us * cols.input_gain);
    let output = scale(2, ys);
    let load_out = cols
        .load_output
        .as_deref()
        .map(|c| scale(3, unit_of(c).1 * cols.load_gain));
    if time.len() < 50 {
        return Err(DataError::TooShort {
            file,
            rows: time.len(),
            need: 50,
        });
    }
    // Uniform sampling: the differentiator and every fingerprint assume one sample period,
    // so a gap (dropped rows) or a jump in the clock would silently bend the fit. Jitter is
    // tolerated (the XL330 servo records in ../shared/data/real reach 1.74× their median
    // interval); a gap of two or more samples is not.
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
    Ok(Recording {
        path: file,
        time,
        input,
        output,
        load_output: load_out,
        dt,
        units: (input_unit(cols), yu.to_string()),
        columns: cols.clone(),
    })
}

/// Load named columns as raw numbers (no unit conversion), with the same error checks.
/// For extra signals a command needs beside input/output (a reference, a pulse train).
pub fn load_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, DataError> {
    read_numeric(path, names).map(|(cols, _)| cols)
}

/// The named columns as finite numbers, with the CSV line of each row (for later errors).
/// A missing column, a cell that is not a number, NaN or inf is an error naming the file,
/// the line and the column.
fn read_numeric(path: &Path, names: &[&str]) -> Result<(Vec<Vec<f64>>, Vec<u64>), DataError> {
    let file = path.to_path_buf();
    let text = std::fs::read(path).map_err(|source| DataError::Io {
        file: file.clone(),
        source,
    })?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_slice());
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
            if !v.is_finite() {
                return Err(DataError::NotFinite {
                    file: file.clone(),
                    line,
                    column: (*name).into(),
                    value: v,
                });
            }
            col.push(v);
        }
        lines.push(line);
    }
    Ok((out, lines))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A geared load encoder is brought onto the output column's axis by `load_gain`, after
    /// its own unit suffix (degrees here), and the other columns are untouched.
    #[test]
    fn load_column_is_scaled_by_its_unit_and_the_load_gain() {
        let dir = std::env::temp_dir().join(format!("jointlab-data-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("geared.csv");
        let mut csv = String::from("time_s,torque_Nm,q_rad,out_deg\n");
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            csv += &format!("{t},{},{},{}\n", 0.5 + t, 30.0 * t, t.to_degrees());
        }
        std::fs::write(&path, csv).expect("write csv");
        let cols = Columns {
            load_output: Some("out_deg".into()),
            load_gain: 30.0,
            ..Columns::new("torque_Nm", "q_rad")
        };
        let rec = load(&path, &cols).expect("load");
        std::fs::remove_dir_all(&dir).ok();
        let load = rec.load_output.as_ref().expect("load column");
        for (k, (&q, &l)) in rec.output.iter().zip(load).enumerate() {
            assert!(
                (q - l).abs() < 1e-12,
                "sample {k}: motor {q} vs geared load {l}"
            );
        }
        assert!(rec.input.iter().zip(&rec.time).all(|(&u, &t)| u == 0.5 + t));
    }
}
