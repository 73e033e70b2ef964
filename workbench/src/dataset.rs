//! A dataset file: which CSV, which columns, their gains and units, and how the input was
//! held, in a few lines of TOML, so a recording is described once and every command takes it
//! (`hil-host diagnose emps.toml`), as MATLAB's `iddata` object is built once.
//!
//! ```toml
//! file = "DATA_EMPS.csv"          # relative to this file
//! time = "t_s"
//! input = "vir_V"
//! input_gain = 35.15065188248547  # N per V: the drive's gain
//! input_unit = "N"
//! output = "qm_m"
//! intersample = "zoh"
//! validate = "DATA_EMPS_PULSES.csv"
//! ```
//!
//! Every key but `file` may be left out: columns come from the header when it settles them
//! ([`data::detect`]), gains default to 1, the hold to `zoh`. The same struct holds what a
//! command line names ([`Dataset::or`] lets flags win over the file), so there is one place
//! where a description becomes [`Columns`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim_plant::effects::Intersample;
use thiserror::Error;

use crate::data::{self, Columns, DataError, Role};

/// A recording and how to read it. `None` fields are "not said here".
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Dataset {
    /// The CSV (a relative path in a dataset file is relative to that file).
    pub file: PathBuf,
    /// Free text: where the data come from.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Time column (default: the first of [`data::TIME_NAMES`] in the header).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    /// Input column (default: the one force/torque column).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<String>,
    /// Output position column (default: the one position column).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output: Option<String>,
    /// Load-side position column, if an output encoder was logged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub load_output: Option<String>,
    /// Gain from the load column to the output's axis (default 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub load_gain: Option<f64>,
    /// Gain from the input column to force/torque (default 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_gain: Option<f64>,
    /// The input's unit after the gain, as reports label it (`N`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_unit: Option<String>,
    /// A column the input is multiplied by, row by row (a supply voltage times a PWM duty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_times: Option<String>,
    /// First time used, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from: Option<f64>,
    /// Last time used, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub to: Option<f64>,
    /// What the input did between samples: `zoh`, `foh`, `mid`, `bl` (default `zoh`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub intersample: Option<String>,
    /// Gear ratio from the output column to the joint's output (default 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gear_ratio: Option<f64>,
    /// A second recording with the same columns, scored where a command validates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validate: Option<PathBuf>,
}

/// A dataset file that cannot be used, with the file and the reason.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// Unreadable.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File.
        file: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Not TOML, an unknown key, a wrong type (toml's message carries line and column).
    #[error("{file}: {msg}")]
    Toml {
        /// File.
        file: PathBuf,
        /// The parser's message.
        msg: String,
    },
    /// A value out of its range.
    #[error("{file}: `{key}` = {value}: {why}")]
    Value {
        /// File (or `<command line>`).
        file: PathBuf,
        /// The key.
        key: &'static str,
        /// Its value.
        value: String,
        /// What it must be.
        why: String,
    },
}

/// `file` relative to `dir`, with `dir/..` pairs folded so messages show a plain path
/// (`../shared/x.csv`, not `datasets/../../shared/x.csv`).
fn beside(dir: &Path, file: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in dir.join(file).components() {
        let last_is_name = matches!(out.components().next_back(), Some(Component::Normal(_)));
        match c {
            Component::CurDir => {}
            Component::ParentDir if last_is_name => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// Whether `path` names a dataset file rather than a CSV (by its `.toml` extension).
pub fn is_dataset(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

impl Dataset {
    /// A dataset that names only its file (everything else detected or defaulted).
    pub fn of_file(file: impl Into<PathBuf>) -> Self {
        Dataset {
            file: file.into(),
            ..Dataset::default()
        }
    }

    /// Read a dataset file; `file` and `validate` become paths relative to its directory.
    pub fn load(path: &Path) -> Result<Self, DatasetError> {
        let text = std::fs::read_to_string(path).map_err(|source| DatasetError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        let mut d = Self::from_toml_str(&text, path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        d.file = beside(dir, &d.file);
        d.validate = d.validate.map(|v| beside(dir, &v));
        Ok(d)
    }

    /// [`Dataset::load`] from text; `file` names it in errors. Paths stay as written.
    pub fn from_toml_str(text: &str, file: &Path) -> Result<Self, DatasetError> {
        let d: Dataset = toml::from_str(text).map_err(|e| DatasetError::Toml {
            file: file.to_path_buf(),
            msg: e.to_string(),
        })?;
        d.check(file)?;
        Ok(d)
    }

    /// The dataset as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// `self`'s fields where it has them, `other`'s elsewhere: command-line flags over a
    /// dataset file. `file` is `self`'s.
    pub fn or(self, other: Dataset) -> Dataset {
        Dataset {
            file: self.file,
            description: self.description.or(other.description),
            time: self.time.or(other.time),
            input: self.input.or(other.input),
            output: self.output.or(other.output),
            load_output: self.load_output.or(other.load_output),
            load_gain: self.load_gain.or(other.load_gain),
            input_gain: self.input_gain.or(other.input_gain),
            input_unit: self.input_unit.or(other.input_unit),
            input_times: self.input_times.or(other.input_times),
            from: self.from.or(other.from),
            to: self.to.or(other.to),
            intersample: self.intersample.or(other.intersample),
            gear_ratio: self.gear_ratio.or(other.gear_ratio),
            validate: self.validate.or(other.validate),
        }
    }

    /// Ranges a value must lie in, checked when the file is read (and again by
    /// [`Dataset::columns`] for values from elsewhere).
    pub fn check(&self, file: &Path) -> Result<(), DatasetError> {
        let bad = |key: &'static str, value: String, why: &str| DatasetError::Value {
            file: file.to_path_buf(),
            key,
            value,
            why: why.into(),
        };
        for (key, v) in [
            ("input_gain", self.input_gain),
            ("load_gain", self.load_gain),
        ] {
            if let Some(v) = v.filter(|v| !v.is_finite() || *v == 0.0) {
                return Err(bad(key, v.to_string(), "a finite number other than 0"));
            }
        }
        if let Some(v) = self.gear_ratio.filter(|v| !v.is_finite() || *v <= 0.0) {
            return Err(bad("gear_ratio", v.to_string(), "a finite number above 0"));
        }
        for (key, v) in [("from", self.from), ("to", self.to)] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(bad(key, v.to_string(), "a finite time in s"));
            }
        }
        if let (Some(a), Some(b)) = (self.from, self.to) {
            if a >= b {
                return Err(bad("to", b.to_string(), "later than `from`"));
            }
        }
        if self.load_gain.is_some() && self.load_output.is_none() {
            return Err(bad(
                "load_gain",
                self.load_gain.unwrap_or(1.0).to_string(),
                "needs `load_output`",
            ));
        }
        if let Some(i) = &self.intersample {
            i.parse::<Intersample>()
                .map_err(|e| bad("intersample", format!("\"{i}\""), &e))?;
        }
        Ok(())
    }

    /// The [`Columns`] that read [`Dataset::file`] (or a validation file with the same
    /// columns): named columns as named, the others found in `file`'s header, defaults
    /// elsewhere. The `from`/`to` window applies when `windowed` (a validation file is used
    /// whole).
    pub fn columns(&self, file: &Path, windowed: bool) -> Result<Columns, DataError> {
        let header = if self.time.is_none() || self.input.is_none() || self.output.is_none() {
            data::header(file)?
        } else {
            Vec::new()
        };
        let pick = |named: &Option<String>, role: Role| match named {
            Some(n) => Ok(n.clone()),
            None => data::detect(file, &header, role),
        };
        let window = (windowed && (self.from.is_some() || self.to.is_some())).then(|| {
            (
                self.from.unwrap_or(f64::NEG_INFINITY),
                self.to.unwrap_or(f64::INFINITY),
            )
        });
        Ok(Columns {
            time: pick(&self.time, Role::Time)?,
            input: pick(&self.input, Role::Input)?,
            output: pick(&self.output, Role::Output)?,
            load_output: self.load_output.clone(),
            load_gain: self.load_gain.unwrap_or(1.0),
            input_gain: self.input_gain.unwrap_or(1.0),
            input_times: self.input_times.clone(),
            input_unit: self.input_unit.clone(),
            window,
            intersample: self
                .intersample
                .as_deref()
                .and_then(|i| i.parse().ok())
                .unwrap_or_default(),
            gear_ratio: self.gear_ratio.unwrap_or(1.0),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dataset_file_reads_and_refuses_what_it_should() {
        let d = Dataset::from_toml_str(
            "file = \"a.csv\"\ninput = \"vir_V\"\ninput_gain = 35.15\nintersample = \"mid\"\n",
            Path::new("d.toml"),
        )
        .unwrap();
        assert_eq!(d.input.as_deref(), Some("vir_V"));
        assert_eq!(d.input_gain, Some(35.15));
        let again = Dataset::from_toml_str(&d.to_toml(), Path::new("d.toml")).unwrap();
        assert_eq!(again, d);
        for (text, says) in [
            ("file = \"a.csv\"\ninptu = \"x\"\n", "inptu"),
            ("file = \"a.csv\"\ninput_gain = 0.0\n", "input_gain"),
            ("file = \"a.csv\"\nintersample = \"hold\"\n", "intersample"),
            ("file = \"a.csv\"\nfrom = 2.0\nto = 1.0\n", "`to`"),
            ("file = \"a.csv\"\nload_gain = 3.0\n", "load_output"),
            ("input = \"x\"\n", "file"),
        ] {
            let e = Dataset::from_toml_str(text, Path::new("d.toml")).unwrap_err();
            assert!(e.to_string().contains(says), "{text:?}: {e}");
            assert!(e.to_string().starts_with("d.toml"), "{e}");
        }
    }

    #[test]
    fn paths_are_relative_to_the_dataset_file() {
        let p = |d: &str, f: &str| beside(Path::new(d), Path::new(f));
        assert_eq!(
            p("datasets", "../../shared/x.csv"),
            Path::new("../shared/x.csv")
        );
        assert_eq!(p("a/b", "./c.csv"), Path::new("a/b/c.csv"));
        assert_eq!(p("", "c.csv"), Path::new("c.csv"));
        assert_eq!(p("/r/d", "../c.csv"), Path::new("/r/c.csv"));
        assert_eq!(p("a", "/abs/c.csv"), Path::new("/abs/c.csv"));
    }

    #[test]
    fn flags_win_over_the_file_and_the_file_over_defaults() {
        let file = Dataset {
            input: Some("a_Nm".into()),
            input_gain: Some(2.0),
            ..Dataset::of_file("x.csv")
        };
        let flags = Dataset {
            input_gain: Some(3.0),
            ..Dataset::of_file("x.csv")
        };
        let d = flags.or(file);
        assert_eq!(d.input.as_deref(), Some("a_Nm"));
        assert_eq!(d.input_gain, Some(3.0));
    }
}
