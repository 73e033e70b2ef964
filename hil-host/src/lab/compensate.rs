//! What a model's fitted effects become on the card (thesis §2.11–2.12, run here at 1 kHz on
//! the card instead of 10 Hz from the supervisor).
//!
//! A model file states every effect as a *resisting* torque `R` in its own frame: torques at
//! the model's output, angles of that output, `gear_ratio` motor turns per output turn (1 for
//! a model fitted to a motor encoder and a motor command). The card cancels `R` by adding it
//! to its command, motor side. Each effect maps to the one card term that can carry it:
//!
//! | effect | card term |
//! |---|---|
//! | coulomb, asymmetry, viscous (and the model's plain dampings) | friction compensation, × `under` |
//! | ripple, cogging | the ripple table (one table: harmonics of its period share it) |
//! | gravity | the gravity feed-forward, when its period is one output turn of the joint; else the ripple table |
//! | offset | the constant feed-forward |
//!
//! Everything else (stiction, backlash, compliance, delay, …) is named in [`Compensation::left_out`]
//! with the reason, never dropped silently.

use std::f64::consts::TAU;

use anyhow::{bail, Result};
use sim_plant::Model;

use super::gains::{Feedforward, FrictionComp, JointScale, RippleFf, RIPPLE_ENTRIES};

/// The under-compensation factor the thesis recommends ("slightly below" the measured friction).
pub const DEFAULT_UNDER: f64 = 0.8;

/// Entries of a ripple table made from a model: half the card's 64, so a gain set with it
/// fits the card's staging (96 entries); a sinusoid is then within 0.5 % between entries.
pub const TABLE_ENTRIES: usize = 32;

/// Cut-off of the friction compensation's velocity low-pass: below the rotor's mode against
/// a transmission (≈ 9 Hz for the thesis's harmonic drive), above a tracking task's motion.
pub const FRICTION_FILTER_HZ: f64 = 2.0;

/// A periodic resisting torque in motor angle: `s·sin(2πθ/P) + c·cos(2πθ/P)`, motor N·m.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Periodic {
    name: &'static str,
    period_rad: f64,
    sin: f64,
    cos: f64,
}

/// A model turned into card terms for one joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Compensation {
    /// Friction feed-forward (output side, as [`super::gains::GainSet`] takes it).
    pub friction: Option<FrictionComp>,
    /// Offset, gravity and ripple feed-forward.
    pub feedforward: Feedforward,
    /// One line per effect compensated: what goes where, in the card's terms.
    pub applied: Vec<String>,
    /// One line per effect of the model the card does not compensate, and why.
    pub left_out: Vec<String>,
}

impl Compensation {
    /// Translates `model` for `joint`. `under` scales the friction terms (0 < under ≤ 1).
    /// Errors name what cannot be represented (a period shorter than the table, an amplitude
    /// above the motor's torque).
    pub fn from_model(model: &Model, joint: &JointScale, under: f64) -> Result<Compensation> {
        if !(under > 0.0 && under <= 1.0) {
            bail!(
                "--under must be in (0, 1] (the thesis's \"slightly below\" is 0.8), got {under}"
            );
        }
        let nm = model.plant.gear_ratio.value;
        if !(nm.is_finite() && nm > 0.0) {
            bail!("the model's gear_ratio {nm} is not a positive number");
        }
        let nj = joint.gear_ratio();
        let cpr = joint.motor_cpr();
        let fx = &model.effects;
        let mut applied = vec![];
        let mut left_out = vec![];
        // Model-output torque → motor torque, and model-output rad → motor rad.
        let motor_torque = |t: f64| t / nm;

        // --- friction ---
        let coulomb = fx.coulomb.as_ref().map_or(0.0, |c| c.torque.value);
        let (c_extra, b_extra) = fx.asymmetry.as_ref().map_or((0.0, 0.0), |a| {
            (a.coulomb_extra.value, a.viscous_extra.value)
        });
        let viscous_model =
            fx.viscous.as_ref().map_or(0.0, |v| v.damping.value) + model.plant.output_damping.value;
        // motor N·m·s/rad: the output's damping seen through the ratio twice, the motor's as is
        let viscous_motor = viscous_model / (nm * nm) + model.motor.damping.value;
        let (cpos, cneg) = (motor_torque(coulomb + c_extra), motor_torque(coulomb));
        // The card has one viscous coefficient: the mean of the two directions'.
        let viscous_motor = viscous_motor + 0.5 * b_extra / (nm * nm);
        let friction = if cpos != 0.0 || cneg != 0.0 || viscous_motor != 0.0 {
            if cpos < 0.0 || cneg < 0.0 || viscous_motor < 0.0 {
                left_out.push(format!(
                    "friction below zero (Coulomb +{} / −{} N·m, viscous {} N·m·s/rad at the \
                     motor): a fit's artefact, not a friction; the card compensates only what is \
                     above zero",
                    fmt(cpos),
                    fmt(cneg),
                    fmt(viscous_motor)
                ));
            }
            let (cpos, cneg, viscous_motor) =
                (cpos.max(0.0), cneg.max(0.0), viscous_motor.max(0.0));
            applied.push(format!(
                "friction: Coulomb +{} / −{} N·m, viscous {} N·m·s/rad (motor side), × {under} \
                 (under-compensation)",
                fmt(cpos),
                fmt(cneg),
                fmt(viscous_motor)
            ));
            if b_extra != 0.0 {
                left_out.push(format!(
                    "asymmetry of viscous friction ({} N·m·s/rad at the model's output): the \
                     card has one viscous coefficient, the mean of the two directions' is used",
                    fmt(b_extra)
                ));
            }
            // The ramp through zero: one count per tick, the velocity estimate's resolution.
            let ramp_motor = TAU / cpr / joint.period_s();
            Some(FrictionComp {
                coulomb_pos: cpos * nj,
                coulomb_neg: cneg * nj,
                viscous: viscous_motor * nj * nj,
                under,
                ramp_velocity: ramp_motor / nj,
                filter_hz: FRICTION_FILTER_HZ,
                on_setpoint: false,
            })
        } else {
            None
        };

        // --- position-dependent loads ---
        let mut ff = Feedforward {
            offset: fx
                .offset
                .as_ref()
                .map_or(0.0, |o| motor_torque(o.torque.value))
                * nj,
            ..Feedforward::default()
        };
        if ff.offset != 0.0 {
            applied.push(format!(
                "offset: {} N·m (motor side), constant feed-forward",
                fmt(ff.offset / nj)
            ));
        }
        let mut periodic = vec![];
        if let Some(r) = &fx.ripple {
            periodic.push(Periodic {
                name: "ripple",
                period_rad: r.period.value * nm,
                sin: motor_torque(r.sin.value),
                cos: motor_torque(r.cos.value),
            });
            if r.load_gain.value != 0.0 {
                left_out.push(format!(
                    "ripple's growth with load ({} per N·m): the table holds the amplitude at \
                     no load",
                    fmt(r.load_gain.value)
                ));
            }
        }
        if let Some(c) = &fx.cogging {
            periodic.push(Periodic {
                name: "cogging",
                period_rad: TAU / c.cycles_per_rev.value,
                sin: motor_torque(c.sin.value),
                cos: motor_torque(c.cos.value),
            });
        }
        if let Some(g) = &fx.gravity {
            let (s, c) = (motor_torque(g.sin.value), motor_torque(g.cos.value));
            // Gravity acts on the model's output angle; the card's gravity term on one output
            // turn of this joint. Where they are the same turn it goes there.
            if (nm - nj).abs() <= 1e-6 * nj {
                ff.gravity_sin = s * nj;
                ff.gravity_cos = c * nj;
                applied.push(format!(
                    "gravity: {} N·m (motor side) at the output angle {:.1}° from motor count 0, \
                     gravity feed-forward",
                    fmt(s.hypot(c)),
                    c.atan2(s).to_degrees()
                ));
            } else {
                periodic.push(Periodic {
                    name: "gravity",
                    period_rad: TAU * nm,
                    sin: s,
                    cos: c,
                });
            }
        }
        ff.ripple = ripple_table(&periodic, joint, &mut applied, &mut left_out)?;
        if let Some(r) = &mut ff.ripple {
            for v in r.table.iter_mut() {
                *v *= nj;
            }
        }

        // --- what the card does not do ---
        if let Some(s) = &fx.stribeck {
            left_out.push(format!(
                "stribeck (stiction {} N·m above Coulomb at the model's output): a stiction \
                 feed-forward switches a large torque at zero speed and limit-cycles (thesis \
                 §2.11); the card's friction ramp under-compensates there on purpose",
                fmt(s.excess.value)
            ));
        }
        if let Some(b) = &fx.backlash {
            left_out.push(format!(
                "backlash ({} rad): lost motion is not a torque to cancel; the card does not \
                 compensate it (keep the under-compensation below 1: thesis §5's limit cycle)",
                fmt(b.width.value)
            ));
        }
        if let Some(c) = &fx.compliance {
            left_out.push(format!(
                "compliance ({} N·m/rad): the card's impedance compensation corrects the \
                 torque-sensor error against a desired stiffness, not a transmission spring; \
                 with an output encoder, a non-colocated mode acts on the output itself",
                fmt(c.stiffness.value)
            ));
        }
        for (present, name, why) in [
            (
                fx.delay.is_some(),
                "delay",
                "a transport delay is the actuator's; feed-forward cannot advance time",
            ),
            (
                fx.deadband.is_some(),
                "deadband",
                "an actuator deadband is not compensated by the card",
            ),
            (
                fx.quantization.is_some(),
                "quantization",
                "D/A steps and measurement fuzz are not a torque to cancel",
            ),
        ] {
            if present {
                left_out.push(format!("{name}: {why}"));
            }
        }
        let peak = friction.map_or(0.0, |f| f.coulomb_pos.max(f.coulomb_neg) * f.under)
            + ff.offset.abs()
            + ff.gravity_sin.hypot(ff.gravity_cos)
            + ff.ripple.map_or(0.0, |r| {
                r.table[..r.len].iter().fold(0.0f64, |m, v| m.max(v.abs()))
            });
        let max_out = model.motor.max_torque.value * nj;
        if peak > max_out {
            bail!(
                "the compensation asks for up to {} N·m at the output before any control, more \
                 than the motor's {} N·m: the model does not fit this joint",
                fmt(peak),
                fmt(max_out)
            );
        }
        Ok(Compensation {
            friction,
            feedforward: ff,
            applied,
            left_out,
        })
    }
}

impl Compensation {
    /// Caps the viscous feed-forward at half the damping of `gains` (law + input damping):
    /// `+u·Bv·ẋ1` is negative damping on the rotor, whose fast mode does not feel the
    /// friction it cancels beyond the transmission, so a full cancellation of a large viscous
    /// friction would leave the rotor undamped (the card's guard refuses that set). Noted in
    /// [`Compensation::left_out`] when it bites.
    pub fn within_damping(&mut self, gains: &super::gains::GainSet) {
        let Some(f) = &mut self.friction else {
            return;
        };
        let cap = 0.5 * (gains.damping + gains.input_damping) / f.under;
        if f.viscous > cap {
            self.left_out.push(format!(
                "viscous friction: {} of its {} N·m·s/rad (output side) compensated; more                  would take over half the loop's damping ({} N·m·s/rad) from the rotor",
                fmt(cap),
                fmt(f.viscous),
                fmt(gains.damping + gains.input_damping)
            ));
            f.viscous = cap;
        }
    }
}

/// Numbers in messages: four significant digits.
fn fmt(v: f64) -> String {
    jointlab_workbench::units::eng(v)
}

/// The periodic terms in one table over the longest period: the others must repeat a whole
/// number of times in it with at least 4 entries per cycle; a term that does not is left out
/// and named.
fn ripple_table(
    terms: &[Periodic],
    joint: &JointScale,
    applied: &mut Vec<String>,
    left_out: &mut Vec<String>,
) -> Result<Option<RippleFf>> {
    let counts_per_rad = joint.motor_cpr() / TAU;
    let Some(base) = terms
        .iter()
        .copied()
        .max_by(|a, b| a.period_rad.total_cmp(&b.period_rad))
    else {
        return Ok(None);
    };
    let period = (base.period_rad * counts_per_rad).round();
    if !(period >= 2.0 && period <= f64::from(i32::MAX as u32)) {
        bail!(
            "{}: a period of {} motor rad is {period} encoder counts, outside the card's \
             ripple table (2 counts to 2³¹)",
            base.name,
            fmt(base.period_rad)
        );
    }
    let len = (period as usize).min(TABLE_ENTRIES);
    let mut table = [0.0; RIPPLE_ENTRIES];
    for t in terms {
        let cycles = base.period_rad / t.period_rad;
        let whole = cycles.round();
        if (cycles - whole).abs() > 1e-3 * cycles || len as f64 / whole < 4.0 {
            left_out.push(format!(
                "{}: its period ({} motor rad) is not a whole fraction of the {}'s that a \
                 {len}-entry table resolves; the card has one ripple table",
                t.name,
                fmt(t.period_rad),
                base.name
            ));
            continue;
        }
        for (i, v) in table.iter_mut().take(len).enumerate() {
            let a = TAU * whole * i as f64 / len as f64;
            *v += t.sin * a.sin() + t.cos * a.cos();
        }
        applied.push(format!(
            "{}: {} N·m (motor side) every {} motor rad ({} counts), ripple table",
            t.name,
            fmt(t.sin.hypot(t.cos)),
            fmt(t.period_rad),
            fmt(t.period_rad * counts_per_rad)
        ));
    }
    if table.iter().all(|v| *v == 0.0) {
        return Ok(None);
    }
    Ok(Some(RippleFf {
        period_counts: period as u32,
        len,
        table,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_plant::presets;

    fn joint(m: &Model) -> JointScale {
        super::super::scenario::joint_scale(m)
    }

    /// A preset's own model, translated for its own joint, gives back the preset's numbers:
    /// the table's Coulomb (output N·m) and its ripple at the tooth period.
    #[test]
    fn a_preset_translates_to_its_own_numbers() {
        let m = presets::preset("harmonic-drive-60").unwrap();
        let c = Compensation::from_model(&m, &joint(&m), 0.8).unwrap();
        let f = c.friction.unwrap();
        let truth = m.effects.coulomb.as_ref().unwrap().torque.value;
        let extra = m
            .effects
            .asymmetry
            .as_ref()
            .map_or(0.0, |a| a.coulomb_extra.value);
        assert!((f.coulomb_neg - truth).abs() < 1e-9 * truth);
        assert!((f.coulomb_pos - truth - extra).abs() < 1e-9 * truth);
        let r = c.feedforward.ripple.unwrap();
        // 120 teeth per output turn at 60:1: two periods per motor turn.
        assert_eq!(r.period_counts, 1152);
        let rip = m.effects.ripple.as_ref().unwrap();
        let amp = rip.sin.value.hypot(rip.cos.value);
        let peak = r.table.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        // The motor's cogging (9 cycles per motor turn, 4.5 per ripple period) cannot share
        // the table: it is left out, and named.
        assert!(c.left_out.iter().any(|l| l.starts_with("cogging")));
        assert!(peak >= 0.95 * amp, "{peak} vs {amp}");
        assert!(
            c.left_out.iter().any(|l| l.starts_with("stribeck")),
            "{:?}",
            c.left_out
        );
    }

    #[test]
    fn bad_under_is_refused_and_negative_friction_left_out() {
        let mut m = presets::preset("harmonic-drive-60").unwrap();
        let j = joint(&m);
        assert!(Compensation::from_model(&m, &j, 1.2).is_err());
        assert!(Compensation::from_model(&m, &j, f64::NAN).is_err());
        // A fit that went below zero in one direction: that direction is not compensated.
        m.effects.asymmetry.as_mut().unwrap().coulomb_extra.value = -1e3;
        let c = Compensation::from_model(&m, &j, 0.8).unwrap();
        assert_eq!(c.friction.unwrap().coulomb_pos, 0.0);
        assert!(c
            .left_out
            .iter()
            .any(|l| l.starts_with("friction below zero")));
    }
}
