//! The model the workbench fits: a rigid inertia plus effects from the `sim-plant` library,
//! each parameter fixed or free, stored as TOML.
//!
//! ```toml
//! name = "emps"
//! [inertia]
//! name = "inertia"
//! value = 95.1
//! free = true
//! [[effect]]
//! kind = "viscous"
//! [[effect.param]]
//! name = "fv"
//! value = 203.5
//! ```
//!
//! Sign convention (the equation-error form): `input = inertia·a + Σ θ·fingerprint`, so a
//! friction parameter is the force it consumes (EMPS: `offset = −3.16 N` means the drive
//! needs 3.16 N less than a symmetric model would).
//!
//! Its field names follow the effect library (`EffectKind::name`, `param_names`, `Shape`).
//! TODO: `sim_plant::Model` (the simulator's model TOML) has landed; the workbench should read
//! and write that type instead of this one (one model file format for simulator and fitter).

use serde::{Deserialize, Serialize};
use sim_plant::effects::{EffectKind, Shape};
use std::path::Path;

/// One parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Name (from `EffectKind::param_names`).
    pub name: String,
    /// Value, SI.
    pub value: f64,
    /// Fitted (true) or held fixed (false).
    #[serde(default = "yes")]
    pub free: bool,
    /// 1σ from the last fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
}

fn yes() -> bool {
    true
}

impl Param {
    /// A free parameter.
    pub fn free(name: &str, value: f64) -> Self {
        Param {
            name: name.into(),
            value,
            free: true,
            sigma: None,
        }
    }
}

/// One effect in the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectEntry {
    /// Which effect.
    pub kind: EffectKind,
    /// Its shape parameters (Stribeck velocity, ripple period, …).
    #[serde(default)]
    pub shape: Shape,
    /// Amplitudes, one per fingerprint column.
    #[serde(rename = "param")]
    pub params: Vec<Param>,
}

/// Rigid inertia + effects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Free-text name.
    #[serde(default)]
    pub name: String,
    /// Inertia (mass for a linear axis).
    pub inertia: Param,
    /// Effects, in the order they were added.
    #[serde(default, rename = "effect")]
    pub effects: Vec<EffectEntry>,
}

/// Model file problems.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// I/O.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    /// TOML syntax or schema.
    #[error("{0}: {1}")]
    Toml(String, String),
    /// Parameter count does not match the effect.
    #[error("{file}: effect `{kind}` needs {need} parameters ({names}), found {have}")]
    Params {
        /// File.
        file: String,
        /// Effect.
        kind: String,
        /// Needed.
        need: usize,
        /// Found.
        have: usize,
        /// Names.
        names: String,
    },
}

impl Model {
    /// The default baseline: rigid inertia with viscous friction, both free.
    pub fn baseline() -> Self {
        Model {
            name: "baseline: rigid inertia + viscous".into(),
            inertia: Param::free("inertia", 0.0),
            effects: vec![EffectEntry::new(EffectKind::Viscous, Shape::default())],
        }
    }

    /// Does the model contain this effect?
    pub fn has(&self, kind: EffectKind) -> bool {
        self.effects.iter().any(|e| e.kind == kind)
    }

    /// Add an effect with free, zero amplitudes.
    pub fn add(&mut self, kind: EffectKind, shape: Shape) {
        self.effects.push(EffectEntry::new(kind, shape));
        self.name = format!("{} + {}", self.name, kind.name());
    }

    /// All parameters, in design order: inertia then effects.
    pub fn params(&self) -> Vec<&Param> {
        std::iter::once(&self.inertia)
            .chain(self.effects.iter().flat_map(|e| e.params.iter()))
            .collect()
    }

    /// Mutable parameters in the same order as [`Model::params`].
    pub fn params_mut(&mut self) -> Vec<&mut Param> {
        std::iter::once(&mut self.inertia)
            .chain(self.effects.iter_mut().flat_map(|e| e.params.iter_mut()))
            .collect()
    }

    /// Load and validate a model TOML.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let f = path.display().to_string();
        let s = std::fs::read_to_string(path).map_err(|e| ModelError::Io(f.clone(), e))?;
        let m: Model =
            toml::from_str(&s).map_err(|e| ModelError::Toml(f.clone(), e.to_string()))?;
        for e in &m.effects {
            let names = e.kind.param_names();
            if e.params.len() != names.len() {
                return Err(ModelError::Params {
                    file: f,
                    kind: e.kind.name().into(),
                    need: names.len(),
                    have: e.params.len(),
                    names: names.join(", "),
                });
            }
        }
        Ok(m)
    }

    /// Save as TOML.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        let f = path.display().to_string();
        let s =
            toml::to_string_pretty(self).map_err(|e| ModelError::Toml(f.clone(), e.to_string()))?;
        std::fs::write(path, s).map_err(|e| ModelError::Io(f, e))
    }
}

impl EffectEntry {
    /// An effect with free zero amplitudes.
    pub fn new(kind: EffectKind, shape: Shape) -> Self {
        EffectEntry {
            kind,
            shape,
            params: kind
                .param_names()
                .iter()
                .map(|n| Param::free(n, 0.0))
                .collect(),
        }
    }
}
