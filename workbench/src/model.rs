//! The model the workbench fits: a rigid inertia plus effects from the `sim-plant` library,
//! each amplitude fixed or free — and its file form, which is the simulator's own model TOML
//! ([`sim_plant::Model`]): one file format for simulating and fitting, so a fitted model can be
//! run in the HIL lab unchanged and any sim-plant model (a preset, a hand-written joint) can be
//! the starting point of a fit.
//!
//! In memory the fitter needs the equation-error view: `input = J·a + Σ θ·fingerprint`, with
//! `J = N²·I1 + I_middle + I2` the rigid inertia referred to the data's axis and θ the
//! fingerprint amplitudes (the sign convention of `sim_plant::effects`: every effect is a
//! resisting torque, so EMPS's `offset = −3.16 N` means the drive needs 3.16 N less than a
//! symmetric model would). [`Model::from_sim`] and [`Model::to_sim`] translate:
//!
//! * amplitudes whose effect has a parameter with role `Amplitude(i)` are that parameter;
//! * backlash's amplitude (the inertia beyond the gap) is `plant.output_inertia`; compliance's
//!   (`−J2/J1` seen from a motor-side sensor, J2 = `plant.output_inertia`, J1 = J − J2) sets
//!   the inertia split (if the file has no output inertia, `J2 = J/2` is assumed and written),
//!   and its analysis shape — the coupled mode's frequency and damping ratio,
//!   ω² = K·(1/J1 + 1/J2), 2ζω = c·(1/J1 + 1/J2) — is `compliance.stiffness` and
//!   `compliance.damping` given that split;
//! * physical shapes (Stribeck velocity and exponent, ripple period, cogging cycles, backlash
//!   width, dead-zone input scale, quantiser step) are the effects' parameters; analysis shapes
//!   (sign smoothing, differentiator smoothing, the delay a column was built for) and the 1σ go
//!   to the file's `[fit]` section ([`sim_plant::model::FitRecord`]);
//! * the structural damping `N²·B1 + B2` of `[motor]`/`[plant]` is part of the viscous term.
//!
//! Data of a linear axis (EMPS) are written with `gear_ratio = 1` and read in N, m, kg where
//! the file's unit comments say N·m, rad, kg·m² — the algebra is the same.

use sim_plant::effects::{EffectKind, Shape};
use sim_plant::model::{FitEffect, FitRecord};
use sim_plant::param::Param as SimParam;
use sim_plant::units::Axis;
use std::path::Path;

/// One parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// Name (from `EffectKind::param_names`).
    pub name: String,
    /// Value, SI.
    pub value: f64,
    /// Fitted (true) or held fixed (false).
    pub free: bool,
    /// 1σ from the last fit (`None` for a parameter held at one of its bounds).
    pub sigma: Option<f64>,
    /// Lower fitting bound (the file's `min`), if any: the fit holds the parameter there
    /// rather than go below it.
    pub min: Option<f64>,
    /// Upper fitting bound (the file's `max`), if any.
    pub max: Option<f64>,
}

impl Param {
    /// A free parameter.
    pub fn free(name: &str, value: f64) -> Self {
        Param {
            name: name.into(),
            value,
            free: true,
            sigma: None,
            min: None,
            max: None,
        }
    }

    /// The bound the value sits on or beyond (`Some(bound)`), if it does.
    pub fn bound_reached(&self) -> Option<f64> {
        self.min
            .filter(|lo| self.value <= *lo)
            .or(self.max.filter(|hi| self.value >= *hi))
    }
}

/// One effect in the model.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectEntry {
    /// Which effect.
    pub kind: EffectKind,
    /// Its shape parameters (Stribeck velocity, ripple period, …).
    pub shape: Shape,
    /// Amplitudes, one per fingerprint column.
    pub params: Vec<Param>,
    /// 1σ of the smooth shape (`FitTraits::smooth_shape`: a ripple's period, …) where the
    /// refit's Levenberg–Marquardt estimated it; `None` for a shape only searched on a grid.
    pub shape_sigma: Option<f64>,
}

/// Rigid inertia + effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Free-text name.
    pub name: String,
    /// Inertia (mass for a linear axis).
    pub inertia: Param,
    /// Effects, in the order they were added.
    pub effects: Vec<EffectEntry>,
    /// The simulator model this one was read from: what the fit does not touch (gear ratio,
    /// sensors, motor limits, settings) is written back from it.
    pub template: Option<sim_plant::Model>,
    /// What its coordinate measures: from its file, or from the data it was fitted to
    /// ([`Model::on_axis`]); `None` reads as rotary.
    pub axis: Option<Axis>,
    /// The unit of the input it was fitted to or compared with, when that is not the axis's
    /// force (a command in V): its parameters are then in that unit, not in N·m.
    pub input_unit: Option<String>,
}

/// Model file problems.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file does not read or parse as a sim-plant model (names file, line, column).
    #[error(transparent)]
    File(#[from] sim_plant::model::ModelError),
    /// It parses, but the workbench cannot fit it.
    #[error("{file}: {source}")]
    Unfittable {
        /// File.
        file: String,
        /// What is wrong.
        #[source]
        source: Unfittable,
    },
    /// A model of one kind of axis given a recording of the other.
    #[error(
        "the model is for a {model} axis ({model_units}), but the recording's position is \
         {data} ({data_units}): a model fitted on one does not describe the other"
    )]
    Axis {
        /// The model's axis.
        model: &'static str,
        /// Its units.
        model_units: String,
        /// The recording's.
        data: &'static str,
        /// Its units.
        data_units: String,
    },
    /// A fitted model that no model file can hold, so it was not written.
    #[error("{file}: not written, the fitted model is not physical: {source}")]
    NotPhysical {
        /// File.
        file: String,
        /// What is wrong.
        #[source]
        source: Unphysical,
    },
}

/// Why a simulator model cannot be the workbench's starting point.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Unfittable {
    /// Nothing to fit against.
    #[error("the rigid inertia N²·I1 + I_middle + I2 = {0} is not positive")]
    Inertia(f64),
    /// A bound on a parameter the fitter does not fit as itself; ignoring it silently would
    /// let a fit leave it where the file forbids.
    #[error(
        "`{parameter}` has a min/max bound the fitter cannot honour: {why}. Bounds are \
         honoured on effect amplitudes only; remove this one"
    )]
    Bound {
        /// Dotted path (`motor.inertia`, `effects.stribeck.velocity`).
        parameter: String,
        /// What the fitter does with this parameter instead.
        why: &'static str,
    },
}

/// Why a fitted model is not physical (see [`Model::physical`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Unphysical {
    /// Compliance's amplitude −J2/J1 fitted positive.
    #[error(
        "compliance {name} = {value:+.4e} is positive: it is −J2/J1 of a two-mass joint, so no \
         plant has it (the column fitted a broadband correction, not a transmission mode)"
    )]
    PositiveCompliance {
        /// Parameter.
        name: String,
        /// Its value.
        value: f64,
    },
    /// Backlash and compliance fitted two different load inertias.
    #[error(
        "backlash's load inertia {name} = {backlash:.4e} and compliance's split J2 = \
         {split:.4e} differ: the joint has one load, and a model file holds one J2"
    )]
    LoadInertia {
        /// Backlash's parameter.
        name: String,
        /// Its value.
        backlash: f64,
        /// Compliance's J2.
        split: f64,
    },
    /// A parameter outside its physical range, as the simulator's reader reports it
    /// (naming the parameter).
    #[error("{0}")]
    Range(String),
}

impl Model {
    /// The default baseline: rigid inertia with viscous friction, both free.
    pub fn baseline() -> Self {
        Model {
            name: "baseline: rigid inertia + viscous".into(),
            inertia: Param::free("inertia", 0.0),
            effects: vec![EffectEntry::new(EffectKind::Viscous, Shape::default())],
            template: None,
            axis: None,
            input_unit: None,
        }
    }

    /// Take the axis and input unit of the data (`Prepared::axis`, `Prepared::input_unit`) the
    /// model is fitted to or compared with; a model file that names the other kind of axis is
    /// an error.
    pub fn on_axis(&mut self, data: Axis, input_unit: &str) -> Result<(), ModelError> {
        self.input_unit = (!input_unit.is_empty() && input_unit != data.unit("N·m"))
            .then(|| input_unit.to_string());
        match self.axis {
            Some(a) if a != data => {
                let units =
                    |x: Axis| format!("{}, {}, {}", x.unit("N·m"), x.unit("rad"), x.unit("kg·m²"));
                Err(ModelError::Axis {
                    model: a.name(),
                    model_units: units(a),
                    data: data.name(),
                    data_units: units(data),
                })
            }
            _ => {
                self.axis = Some(data);
                Ok(())
            }
        }
    }

    /// Does the model contain this effect?
    pub fn has(&self, kind: EffectKind) -> bool {
        self.effect(kind).is_some()
    }

    /// The model's entry for this effect, if it holds one.
    pub fn effect(&self, kind: EffectKind) -> Option<&EffectEntry> {
        self.effects.iter().find(|e| e.kind == kind)
    }

    /// The range the fit keeps each parameter in, in [`Model::params`] order: the file's
    /// `min`/`max` where it gives them, narrowed to the parameter's physical range.
    ///
    /// Why the physical range: `fit` refuses to write a model with a parameter outside it (a
    /// negative Coulomb level, Stribeck excess, viscous drag or load inertia has no plant), so an
    /// unconstrained least-squares optimum there is not a model the user can have. Held at the
    /// bound (see [`crate::residual::refit_in_range`]), the rest refits to the best model that
    /// exists. The quantiser's gain is the one exception: its refit reads a gain outside
    /// [0, 1] as a step not yet found and searches further (`refine::search`), and `fit` then
    /// refuses what it could not mend.
    pub fn fit_bounds(&self) -> Vec<(Option<f64>, Option<f64>)> {
        let phys = |kind: Option<EffectKind>, name: &str| -> (Option<f64>, Option<f64>) {
            match (kind, name) {
                // The rigid inertia, as the model file holds it (`[motor] inertia`): its
                // declared lower limit is above 0, so a fit held there can still be written.
                (None, _) => (
                    sim_plant::model::sections::motor::PARAMS
                        .iter()
                        .find(|s| s.name == "inertia")
                        .map_or(Some(0.0), |s| Some(s.min)),
                    None,
                ),
                (Some(EffectKind::Quantization), "gain") => (None, None),
                // The load inertia beyond a gap (`plant.output_inertia`) and −J2/J1 of a spring.
                (Some(EffectKind::Backlash), "load_inertia") => (Some(0.0), None),
                (Some(EffectKind::Compliance), "inertia_ratio") => (None, Some(0.0)),
                (Some(k), n) => k
                    .params()
                    .iter()
                    .find(|s| s.name == n && matches!(s.role, sim_plant::param::Role::Amplitude(_)))
                    .map_or((None, None), |s| (Some(s.min), Some(s.max))),
            }
        };
        self.params()
            .iter()
            .zip(self.param_owners())
            .map(|(q, o)| {
                let (lo, hi) = phys(o, &q.name);
                let lo = match (q.min, lo) {
                    (Some(a), Some(b)) => Some(a.max(b)),
                    (a, b) => a.or(b),
                };
                let hi = match (q.max, hi) {
                    (Some(a), Some(b)) => Some(a.min(b)),
                    (a, b) => a.or(b),
                };
                (lo, hi)
            })
            .collect()
    }

    /// Add an effect with free, zero amplitudes.
    pub fn add(&mut self, kind: EffectKind, shape: Shape) {
        self.effects.push(EffectEntry::new(kind, shape));
        self.name = format!("{} + {}", self.name, kind.name());
    }

    /// Remove the `index`-th effect, and its name from the model's name (a saved model's
    /// name lists what it holds).
    pub fn remove(&mut self, index: usize) -> EffectEntry {
        let e = self.effects.remove(index);
        let tag = format!(" + {}", e.kind.name());
        if let Some(at) = self.name.rfind(&tag) {
            self.name.replace_range(at..at + tag.len(), "");
        }
        e
    }

    /// All parameters, in design order: inertia then effects.
    pub fn params(&self) -> Vec<&Param> {
        std::iter::once(&self.inertia)
            .chain(self.effects.iter().flat_map(|e| e.params.iter()))
            .collect()
    }

    /// The effect owning each parameter, in [`Model::params`] order (`None`: the inertia).
    pub fn param_owners(&self) -> Vec<Option<EffectKind>> {
        std::iter::once(None)
            .chain(
                self.effects
                    .iter()
                    .flat_map(|e| e.params.iter().map(move |_| Some(e.kind))),
            )
            .collect()
    }

    /// Mutable parameters in the same order as [`Model::params`].
    pub fn params_mut(&mut self) -> Vec<&mut Param> {
        std::iter::once(&mut self.inertia)
            .chain(self.effects.iter_mut().flat_map(|e| e.params.iter_mut()))
            .collect()
    }

    /// Load a sim-plant model file (any: a preset, a hand-written joint, a saved fit).
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let sim = sim_plant::Model::load(path)?;
        Self::from_sim(&sim).map_err(|source| ModelError::Unfittable {
            file: path.display().to_string(),
            source,
        })
    }

    /// [`Model::load`] from the file's text (the Python package's `Model.from_toml`); `file`
    /// names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, ModelError> {
        let sim = sim_plant::Model::from_toml_str(text, file)?;
        Self::from_sim(&sim).map_err(|source| ModelError::Unfittable {
            file: file.into(),
            source,
        })
    }

    /// The text [`Model::save`] writes, checked the same way; `file` names it in errors.
    pub fn to_toml_string(&self, file: &str) -> Result<String, ModelError> {
        let text = self.to_sim().to_toml_string();
        self.check_written(&text, file)
            .map_err(|source| ModelError::NotPhysical {
                file: file.into(),
                source,
            })?;
        Ok(text)
    }

    /// Save as a sim-plant model file. The text is parsed back first: a fit that left a
    /// parameter outside its physical range (a negative Coulomb level, say) is reported, naming
    /// the parameter, instead of writing a file that would not load.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        let file = path.display().to_string();
        let text = self.to_toml_string(&file)?;
        std::fs::write(path, text)
            .map_err(|source| sim_plant::model::ModelError::Io { file, source })?;
        Ok(())
    }

    /// Whether the simulator accepts this model as it would be written (every parameter inside
    /// its physical range); the reason if not. `--auto` only keeps models that pass, so what it
    /// finds can always be saved.
    pub fn physical(&self) -> Result<(), Unphysical> {
        self.check_written(&self.to_sim().to_toml_string(), "fitted model")
    }

    /// [`Model::physical`] of this model's file text `text` (named `file` in the reason): the
    /// split check, then the text parsed back as a simulator model — the one place the
    /// parameters' physical ranges are checked.
    fn check_written(&self, text: &str, file: &str) -> Result<(), Unphysical> {
        self.physical_split()?;
        sim_plant::Model::from_toml_str(text, file)
            .map(|_| ())
            .map_err(|e| Unphysical::Range(e.to_string()))
    }

    /// A compliance amplitude must be −J2/J1 < 0 for the file's two masses to exist: a
    /// positive one (the column used as a broadband correction) has no two-mass plant, and
    /// writing |α| would save a different model from the one that was scored.
    ///
    /// Backlash and compliance both name the load's inertia J2 (the file's one
    /// `plant.output_inertia`): fitted apart they disagree, and the file would hold only one
    /// of them, so such a model is refused too.
    pub fn physical_split(&self) -> Result<(), Unphysical> {
        let first = |k: EffectKind| {
            self.effects
                .iter()
                .find(|e| e.kind == k)
                .and_then(|e| e.params.first())
        };
        let compliance = first(EffectKind::Compliance);
        if let Some(p) = compliance.filter(|p| p.value > 0.0) {
            return Err(Unphysical::PositiveCompliance {
                name: p.name.clone(),
                value: p.value,
            });
        }
        if let (Some(c), Some(b)) = (compliance, first(EffectKind::Backlash)) {
            let j2 = load_inertia_of_split(self.inertia.value, c.value);
            if (j2 - b.value).abs() > 1e-9 * self.inertia.value.abs() {
                return Err(Unphysical::LoadInertia {
                    name: b.name.clone(),
                    backlash: b.value,
                    split: j2,
                });
            }
        }
        Ok(())
    }

    /// The equation-error view of a simulator model.
    ///
    /// Fails for a model whose rigid inertia is not positive (nothing to fit against), and
    /// for a `min`/`max` bound on a parameter that is not an effect's amplitude (see
    /// [`Unfittable::Bound`]).
    pub fn from_sim(sim: &sim_plant::Model) -> Result<Self, Unfittable> {
        // A compliant plant (2- or 3-mass) is seen through its rigid limit: the springs are
        // effects (compliance, backlash) whose fingerprints stand for them; the 3-mass plant's
        // proximal stage has none and is kept from the template on writing.
        let n = sim.plant.gear_ratio.value;
        let j = n * n * sim.motor.inertia.value
            + sim.plant.middle_inertia.value
            + sim.plant.output_inertia.value;
        let j_far = sim.plant.output_inertia.value;
        if !(j.is_finite() && j > 0.0) {
            return Err(Unfittable::Inertia(j));
        }
        refuse_bounds_not_fitted(sim)?;
        let mut model = Model {
            name: sim.name.clone(),
            inertia: Param {
                name: "inertia".into(),
                value: j,
                free: sim.motor.inertia.free,
                // A fixed value is given, not estimated: the fit record's σ (of whatever
                // value was fitted then) does not belong to it.
                sigma: sim.fit.inertia_sigma.filter(|_| sim.motor.inertia.free),
                min: None,
                max: None,
            },
            effects: Vec::new(),
            template: Some(sim.clone()),
            axis: sim.axis,
            input_unit: sim.input_unit.clone(),
        };
        for kind in sim.effects.kinds() {
            let record = sim.fit.effects.get(kind.name());
            let mut shape = record.map(|r| r.shape.clone()).unwrap_or_default();
            let by_name = |name: &str| {
                sim.effects
                    .params(kind)
                    .into_iter()
                    .find(|(s, _)| s.name == name)
                    .map(|(_, p)| p.clone())
            };
            let value = |name: &str| by_name(name).map(|p| p.value).unwrap_or(0.0);
            for fs in kind.fit_traits().file_shape {
                (fs.set)(&mut shape, value(fs.param), n);
            }
            // The mode's frequency and damping come from the spring and the inertia split, a
            // fact of the plant, not of the effect alone.
            if kind == EffectKind::Compliance {
                let far = if j_far > 0.0 { j_far } else { 0.5 * j };
                let k = value("stiffness");
                // The motion form's mode carries the load's drag too, at most the whole drag
                // (see `to_sim`; the record keeps the column's own value).
                let drag = n * n * sim.motor.damping.value
                    + sim.plant.output_damping.value
                    + sim
                        .effects
                        .viscous
                        .as_ref()
                        .map_or(0.0, |v| v.damping.value);
                let load = if shape.compliance_near_inertia > 0.0 {
                    shape.compliance_load_damping.clamp(0.0, drag.max(0.0))
                } else {
                    0.0
                };
                if k > 0.0 && far < j {
                    let mode = |c: f64| {
                        sim_plant::effects::compliance::mode_from_spring(k, c, j - far, far)
                    };
                    let (mut f, mut zeta) = mode(value("damping") + load);
                    // A file written before the load's drag was taken out of the spring holds
                    // the mode's damping in the spring: its fit record's mode says so.
                    let same = |(f1, z1): (f64, f64)| {
                        (f1 - shape.compliance_frequency).abs() <= 1e-9 * f1
                            && (z1 - shape.compliance_damping).abs() <= 1e-9 * z1
                    };
                    let older = mode(value("damping"));
                    if load > 0.0 && record.is_some() && same(older) && !same((f, zeta)) {
                        (f, zeta) = older;
                    }
                    shape.compliance_frequency = f;
                    shape.compliance_damping = zeta;
                }
            }
            let mut entry = EffectEntry::new(kind, shape);
            for (i, p) in entry.params.iter_mut().enumerate() {
                if let Some(q) = by_name(&p.name) {
                    (p.min, p.max) = (q.min, q.max);
                }
                let (v, free) = match (kind, by_name(&p.name)) {
                    (_, Some(q)) => (q.value, q.free),
                    // Equation-error-only amplitudes keep what `EffectEntry::new` gave them.
                    (_, None) if kind.fit_traits().held.iter().any(|(h, _)| *h == p.name) => {
                        (p.value, p.free)
                    }
                    (EffectKind::Backlash, None) => (j_far, sim.plant.output_inertia.free),
                    (EffectKind::Compliance, None) => {
                        let far = if j_far > 0.0 { j_far } else { 0.5 * j };
                        let free = by_name("stiffness").is_some_and(|q| q.free);
                        (
                            if far < j {
                                split_of_load_inertia(j, far)
                            } else {
                                0.0
                            },
                            free,
                        )
                    }
                    (_, None) => (0.0, true),
                };
                p.value = v;
                p.free = free;
                p.sigma = record
                    .and_then(|r| r.sigma.get(i).copied())
                    .filter(|s| s.is_finite() && free);
            }
            model.effects.push(entry);
        }
        // Structural damping N²·B1 + B2 acts like viscous friction in the rigid view.
        let b = n * n * sim.motor.damping.value + sim.plant.output_damping.value;
        if b != 0.0 {
            if !model.has(EffectKind::Viscous) {
                let mut e = EffectEntry::new(EffectKind::Viscous, Shape::default());
                e.params[0].free = false;
                model.effects.insert(0, e);
            }
            for e in model.effects.iter_mut() {
                if e.kind == EffectKind::Viscous {
                    let q = &mut e.params[0];
                    q.value += b;
                    q.min = q.min.map(|m| m + b);
                    q.max = q.max.map(|m| m + b);
                }
            }
        }
        Ok(model)
    }

    /// Compliance's motion form: the viscous drag in all (N·m·s/rad) and the load's part of
    /// it, at most the whole (a refit after the share was searched can lower the drag).
    fn load_drag(&self) -> Option<(f64, f64)> {
        let spring = self
            .effect(EffectKind::Compliance)
            .filter(|e| e.shape.compliance_near_inertia > 0.0)?;
        let v = self.effect(EffectKind::Viscous)?.params.first()?.value;
        (v.is_finite() && v > 0.0).then(|| {
            let load = spring.shape.compliance_load_damping;
            (
                v,
                if load.is_finite() {
                    load.clamp(0.0, v)
                } else {
                    0.0
                },
            )
        })
    }

    /// The simulator model of this fit: the template it was read from (or a default rigid
    /// axis with `gear_ratio = 1`) with the fitted values written in.
    pub fn to_sim(&self) -> sim_plant::Model {
        let mut sim = self.template.clone().unwrap_or_else(|| sim_plant::Model {
            name: self.name.clone(),
            ..sim_plant::Model::default()
        });
        sim.name = self.name.clone();
        sim.axis = self.axis;
        sim.input_unit = self.input_unit.clone();
        let n = sim.plant.gear_ratio.value;
        let b = n * n * sim.motor.damping.value + sim.plant.output_damping.value;
        // Effects removed from the fit are removed from the file.
        for k in sim.effects.kinds() {
            if !self.has(k) {
                sim.effects.remove(k);
            }
        }
        let mut record = FitRecord {
            source: sim.fit.source.clone(),
            inertia_sigma: self.inertia.sigma,
            effects: Default::default(),
        };
        let mut j_far: Option<(f64, bool)> = None;
        for e in &self.effects {
            sim.effects.insert_default(e.kind);
            let amp = |name: &str| e.params.iter().find(|p| p.name == name);
            // The file's viscous term excludes the structural damping b (see `from_sim`).
            let shift = if e.kind == EffectKind::Viscous {
                b
            } else {
                0.0
            };
            let sp = |p: &Param| {
                let mut v = if p.free {
                    SimParam::free(p.value - shift)
                } else {
                    SimParam::fixed(p.value - shift)
                };
                v.min = p.min.map(|m| m - shift);
                v.max = p.max.map(|m| m - shift);
                v
            };
            for (spec, q) in sim.effects.params_mut(e.kind) {
                if let Some(p) = amp(spec.name) {
                    *q = sp(p);
                    continue;
                }
                let set = e
                    .kind
                    .fit_traits()
                    .file_shape
                    .iter()
                    .find(|fs| fs.param == spec.name)
                    .and_then(|fs| (fs.get)(&e.shape, n));
                if let Some(v) = set {
                    q.value = v;
                }
            }
            match e.kind {
                EffectKind::Backlash => j_far = Some((e.params[0].value, e.params[0].free)),
                EffectKind::Compliance if j_far.is_none() => {
                    // α > 0 is refused on saving (see `physical_split`).
                    let alpha = e.params[0].value;
                    let t = &sim.plant.output_inertia;
                    j_far = Some(if alpha < 0.0 && alpha.is_finite() {
                        (
                            load_inertia_of_split(self.inertia.value, alpha),
                            e.params[0].free,
                        )
                    } else if t.value > 0.0 {
                        (t.value, t.free)
                    } else {
                        (0.5 * self.inertia.value, false)
                    });
                }
                _ => {}
            }
            record.effects.insert(
                e.kind.name().to_string(),
                FitEffect {
                    shape: e.shape.clone(),
                    sigma: e
                        .params
                        .iter()
                        .map(|p| p.sigma.unwrap_or(f64::NAN))
                        .collect(),
                },
            );
        }
        // Compliance: K and c from the mode and the split, ω² = K·(1/J1 + 1/J2).
        if let (Some(e), Some((far, _))) = (
            self.effects
                .iter()
                .find(|e| e.kind == EffectKind::Compliance),
            j_far,
        ) {
            let near = self.inertia.value - far;
            if let Some(c) = sim.effects.compliance.as_mut() {
                if far > 0.0 && near > 0.0 && e.shape.compliance_frequency > 0.0 {
                    let (k, damping) = sim_plant::effects::compliance::spring_from_mode(
                        e.shape.compliance_frequency,
                        e.shape.compliance_damping,
                        near,
                        far,
                    );
                    c.stiffness.value = k;
                    c.damping.value = damping;
                    // The motion form's mode damping is the spring's plus the load's drag
                    // (`compliance::motion_column`), and its fit says how much of the viscous
                    // drag sits at the load: the rest is the motor's (sim-plant applies the
                    // viscous effect at the load).
                    if let Some((v, load)) = self.load_drag().filter(|_| n > 0.0) {
                        c.damping.value = (damping - load).max(0.0);
                        let b2 = sim.plant.output_damping.value.clamp(0.0, load);
                        sim.plant.output_damping.value = b2;
                        sim.motor.damping.value = (v - load) / (n * n);
                        if let Some(q) = sim.effects.viscous.as_mut().map(|p| &mut p.damping) {
                            let d = load - b2 - q.value;
                            q.value += d;
                            q.min = q.min.map(|m| m + d);
                            q.max = q.max.map(|m| m + d);
                        }
                    }
                }
                c.stiffness.free = e.params[0].free;
            }
        }
        // Inertia: J = N²·I1 + I_middle + I2.
        if let Some((far, free)) = j_far {
            sim.plant.output_inertia.value = far;
            sim.plant.output_inertia.free = free;
        }
        let rest =
            self.inertia.value - sim.plant.middle_inertia.value - sim.plant.output_inertia.value;
        sim.motor.inertia.value = if n > 0.0 { rest / (n * n) } else { rest };
        sim.motor.inertia.free = self.inertia.free;
        sim.fit = record;
        sim
    }
}

impl EffectEntry {
    /// An effect with free zero amplitudes, except those the effect holds at a physical value
    /// (`FitTraits::held`: stribeck's `hold` is 1, at rest the friction is the applied torque).
    pub fn new(kind: EffectKind, shape: Shape) -> Self {
        let held = kind.fit_traits().held;
        EffectEntry {
            kind,
            shape,
            params: kind
                .param_names()
                .iter()
                .map(|&n| match held.iter().find(|(h, _)| *h == n) {
                    Some(&(_, v)) => Param {
                        free: false,
                        ..Param::free(n, v)
                    },
                    None => Param::free(n, 0.0),
                })
                .collect(),
            shape_sigma: None,
        }
    }
}

/// A `min`/`max` bound the fitter cannot honour, as [`Unfittable::Bound`]: bounds are kept on
/// the effects' amplitudes, each fitted as itself by least squares; the inertia and the
/// structural damping are fitted as sums of several file parameters, shapes are searched on
/// grids, and the other parameters are not fitted at all.
fn refuse_bounds_not_fitted(sim: &sim_plant::Model) -> Result<(), Unfittable> {
    for (path, spec, p) in sim.parameters() {
        if p.min.is_none() && p.max.is_none() {
            continue;
        }
        let amplitude = sim.effects.kinds().iter().any(|k| {
            path.strip_prefix("effects.")
                .and_then(|r| r.strip_prefix(k.name()))
                .and_then(|r| r.strip_prefix('.'))
                .is_some_and(|name| k.param_names().contains(&name))
        });
        if amplitude {
            continue;
        }
        let why = if path.starts_with("effects.") {
            "it is a shape, searched on a grid, not fitted by least squares"
        } else if matches!(
            spec.name,
            "inertia" | "middle_inertia" | "output_inertia" | "damping" | "output_damping"
        ) {
            "the fitter fits the rigid inertia N²·I1 + I_middle + I2 and the structural damping \
             as one number each, not this part of them"
        } else {
            "the fitter does not fit it"
        };
        return Err(Unfittable::Bound {
            parameter: path,
            why,
        });
    }
    Ok(())
}

/// The load inertia J2 of a rigid inertia `j` split by compliance's amplitude α = −J2/J1:
/// J2 = J·|α|/(1 + |α|) (α < 0).
fn load_inertia_of_split(j: f64, alpha: f64) -> f64 {
    let ratio = -alpha;
    j * ratio / (1.0 + ratio)
}

/// The inverse of [`load_inertia_of_split`]: α = −J2/J1 with J1 = J − J2.
fn split_of_load_inertia(j: f64, j2: f64) -> f64 {
    -j2 / (j - j2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fitted() -> Model {
        let mut m = Model::baseline();
        m.inertia.value = 95.1;
        m.inertia.sigma = Some(0.2);
        m.effects[0].params[0].value = 203.5;
        m.add(EffectKind::Coulomb, Shape::default());
        m.effects[1].params[0].value = 20.39;
        m.effects[1].shape.sign_epsilon = 2.5e-4;
        m.effects[1].shape.sign_lead = -1.5e-3;
        m.add(EffectKind::Offset, Shape::default());
        m.effects[2].params[0].value = -3.16;
        m.effects[2].params[0].sigma = Some(0.21);
        let shape = Shape {
            stribeck_velocity: 0.013,
            stribeck_exponent: 1.0,
            ..Shape::default()
        };
        m.add(EffectKind::Stribeck, shape);
        m.effects[3].params[0].value = 4.5;
        m.effects[3].params[0].free = false;
        m
    }

    /// `physical` is what `--auto` and `save` rely on: a quantiser gain (fraction of the
    /// rounding error present, physical range [0, 1]) fitted to 1.07 is refused with the
    /// parameter's name; 0.9 passes.
    #[test]
    fn physical_names_the_parameter_out_of_range() {
        let mut m = fitted();
        m.add(
            EffectKind::Quantization,
            Shape {
                quantum: 0.05,
                ..Shape::default()
            },
        );
        let q = m.effects.len() - 1;
        m.effects[q].params[0].value = 0.9;
        assert_eq!(m.physical(), Ok(()));
        m.effects[q].params[0].value = 1.07;
        let err = m
            .physical()
            .expect_err("gain 1.07 is outside [0, 1]")
            .to_string();
        assert!(err.contains("gain"), "{err}");
        let dir = std::env::temp_dir().join(format!("jointlab-phys-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("q.toml");
        assert!(m.save(&f).is_err());
        assert!(!f.exists(), "an unphysical model must not be written");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_fit_round_trips_through_the_simulators_model_file() {
        let m = fitted();
        let text = m.to_sim().to_toml_string();
        let sim = sim_plant::Model::from_toml_str(&text, "fit.toml").unwrap();
        // The simulator sees the physics as its own parameters …
        let c = sim.effects.coulomb.as_ref().unwrap();
        assert_eq!(c.torque.value, 20.39);
        assert!(c.torque.free);
        let s = sim.effects.stribeck.as_ref().unwrap();
        assert_eq!((s.excess.value, s.velocity.value), (4.5, 0.013));
        assert!(!s.excess.free);
        assert_eq!(sim.plant.gear_ratio.value, 1.0);
        assert_eq!(sim.motor.inertia.value, 95.1);
        // … and the fitter gets back what it wrote, analysis shapes and 1σ included.
        assert!(text.contains("sign_lead"), "{text}");
        let back = Model::from_sim(&sim).unwrap();
        assert_eq!(back.inertia.value, 95.1);
        assert_eq!(back.inertia.sigma, Some(0.2));
        assert_eq!(back.effects.len(), 4);
        for (a, b) in m.effects.iter().zip(&back.effects) {
            // File order is the library's order; match by kind.
            let b = back.effects.iter().find(|e| e.kind == a.kind).unwrap_or(b);
            assert_eq!(a.shape, b.shape, "{}", a.kind.name());
            assert_eq!(a.params, b.params, "{}", a.kind.name());
        }
    }

    /// A parameter fixed in the file is given, not estimated: the σ its fit record holds
    /// (for the value fitted then) is not shown against it.
    #[test]
    fn a_fixed_parameter_has_no_sigma() {
        let mut m = fitted();
        m.inertia.free = false;
        let sim = sim_plant::Model::from_toml_str(&m.to_sim().to_toml_string(), "f.toml").unwrap();
        let back = Model::from_sim(&sim).unwrap();
        assert_eq!(back.inertia.sigma, None);
        let offset = back
            .effects
            .iter()
            .find(|e| e.kind == EffectKind::Offset)
            .unwrap();
        assert_eq!(offset.params[0].sigma, Some(0.21));
    }

    /// Removing an effect takes it out of the name too (the name lists what a saved model
    /// holds), and only that one.
    #[test]
    fn remove_keeps_the_name_true() {
        let mut m = Model::baseline();
        m.add(EffectKind::Coulomb, Shape::default());
        m.add(EffectKind::Offset, Shape::default());
        let before = m.name.clone();
        let e = m.remove(1);
        assert_eq!(e.kind, EffectKind::Coulomb);
        assert_eq!(m.name, before.replace(" + coulomb", ""));
        assert!(m.name.ends_with(" + offset"), "{}", m.name);
    }

    /// J = 0.03 with a 25 Hz, ζ = 0.05 compliance (amplitude 0 until a test sets it).
    fn compliant() -> Model {
        let mut m = Model::baseline();
        m.inertia.value = 0.03;
        let shape = Shape {
            compliance_frequency: 25.0,
            compliance_damping: 0.05,
            ..Shape::default()
        };
        m.add(EffectKind::Compliance, shape);
        m
    }

    /// A model file holds one load inertia: a positive compliance amplitude (no two-mass
    /// plant) and a backlash whose J2 disagrees with compliance's split are refused, naming
    /// the parameter, rather than saved as a different model.
    #[test]
    fn a_split_no_file_can_hold_is_refused() {
        let mut m = compliant();
        m.effects[1].params[0].value = 0.5;
        let e = m.physical().unwrap_err().to_string();
        assert!(e.contains("inertia_ratio") && e.contains("positive"), "{e}");
        let path = std::env::temp_dir().join(format!("jointlab-split-{}.toml", std::process::id()));
        assert!(m.save(&path).is_err() && !path.exists());
        m.effects[1].params[0].value = -0.5; // J2 = 0.01
        assert!(m.physical().is_ok());
        m.add(EffectKind::Backlash, Shape::default());
        m.effects[2].params[0].value = 0.02;
        let e = m.physical().unwrap_err().to_string();
        assert!(e.contains("load_inertia"), "{e}");
        m.effects[2].params[0].value = 0.01;
        assert!(m.physical().is_ok(), "{:?}", m.physical());
    }

    #[test]
    fn compliance_maps_to_the_inertia_split_and_the_spring_of_its_mode() {
        let mut m = compliant();
        let e = m.effects.last_mut().unwrap();
        e.params[0].value = -0.5; // J2/J1 = 1/2
        let sim = m.to_sim();
        // J2 = J·0.5/1.5 = 0.01, J1 = 0.02.
        assert!((sim.plant.output_inertia.value - 0.01).abs() < 1e-12);
        assert!((sim.motor.inertia.value - 0.02).abs() < 1e-12);
        let c = sim.effects.compliance.as_ref().unwrap();
        let w = std::f64::consts::TAU * 25.0;
        let jr = 0.02 * 0.01 / 0.03;
        assert!((c.stiffness.value - w * w * jr).abs() < 1e-9 * w * w * jr);
        assert!((c.damping.value - 2.0 * 0.05 * w * jr).abs() < 1e-9);
        // Read back through the file: the same amplitude and mode.
        let text = sim.to_toml_string();
        let sim = sim_plant::Model::from_toml_str(&text, "c.toml").unwrap();
        let back = Model::from_sim(&sim).unwrap();
        let e = back
            .effects
            .iter()
            .find(|e| e.kind == EffectKind::Compliance)
            .unwrap();
        assert!(
            (e.params[0].value + 0.5).abs() < 1e-9,
            "{}",
            e.params[0].value
        );
        assert!((e.shape.compliance_frequency - 25.0).abs() < 1e-9);
        assert!((e.shape.compliance_damping - 0.05).abs() < 1e-9);
        assert!((back.inertia.value - 0.03).abs() < 1e-12);
    }

    /// Compliance's motion form holds the load's share of the viscous drag: through the file
    /// it is the load's friction, the rest is the motor's, and the model comes back as fitted.
    /// A share larger than the drag (the drag refitted lower since) puts the whole drag at the
    /// load; the column keeps its own value.
    #[test]
    fn the_load_drag_of_the_motion_form_round_trips_through_the_file() {
        for (load, kept) in [(0.03, 0.03), (0.15, 0.1)] {
            let mut m = compliant();
            assert_eq!(m.effects[0].kind, EffectKind::Viscous);
            m.effects[0].params[0].value = 0.1;
            let e = &mut m.effects[1];
            e.params[0].value = -0.5;
            e.shape.compliance_near_inertia = 0.02;
            e.shape.compliance_ratio = 0.5;
            e.shape.compliance_load_damping = load;
            let text = m.to_sim().to_toml_string();
            let sim = sim_plant::Model::from_toml_str(&text, "c.toml").unwrap();
            let at_load = sim.plant.output_damping.value
                + sim.effects.viscous.as_ref().unwrap().damping.value;
            assert!((at_load - kept).abs() < 1e-12, "{at_load}\n{text}");
            assert!(
                (sim.motor.damping.value - (0.1 - kept)).abs() < 1e-12,
                "{text}"
            );
            let w = std::f64::consts::TAU * 25.0;
            let c_mode = 2.0 * 0.05 * w * (0.02 * 0.01 / 0.03);
            let spring = sim.effects.compliance.as_ref().unwrap().damping.value;
            assert!((spring - (c_mode - kept)).abs() < 1e-12, "{spring}");
            let back = Model::from_sim(&sim).unwrap();
            let e = back.effect(EffectKind::Compliance).unwrap();
            assert!((e.shape.compliance_frequency - 25.0).abs() < 1e-9);
            assert!((e.shape.compliance_damping - 0.05).abs() < 1e-9);
            // The column's own value comes back as fitted (the file's split is capped).
            assert_eq!(e.shape.compliance_load_damping, load);
            let viscous = back.effect(EffectKind::Viscous).unwrap();
            assert!((viscous.params[0].value - 0.1).abs() < 1e-12);
            // A file of the older layout (the whole drag at the load, the mode's damping in
            // the spring) reads back as the same model: its fit record's mode tells it.
            let mut old = sim.clone();
            old.effects.compliance.as_mut().unwrap().damping.value = c_mode;
            old.effects.viscous.as_mut().unwrap().damping.value = 0.1;
            old.motor.damping.value = 0.0;
            let back = Model::from_sim(&old).unwrap();
            let e = back.effect(EffectKind::Compliance).unwrap();
            assert!((e.shape.compliance_damping - 0.05).abs() < 1e-9);
        }
    }

    #[test]
    fn a_preset_loads_as_its_rigid_equation_error_view() {
        let sim = sim_plant::presets::preset("whoi-cable-30").unwrap();
        let n = sim.plant.gear_ratio.value;
        let m = Model::from_sim(&sim).unwrap();
        let j = n * n * sim.motor.inertia.value
            + sim.plant.middle_inertia.value
            + sim.plant.output_inertia.value;
        assert!((m.inertia.value - j).abs() <= 1e-12 * j);
        for k in sim.effects.kinds() {
            assert!(m.has(k), "{}", k.name());
        }
        if let Some(c) = &sim.effects.coulomb {
            let e = m
                .effects
                .iter()
                .find(|e| e.kind == EffectKind::Coulomb)
                .unwrap();
            assert_eq!(e.params[0].value, c.torque.value);
        }
        // Written back, the gear ratio, sensors and settings are kept.
        let again = m.to_sim();
        assert_eq!(again.plant.gear_ratio, sim.plant.gear_ratio);
        assert_eq!(again.sensors, sim.sensors);
        let rel =
            (again.motor.inertia.value - sim.motor.inertia.value).abs() / sim.motor.inertia.value;
        assert!(rel < 1e-9, "motor inertia {rel}");
    }

    #[test]
    fn an_unphysical_fit_is_not_written_and_the_error_names_the_parameter() {
        let mut m = fitted();
        m.effects[1].params[0].value = -1.0; // negative Coulomb level
        let dir = std::env::temp_dir().join(format!("wb-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.toml");
        let err = m.save(&path).unwrap_err().to_string();
        assert!(err.contains("torque") && err.contains("bad.toml"), "{err}");
        assert!(!path.exists());
    }

    #[test]
    fn a_bad_model_file_is_reported_with_line_and_column() {
        let dir = std::env::temp_dir().join(format!("wb-model-l-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.toml");
        std::fs::write(&path, "name = \"x\"\n[effects.coulomb]\ntorque = \"abc\"\n").unwrap();
        let err = Model::load(&path).unwrap_err().to_string();
        assert!(err.contains("m.toml") && err.contains(":3:"), "{err}");
    }
}
