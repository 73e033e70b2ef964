//! Model files: a joint described as inertias, a gear ratio and a set of effects, in TOML.
//!
//! ```toml
//! name = "harmonic-drive-60"
//! [motor]                       # at the motor shaft
//! inertia = 2.5e-4              # kg·m²
//! [plant]                       # referred to the output shaft
//! gear_ratio = 60.0
//! output_inertia = 0.05
//! [effects.coulomb]
//! torque = { value = 5.0, free = true }   # N·m
//! [effects.backlash]
//! width = "0.8 deg"
//! ```
//!
//! Structure follows from the parameters: no `compliance`/`backlash` effect → a rigid single
//! inertia `J = N²·I1 + I2` (the workbench's baseline "rigid inertia + effects"); with one →
//! the 2-mass plant of thesis §3.1; `plant.proximal_stiffness > 0` in addition → the 3-mass
//! plant of Eqn 3.3.26.
//!
//! A fitter's record (1σ of each estimate, the analysis shapes it used) goes to an optional
//! `[fit]` section ([`FitRecord`]) that the simulator ignores, so a fitted model is one file
//! that both `hil-host fit` and the HIL lab read.
//!
//! Parsing is strict (`deny_unknown_fields` everywhere); every error carries file, line and
//! column. [`Model::to_toml_string`] writes a file that parses back to an equal model (the
//! fitter writes refit models with it).

pub mod error;
pub mod fit_record;
pub mod sections;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use error::{line_col, Located, ModelError};
pub use fit_record::{FitEffect, FitRecord};

use crate::effects::{EffectKind, EffectSet};
use crate::param::{Param, ParamSpec};
use crate::units::Axis;

/// Which mechanical structure a model describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlantKind {
    /// One inertia: motor and load move together.
    Rigid,
    /// Motor | transmission spring | output (thesis Fig 3.1.3).
    TwoMass,
    /// Motor | proximal spring Ks | middle | transmission spring KT | output (Eqn 3.3.26).
    ThreeMass,
}

/// A joint model: what a model file holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Short name (presets use it as their key).
    #[serde(default = "unnamed")]
    pub name: String,
    /// Free text: source, assumptions.
    #[serde(default)]
    pub description: String,
    /// What the coordinate measures; absent, a rotary joint's unit names (the numbers are the
    /// same either way, see [`Axis`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<Axis>,
    /// The unit of the input a fitter measured, when it is not the axis's force (a command
    /// in `V`): the torque-like parameters are in it (N·m·s/rad reads V·s/rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_unit: Option<String>,
    /// Motor-shaft data.
    #[serde(default)]
    pub motor: sections::motor::Params,
    /// Output-referred mechanics.
    #[serde(default)]
    pub plant: sections::plant::Params,
    /// Sensor data.
    #[serde(default)]
    pub sensors: sections::sensors::Params,
    /// The effects present, with their parameters.
    #[serde(default)]
    pub effects: EffectSet,
    /// What a fitter recorded (1σ, analysis shapes); ignored by the simulator.
    #[serde(default)]
    pub fit: FitRecord,
}

fn unnamed() -> String {
    "unnamed".into()
}

impl Default for Model {
    fn default() -> Self {
        Self {
            name: unnamed(),
            description: String::new(),
            axis: None,
            input_unit: None,
            motor: Default::default(),
            plant: Default::default(),
            sensors: Default::default(),
            effects: Default::default(),
            fit: Default::default(),
        }
    }
}

impl Model {
    /// Parse a model from TOML text; `file` names the source in error messages.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, ModelError> {
        let mut model: Model = toml::from_str(text)
            .map_err(|e| ModelError::at(file, text, e.span(), e.message().to_string()))?;
        model.resolve(file, text)?;
        Ok(model)
    }

    /// Read and parse a model file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            file: file.clone(),
            source,
        })?;
        Self::from_toml_str(&text, &file)
    }

    /// Write the model as TOML (see [`Model::to_toml_string`]).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_toml_string()).map_err(|source| ModelError::Io {
            file: path.display().to_string(),
            source,
        })
    }

    /// Mechanical structure implied by the parameters.
    pub fn kind(&self) -> PlantKind {
        let spring = self.effects.contains(EffectKind::Compliance)
            || self.effects.contains(EffectKind::Backlash);
        if self.plant.proximal_stiffness.value > 0.0 {
            PlantKind::ThreeMass
        } else if spring {
            PlantKind::TwoMass
        } else {
            PlantKind::Rigid
        }
    }

    /// Every parameter of the model with a dotted path (`effects.coulomb.torque`,
    /// `motor.inertia`, …), in file order. The fitter uses these names.
    pub fn parameters(&self) -> Vec<(String, &'static ParamSpec, &Param)> {
        let mut out = Vec::new();
        for (s, p) in self.motor.entries() {
            out.push((format!("motor.{}", s.name), s, p));
        }
        for (s, p) in self.plant.entries() {
            out.push((format!("plant.{}", s.name), s, p));
        }
        for (s, p) in self.sensors.entries() {
            out.push((format!("sensors.{}", s.name), s, p));
        }
        for k in self.effects.kinds() {
            for (s, p) in self.effects.params(k) {
                out.push((format!("effects.{}.{}", k.name(), s.name), s, p));
            }
        }
        out
    }

    /// Mutable access to one parameter by its dotted path.
    pub fn parameter_mut(&mut self, path: &str) -> Option<&mut Param> {
        let mut parts = path.split('.');
        let section = parts.next()?;
        let (group, name) = if section == "effects" {
            (parts.next()?, parts.next()?)
        } else {
            ("", parts.next()?)
        };
        if parts.next().is_some() {
            return None;
        }
        let entries = match section {
            "motor" => self.motor.entries_mut(),
            "plant" => self.plant.entries_mut(),
            "sensors" => self.sensors.entries_mut(),
            "effects" => self.effects.params_mut(EffectKind::from_name(group)?),
            _ => return None,
        };
        entries
            .into_iter()
            .find(|(s, _)| s.name == name)
            .map(|(_, p)| p)
    }

    /// Convert written units, check ranges and cross-parameter consistency.
    fn resolve(&mut self, file: &str, text: &str) -> Result<(), ModelError> {
        let axis = self.axis.unwrap_or_default();
        let check = |entries: Vec<(&'static ParamSpec, &mut Param)>| -> Result<(), ModelError> {
            for (spec, p) in entries {
                p.resolve(spec, axis)
                    .map_err(|m| ModelError::at(file, text, p.span(), m))?;
            }
            Ok(())
        };
        check(self.motor.entries_mut())?;
        check(self.plant.entries_mut())?;
        check(self.sensors.entries_mut())?;
        for k in EffectKind::ALL {
            check(self.effects.params_mut(k))?;
        }
        self.check_consistency()
            .map_err(|(span, m)| ModelError::at(file, text, span, m))
    }

    /// Cross-parameter checks; on failure the span of the parameter to fix.
    pub fn check_consistency(&self) -> Result<(), (Option<std::ops::Range<usize>>, String)> {
        let p = &self.plant;
        match self.kind() {
            PlantKind::Rigid => {}
            PlantKind::TwoMass | PlantKind::ThreeMass => {
                if p.output_inertia.value <= 0.0 {
                    // Point at the inertia if written, else at what made the plant compliant.
                    let why = self
                        .effects
                        .compliance
                        .as_ref()
                        .and_then(|c| c.entries().iter().find_map(|(_, q)| q.span()))
                        .or_else(|| self.effects.backlash.as_ref().and_then(|b| b.width.span()))
                        .or_else(|| p.proximal_stiffness.span());
                    return Err((
                        p.output_inertia.span().or(why),
                        "a compliant transmission (compliance/backlash effect or \
                         proximal_stiffness) needs plant.output_inertia > 0"
                            .into(),
                    ));
                }
            }
        }
        if self.kind() == PlantKind::ThreeMass && p.middle_inertia.value <= 0.0 {
            return Err((
                p.middle_inertia.span(),
                "the 3-mass plant (proximal_stiffness > 0) needs plant.middle_inertia > 0".into(),
            ));
        }
        if self.kind() == PlantKind::ThreeMass && !self.effects.contains(EffectKind::Compliance) {
            return Err((
                p.proximal_stiffness.span(),
                "the 3-mass plant needs a compliance effect for the distal spring KT".into(),
            ));
        }
        if let Some(c) = &self.effects.compliance {
            if c.knee.value > 0.0 && c.soft_stiffness.value > c.stiffness.value {
                return Err((
                    c.soft_stiffness.span(),
                    "compliance.soft_stiffness above compliance.stiffness: a soft zone must be \
                     softer (write the softening case as stiffness < soft_stiffness with knee = 0)"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    /// TOML text of the model, with units as comments; parses back to an equal model.
    pub fn to_toml_string(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!("name = {}\n", toml_string(&self.name)));
        if !self.description.is_empty() {
            s.push_str(&format!(
                "description = {}\n",
                toml_string(&self.description)
            ));
        }
        if let Some(axis) = self.axis {
            s.push_str(&format!("axis = \"{}\"\n", axis.name()));
        }
        if let Some(u) = &self.input_unit {
            s.push_str(&format!("input_unit = {}\n", toml_string(u)));
        }
        let axis = self.axis.unwrap_or_default();
        let unit = |canonical: &str| match &self.input_unit {
            None => axis.unit(canonical),
            Some(u) => axis
                .unit(canonical)
                .replace(&axis.unit("kg·m²"), &format!("{u}·s²/{}", axis.unit("rad")))
                .replace(&axis.unit("N·m"), u),
        };
        let mut section =
            |title: &str, comment: &str, entries: Vec<(&'static ParamSpec, &Param)>| {
                s.push_str(&format!("\n[{title}]"));
                if !comment.is_empty() {
                    s.push_str(&format!("  # {comment}"));
                }
                s.push('\n');
                for (spec, p) in entries {
                    s.push_str(&format!(
                        "{} = {}  # {}\n",
                        spec.name,
                        p.to_toml_value(),
                        unit(spec.unit)
                    ));
                }
            };
        section("motor", "at the motor shaft", self.motor.entries());
        section(
            "plant",
            "referred to the output shaft",
            self.plant.entries(),
        );
        section("sensors", "", self.sensors.entries());
        for k in self.effects.kinds() {
            section(&format!("effects.{}", k.name()), "", self.effects.params(k));
        }
        s.push_str(&self.fit.to_toml_string());
        s
    }
}

/// `s` as a TOML basic string. Written here rather than by the `toml` crate: its writer
/// counts a run of quotes in a `u8` and overflows on 256 of them.
fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
