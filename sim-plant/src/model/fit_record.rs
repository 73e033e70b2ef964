//! `[fit]`: what a fitter learned beyond the physical parameters — the 1σ of each estimate
//! and the *analysis shapes* it used (the sign-smoothing velocity of a friction column, the
//! smoothing length of a differentiated column, the delay a column was built for, …).
//!
//! The simulator ignores this section; it is written by `hil-host fit` so that a model file
//! is one complete record (MATLAB's identified models likewise carry their covariance), and
//! read back so that refitting from a saved model starts where the last fit ended. Physical
//! quantities (Stribeck velocity, ripple period, backlash width, quantiser step) live in the
//! effects' own parameters, not here; where both exist the effect parameter wins.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::effects::Shape;

/// The `[fit]` section of a model file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitRecord {
    /// Where the estimates came from (data file, residual form), free text.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
    /// 1σ of the rigid inertia `N²·I1 + I2` (output-referred).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia_sigma: Option<f64>,
    /// Per effect (lowercase name): analysis shape and amplitude 1σ.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub effects: BTreeMap<String, FitEffect>,
}

/// What the fitter recorded for one effect.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitEffect {
    /// The shape its fingerprint was built with.
    #[serde(default)]
    pub shape: Shape,
    /// 1σ of each fingerprint amplitude, in column order (NaN = not estimated).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sigma: Vec<f64>,
}

impl FitRecord {
    /// TOML text of the section (empty for an empty record).
    pub fn to_toml_string(&self) -> String {
        if *self == FitRecord::default() {
            return String::new();
        }
        #[derive(Serialize)]
        struct Wrap<'a> {
            fit: &'a FitRecord,
        }
        // Shapes are written as their differences from the default: an effect reads only the
        // fields it needs, the rest would be noise in the file.
        let mut value = toml::Value::try_from(Wrap { fit: self })
            .unwrap_or_else(|_| toml::Value::Table(Default::default()));
        let default = toml::Value::try_from(Shape::default()).ok();
        if let (Some(effects), Some(toml::Value::Table(default))) = (
            value
                .get_mut("fit")
                .and_then(|f| f.get_mut("effects"))
                .and_then(|e| e.as_table_mut()),
            default,
        ) {
            for (_, e) in effects.iter_mut() {
                let Some(e) = e.as_table_mut() else { continue };
                if let Some(shape) = e.get_mut("shape").and_then(|s| s.as_table_mut()) {
                    shape.retain(|k, v| default.get(k) != Some(v));
                }
                if e.get("shape")
                    .and_then(|s| s.as_table())
                    .is_some_and(|t| t.is_empty())
                {
                    e.remove("shape");
                }
            }
        }
        let body = toml::to_string(&value).unwrap_or_default();
        format!("\n# Written by the fitter; the simulator ignores this section.\n{body}")
    }
}
