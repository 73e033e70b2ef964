//! The thesis's transmissions as ready-made models.
//!
//! The table lives in ONE data file, `presets/transmissions.toml` (embedded at compile time),
//! holding Tables 4.1/4.2 rows in the thesis's own units plus every assumed number with its
//! reason. This module only converts a row into a [`Model`]; [`preset_toml`] writes the model
//! file for a preset, which loads back with [`Model::from_toml_str`].

use std::f64::consts::{PI, TAU};
use std::sync::OnceLock;

use serde::Deserialize;

use crate::effects::{
    asymmetry, backlash, cogging, compliance, coulomb, ripple, stribeck, viscous, EffectSet,
};
use crate::model::sections;
use crate::model::Model;
use crate::param::Param;

/// The embedded table.
pub const TABLE_TOML: &str = include_str!("../presets/transmissions.toml");

/// `[motor]` of the table: the SEIBERCO Sensorimotor.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorRow {
    /// N·m at the motor.
    pub max_torque: f64,
    /// Encoder counts per motor rev.
    pub counts_per_rev: f64,
    /// Cogging amplitude, N·m at the motor.
    pub cogging_amplitude: f64,
    /// Cogging cycles per motor rev.
    pub cogging_cycles: f64,
}

/// `[defaults]` of the table: assumptions shared by all rows.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Defaults {
    /// kg·m².
    pub output_inertia: f64,
    /// Damping ratio of the locked-output transmission mode.
    pub damping_ratio: f64,
    /// rad/s.
    pub stribeck_velocity: f64,
    /// Stribeck exponent.
    pub stribeck_exponent: f64,
    /// N·m per LSB.
    pub torque_resolution: f64,
    /// N·m rms.
    pub torque_noise: f64,
    /// rad/s at the motor.
    pub velocity_resolution: f64,
}

/// One `[[transmission]]` row (thesis units; see the data file for each field's source).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransmissionRow {
    /// Preset name.
    pub name: String,
    /// Human title.
    pub title: String,
    /// Gear ratio N.
    pub ratio: f64,
    /// Stiction [+, −] magnitudes, N·m (Table 4.1).
    pub stiction: [f64; 2],
    /// Coulomb [+, −] magnitudes, N·m (Table 4.1).
    pub coulomb: [f64; 2],
    /// Viscous [+, −], N·m/(deg/s) (Table 4.1).
    pub viscous_deg: [f64; 2],
    /// Stiffness [min, max], N·m/rad (Table 4.2).
    pub stiffness: [f64; 2],
    /// Soft-zone knee torque, N·m.
    pub knee: f64,
    /// Backlash, degrees at the output.
    pub backlash_deg: f64,
    /// Input inertia at the motor shaft, kg·m².
    pub input_inertia: f64,
    /// Ks/KT(max) for a 3-mass plant; 0 = 2-mass.
    pub proximal_ratio: f64,
    /// Middle-stage inertia, output-referred, kg·m².
    pub middle_inertia: f64,
    /// Ripple amplitude per N·m of transmitted torque.
    pub ripple_fraction: f64,
    /// Ripple amplitude at no load, N·m.
    pub ripple_floor: f64,
    /// Ripple periods per output revolution.
    pub ripple_periods_per_rev: f64,
}

impl TransmissionRow {
    /// Viscous [+, −] in N·m·s/rad.
    pub fn viscous(&self) -> [f64; 2] {
        let k = 180.0 / PI;
        [self.viscous_deg[0] * k, self.viscous_deg[1] * k]
    }

    /// Backlash in rad.
    pub fn backlash(&self) -> f64 {
        self.backlash_deg.to_radians()
    }
}

/// The whole table.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    /// Motor data.
    pub motor: MotorRow,
    /// Shared assumptions.
    pub defaults: Defaults,
    /// The transmissions.
    pub transmission: Vec<TransmissionRow>,
}

/// The parsed table (parsed once; the embedded file is checked by the tests).
pub fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(|| match toml::from_str(TABLE_TOML) {
        Ok(t) => t,
        Err(e) => panic!("embedded presets/transmissions.toml is invalid: {e}"),
    })
}

/// Names of all presets, in table order.
pub fn preset_names() -> Vec<&'static str> {
    table()
        .transmission
        .iter()
        .map(|r| r.name.as_str())
        .collect()
}

/// The table row of a preset.
pub fn row(name: &str) -> Option<&'static TransmissionRow> {
    table().transmission.iter().find(|r| r.name == name)
}

/// A preset as a model, or `None` for an unknown name.
pub fn preset(name: &str) -> Option<Model> {
    let t = table();
    row(name).map(|r| build(&t.motor, &t.defaults, r))
}

/// The model file text of a preset.
pub fn preset_toml(name: &str) -> Option<String> {
    preset(name).map(|m| m.to_toml_string())
}

fn fixed(v: f64) -> Param {
    Param::fixed(v)
}

/// Row → model. The conversions (signs, ± split into coulomb + asymmetry, series stiffness
/// split for the 3-mass cable) are the only logic here.
fn build(motor: &MotorRow, d: &Defaults, r: &TransmissionRow) -> Model {
    let n = r.ratio;
    let i1_reflected = n * n * r.input_inertia;

    // Stiffness: 2-mass takes Table 4.2 directly; the 3-mass cable splits the measured series
    // stiffness 1/K = 1/Ks + 1/KT with Ks = ρ·KT(max), so both min and max are reproduced.
    let [kmin, kmax] = r.stiffness;
    let (ks, kt_soft, kt_hard) = if r.proximal_ratio > 0.0 {
        let kt_hard = kmax * (1.0 + 1.0 / r.proximal_ratio);
        let ks = r.proximal_ratio * kt_hard;
        let kt_soft = 1.0 / (1.0 / kmin - 1.0 / ks);
        (ks, kt_soft, kt_hard)
    } else {
        (0.0, kmin, kmax)
    };
    // Structural damping for ζ of the locked-output mode on the stiff branch.
    let k_locked = kmax;
    let damping = 2.0 * d.damping_ratio * (k_locked * i1_reflected).sqrt();

    let mut effects = EffectSet::default();
    let [sp, sn] = r.stiction;
    let [cp, cn] = r.coulomb;
    let [bp, bn] = r.viscous();
    effects.coulomb = Some(coulomb::Params { torque: fixed(cn) });
    effects.stribeck = Some(stribeck::Params {
        excess: fixed(sn - cn),
        velocity: fixed(d.stribeck_velocity),
        exponent: fixed(d.stribeck_exponent),
    });
    effects.viscous = Some(viscous::Params { damping: fixed(bn) });
    let asym = asymmetry::Params {
        coulomb_extra: fixed(cp - cn),
        viscous_extra: fixed(bp - bn),
        stiction_extra: fixed((sp - cp) - (sn - cn)),
    };
    if asym != asymmetry::Params::default() {
        effects.asymmetry = Some(asym);
    }
    effects.compliance = Some(compliance::Params {
        stiffness: fixed(kt_hard),
        soft_stiffness: fixed(kt_soft),
        knee: fixed(r.knee),
        damping: fixed(damping),
    });
    if r.backlash_deg > 0.0 {
        effects.backlash = Some(backlash::Params {
            width: fixed(r.backlash()),
        });
    }
    if r.ripple_floor > 0.0 {
        effects.ripple = Some(ripple::Params {
            sin: fixed(r.ripple_floor),
            cos: fixed(0.0),
            period: fixed(TAU / r.ripple_periods_per_rev),
            load_gain: fixed(r.ripple_fraction / r.ripple_floor),
        });
    }
    effects.cogging = Some(cogging::Params {
        sin: fixed(motor.cogging_amplitude * n),
        cos: fixed(0.0),
        cycles_per_rev: fixed(motor.cogging_cycles),
    });

    let mut plant = sections::plant::Params {
        gear_ratio: fixed(n),
        output_inertia: fixed(d.output_inertia),
        ..Default::default()
    };
    if ks > 0.0 {
        plant.middle_inertia = fixed(r.middle_inertia);
        plant.proximal_stiffness = fixed(ks);
        // Same damping ratio on the proximal stage.
        plant.proximal_damping = fixed(2.0 * d.damping_ratio * (ks * i1_reflected).sqrt());
    }
    Model {
        name: r.name.clone(),
        description: format!(
            "{} — Schempf 1990 Tables 4.1/4.2 via sim-plant/presets/transmissions.toml \
             (assumed numbers are marked there)",
            r.title
        ),
        axis: None,
        input_unit: None,
        motor: sections::motor::Params {
            inertia: fixed(r.input_inertia),
            damping: fixed(0.0),
            max_torque: fixed(motor.max_torque),
            counts_per_rev: fixed(motor.counts_per_rev),
        },
        plant,
        sensors: sections::sensors::Params {
            output_counts_per_rev: fixed(0.0),
            torque_resolution: fixed(d.torque_resolution),
            torque_noise: fixed(d.torque_noise),
            velocity_resolution: fixed(d.velocity_resolution),
            delay: fixed(0.0),
        },
        effects,
        fit: Default::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_parses_and_every_preset_round_trips_through_toml() {
        let names = preset_names();
        assert_eq!(names.len(), 8);
        for name in names {
            let m = preset(name).unwrap();
            let text = preset_toml(name).unwrap();
            let back = Model::from_toml_str(&text, name).unwrap();
            assert_eq!(back, m, "{name}");
            assert!(
                crate::plant::Plant::new(&m, Default::default()).is_ok(),
                "{name}"
            );
        }
        assert!(preset("nope").is_none());
    }

    #[test]
    fn cable_is_three_mass_and_split_reproduces_series_stiffness() {
        let m = preset("whoi-cable-30").unwrap();
        assert_eq!(m.kind(), crate::model::PlantKind::ThreeMass);
        let ks = m.plant.proximal_stiffness.value;
        let c = m.effects.compliance.as_ref().unwrap();
        let series = |kt: f64| 1.0 / (1.0 / ks + 1.0 / kt);
        assert!((series(c.soft_stiffness.value) - 4100.0).abs() < 1e-6);
        assert!((series(c.stiffness.value) - 5150.0).abs() < 1e-6);
        assert!((ks / c.stiffness.value - 1.8).abs() < 1e-12);
    }
}
