//! What every `--json` object of the workbench carries beside its results: a
//! `schema_version`, so a script can tell a layout it knows from a newer one, and the units
//! of the record's signals, so no number is read in the wrong unit.

use serde::Serialize;

use crate::data::{self, Columns};
use crate::residual::Mode;
use crate::units::{unit_of, UnknownUnit};

/// The layout of the workbench's JSON objects. Raised when a key changes meaning or goes
/// away; a new key does not raise it.
pub const SCHEMA_VERSION: u32 = 1;

/// The units of a record's signals, and so of every number the workbench reports about it.
/// Parameters carry their own (`params[].unit`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RecordUnits {
    /// Time.
    pub time: String,
    /// The input (force or torque, or the command times its gain).
    pub input: String,
    /// Position.
    pub position: String,
    /// Velocity.
    pub velocity: String,
    /// Acceleration.
    pub acceleration: String,
    /// The residual, RMS, noise floor and every bin's RMS and mean: the input's unit for the
    /// equation error, the position's for the output error.
    pub residual: String,
}

impl RecordUnits {
    /// The units of a record read with `cols`, for a `mode` residual.
    pub fn of(cols: &Columns, mode: Mode) -> Result<Self, UnknownUnit> {
        let input = data::input_unit(cols);
        let position = unit_of(&cols.output)?.0.to_string();
        // A column without a unit suffix (arrays passed unnamed): per second of nothing.
        let per = if position.is_empty() { "1" } else { &position };
        Ok(RecordUnits {
            time: "s".into(),
            residual: match mode {
                Mode::Equation => input.clone(),
                Mode::Output => position.clone(),
            },
            input,
            velocity: format!("{per}/s"),
            acceleration: format!("{per}/s²"),
            position,
        })
    }
}

/// Put `schema_version` and `units` into the JSON object `j`.
pub fn stamp(j: &mut serde_json::Value, units: &RecordUnits) {
    j["schema_version"] = serde_json::json!(SCHEMA_VERSION);
    j["units"] = serde_json::json!(units);
}
