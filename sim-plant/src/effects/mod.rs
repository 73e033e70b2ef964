//! # The effect library contract: names, shapes and residual fingerprints
//!
//! **Stop-gap written in branch `bench`** so the workbench could be built before branch `plant`
//! lands its library. It follows the agreed contract (`EffectKind` with `ALL`/`name`/
//! `from_name`/`describe`, `Trajectory`, `Shape`, `fingerprint`, `shape_grid`); when `plant`
//! merges, its version of this file wins and the workbench only calls these items.
//!
//! A *fingerprint* is the set of regressor columns an effect adds to an **equation-error**
//! (inverse-dynamics) prediction of the applied input, per unit amplitude:
//!
//! ```text
//! u_pred(t) = M·a(t) + Σ_effects Σ_j θ_j · column_j(t)
//! ```
//!
//! With the shape parameters fixed (Stribeck velocity, ripple period, backlash width, …) every
//! effect is linear in its amplitudes θ, so a candidate can be tested and fitted by linear least
//! squares; the shape is searched over `shape_grid`. Positions/velocities are axis-referred SI
//! (m or rad), the input is the applied force/torque.

use serde::{Deserialize, Serialize};

/// Every physical effect the library knows. The order is the order of [`EffectKind::ALL`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EffectKind {
    /// Constant force/torque offset (amplifier offset, seal drag, vertical-axis weight).
    Offset,
    /// Viscous friction `B·ω`.
    Viscous,
    /// Coulomb friction `Fc·sign(ω)`.
    Coulomb,
    /// Direction-dependent viscous friction: `ΔB·|ω|` (so `B± = B ± ΔB`). A direction-dependent
    /// Coulomb level is `offset + Fc·sign(ω)` and needs no separate column.
    Asymmetry,
    /// Stribeck (stiction-to-Coulomb) transition `Fs·sign(ω)·exp(−(ω/ωs)²)`.
    Stribeck,
    /// Backlash at the motor side: inside the gap the load is decoupled.
    Backlash,
    /// Transmission compliance seen from a motor-side position sensor.
    Compliance,
    /// Transmission ripple periodic in output position.
    Ripple,
    /// Motor cogging periodic in rotor angle (needs the gear ratio).
    Cogging,
    /// Gravity on a rotary joint `m·g·l·sin(θ+φ)`.
    Gravity,
    /// Dead zone on the drive input.
    Deadband,
    /// Pure delay between the logged input and the input the plant received.
    Delay,
    /// Quantisation of the drive input (D/A steps) that the log does not show.
    Quantization,
}

impl EffectKind {
    /// All effects, in a fixed order.
    pub const ALL: [EffectKind; 13] = [
        EffectKind::Offset,
        EffectKind::Viscous,
        EffectKind::Coulomb,
        EffectKind::Asymmetry,
        EffectKind::Stribeck,
        EffectKind::Backlash,
        EffectKind::Compliance,
        EffectKind::Ripple,
        EffectKind::Cogging,
        EffectKind::Gravity,
        EffectKind::Deadband,
        EffectKind::Delay,
        EffectKind::Quantization,
    ];

    /// Lower-case name used on the CLI, in JSON and in TOML.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::Offset => "offset",
            EffectKind::Viscous => "viscous",
            EffectKind::Coulomb => "coulomb",
            EffectKind::Asymmetry => "asymmetry",
            EffectKind::Stribeck => "stribeck",
            EffectKind::Backlash => "backlash",
            EffectKind::Compliance => "compliance",
            EffectKind::Ripple => "ripple",
            EffectKind::Cogging => "cogging",
            EffectKind::Gravity => "gravity",
            EffectKind::Deadband => "deadband",
            EffectKind::Delay => "delay",
            EffectKind::Quantization => "quantization",
        }
    }

    /// Inverse of [`EffectKind::name`] (case-insensitive).
    pub fn from_name(s: &str) -> Option<EffectKind> {
        let s = s.trim().to_ascii_lowercase();
        EffectKind::ALL.into_iter().find(|k| k.name() == s)
    }

    /// One-line description of the effect and of its residual fingerprint (thesis notes §7).
    pub fn describe(self) -> &'static str {
        match self {
            EffectKind::Offset => "constant offset: residual mean ≠ 0 regardless of motion",
            EffectKind::Viscous => "viscous friction: residual ∝ velocity",
            EffectKind::Coulomb => "Coulomb friction: residual ±Fc flipping at velocity reversals",
            EffectKind::Asymmetry => "direction asymmetry: residual ∝ |velocity| (B+ ≠ B−)",
            EffectKind::Stribeck => {
                "Stribeck/stiction: residual peaks near velocity zero, decays with speed"
            }
            EffectKind::Backlash => "backlash: load decoupled for a gap width after each reversal",
            EffectKind::Compliance => {
                "compliance: residual ∝ 4th derivative of motor position (resonance)"
            }
            EffectKind::Ripple => "transmission ripple: residual periodic in output position",
            EffectKind::Cogging => "motor cogging: residual periodic in rotor angle",
            EffectKind::Gravity => "gravity: residual ∝ sin/cos of joint angle",
            EffectKind::Deadband => "input dead zone: residual ≈ saturated input near zero command",
            EffectKind::Delay => "input delay: residual ∝ input rate",
            EffectKind::Quantization => {
                "input quantisation: sawtooth residual in the commanded input"
            }
        }
    }

    /// Physically admissible sign of the *first* amplitude (in the equation-error convention
    /// `input = … + θ·column`), or `None` if either sign is physical. Friction consumes force
    /// (Coulomb, Stribeck, viscous > 0); a delay is positive; a dead zone and an unseen D/A
    /// quantisation leave a residual of the command's sign; compliance seen from the motor
    /// subtracts `J2²/K·a⁗` and backlash removes the load inertia inside the gap (< 0).
    /// Diagnosis uses it for one-sided tests: an estimate of the wrong sign is not evidence
    /// for the effect (it is usually errors-in-variables bias from noisy derivatives).
    pub fn admissible_sign(self) -> Option<f64> {
        match self {
            EffectKind::Viscous
            | EffectKind::Coulomb
            | EffectKind::Stribeck
            | EffectKind::Delay => Some(1.0),
            EffectKind::Deadband | EffectKind::Quantization => Some(1.0),
            EffectKind::Compliance | EffectKind::Backlash => Some(-1.0),
            _ => None,
        }
    }

    /// Names of the amplitude parameters, one per fingerprint column.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            EffectKind::Offset => &["offset"],
            EffectKind::Viscous => &["fv"],
            EffectKind::Coulomb => &["fc"],
            EffectKind::Asymmetry => &["dfv"],
            EffectKind::Stribeck => &["fs"],
            EffectKind::Backlash => &["gap_inertia", "gap_friction"],
            EffectKind::Compliance => &["snap_gain"],
            EffectKind::Ripple => &["ripple_sin", "ripple_cos"],
            EffectKind::Cogging => &["cogging_sin", "cogging_cos"],
            EffectKind::Gravity => &["gravity_sin", "gravity_cos"],
            EffectKind::Deadband => &["deadband_gain"],
            EffectKind::Delay => &["delay_gain"],
            EffectKind::Quantization => &["quant_gain"],
        }
    }
}

/// A measured or simulated motion, axis-referred SI. `input` is the applied force/torque.
#[derive(Debug, Clone, Copy)]
pub struct Trajectory<'a> {
    /// Sample period [s].
    pub dt: f64,
    /// Applied input (force/torque).
    pub input: &'a [f64],
    /// Position [m or rad].
    pub position: &'a [f64],
    /// Velocity.
    pub velocity: &'a [f64],
    /// Acceleration.
    pub acceleration: &'a [f64],
}

/// Shape parameters: the nonlinear parameters that, once fixed, make a fingerprint linear in
/// its amplitudes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Shape {
    /// Stribeck velocity ωs.
    pub stribeck_velocity: f64,
    /// Ripple period in position.
    pub ripple_period: f64,
    /// Cogging period in output position (= 2π/(poles·ratio)); 0 = unknown.
    pub cogging_period: f64,
    /// Backlash width (motor-side travel to cross the gap).
    pub backlash_width: f64,
    /// Dead-zone half width on the input.
    pub deadband_width: f64,
    /// Input quantisation step.
    pub quantum: f64,
    /// Input delay [s].
    pub delay: f64,
    /// Velocity below which `sign(ω)` is taken as 0 (noise guard).
    pub sign_epsilon: f64,
}

impl Default for Shape {
    fn default() -> Self {
        Shape {
            stribeck_velocity: 0.01,
            ripple_period: 0.01,
            cogging_period: 0.0,
            backlash_width: 1e-3,
            deadband_width: 0.1,
            quantum: 0.01,
            delay: 1e-3,
            sign_epsilon: 0.0,
        }
    }
}

fn sgn(v: f64, eps: f64) -> f64 {
    if v > eps {
        1.0
    } else if v < -eps {
        -1.0
    } else {
        0.0
    }
}

/// Central-difference derivative (one-sided at the ends).
fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    let mut d = vec![0.0; n];
    if n < 2 {
        return d;
    }
    for i in 1..n - 1 {
        d[i] = (x[i + 1] - x[i - 1]) / (2.0 * dt);
    }
    d[0] = (x[1] - x[0]) / dt;
    d[n - 1] = (x[n - 1] - x[n - 2]) / dt;
    d
}

/// Regressor columns an effect adds to the equation-error prediction of the input, per unit
/// amplitude (see the module docs). Returns an empty vector when the effect is not testable
/// from this trajectory (e.g. cogging with an unknown period).
pub fn fingerprint(kind: EffectKind, t: &Trajectory, s: &Shape) -> Vec<Vec<f64>> {
    let v = t.velocity;
    let x = t.position;
    let eps = s.sign_epsilon;
    match kind {
        EffectKind::Offset => vec![vec![1.0; v.len()]],
        EffectKind::Viscous => vec![v.to_vec()],
        EffectKind::Coulomb => vec![v.iter().map(|&w| sgn(w, eps)).collect()],
        EffectKind::Asymmetry => vec![v.iter().map(|w| w.abs()).collect()],
        EffectKind::Stribeck => {
            let vs = s.stribeck_velocity.max(1e-300);
            vec![v
                .iter()
                .map(|&w| sgn(w, eps) * (-(w / vs) * (w / vs)).exp())
                .collect()]
        }
        EffectKind::Backlash => {
            // Motor travel since the last reversal; while it is below the gap width the load
            // is decoupled, so the rigid model over-predicts by the load's inertia and friction.
            let w = s.backlash_width;
            let mut gap = vec![0.0; v.len()];
            let mut x_rev = x.first().copied().unwrap_or(0.0);
            let mut dir = 0.0;
            for i in 0..v.len() {
                let d = sgn(v[i], eps);
                if d != 0.0 && d != dir {
                    dir = d;
                    x_rev = x[i];
                }
                if dir != 0.0 && (x[i] - x_rev).abs() < w {
                    gap[i] = 1.0;
                }
            }
            let a = t.acceleration;
            vec![
                gap.iter().zip(a).map(|(g, a)| g * a).collect(),
                gap.iter().zip(v).map(|(g, &w)| g * sgn(w, eps)).collect(),
            ]
        }
        EffectKind::Compliance => {
            // Motor-side sensor, load J2 behind spring K: u ≈ (J1+J2)·a − (J2²/K)·a⁗. The
            // load-damping term −(J2·B2/K)·a⃛ is left out on purpose: a⃛ ∝ du/dt is the delay
            // fingerprint, and a column shared by two effects makes them indistinguishable.
            let jerk = derivative(t.acceleration, t.dt);
            vec![derivative(&jerk, t.dt)]
        }
        EffectKind::Ripple | EffectKind::Cogging => {
            let p = if kind == EffectKind::Ripple {
                s.ripple_period
            } else {
                s.cogging_period
            };
            if p <= 0.0 {
                return Vec::new();
            }
            let k = std::f64::consts::TAU / p;
            let (sn, cs): (Vec<f64>, Vec<f64>) = x.iter().map(|&q| (k * q).sin_cos()).unzip();
            vec![sn, cs]
        }
        EffectKind::Gravity => {
            let (sn, cs): (Vec<f64>, Vec<f64>) = x.iter().map(|&q| q.sin_cos()).unzip();
            vec![sn, cs]
        }
        EffectKind::Deadband => {
            let d = s.deadband_width.max(1e-300);
            vec![t.input.iter().map(|&u| (u / d).clamp(-1.0, 1.0)).collect()]
        }
        EffectKind::Delay => {
            // The plant received the logged command d late, so what it applied at t was
            // logged at t − d: residual = logged − applied ≈ applied(t + d) − applied(t).
            // The column is the *centred* difference applied(t + d/2) − applied(t − d/2): the
            // same first-order term d·u̇, but no even-derivative terms (d²/2·ü …), which would
            // pick up the acceleration noise that `input` (a motion-based reconstruction)
            // carries and make every noisy record look delayed. Linear interpolation; the ends
            // reuse the end values. Amplitude 1 means "about this delay".
            let n = t.input.len() as isize;
            let at = |x: f64| {
                let j = x.floor();
                let f = x - j;
                let g = |k: isize| t.input[k.clamp(0, n - 1) as usize];
                (1.0 - f) * g(j as isize) + f * g(j as isize + 1)
            };
            let half = 0.5 * s.delay.max(0.0) / t.dt;
            vec![(0..n)
                .map(|i| at(i as f64 + half) - at(i as f64 - half))
                .collect()]
        }
        EffectKind::Quantization => {
            let q = s.quantum.max(1e-300);
            vec![t.input.iter().map(|&u| u - q * (u / q).round()).collect()]
        }
    }
}

fn logspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if n <= 1 || lo <= 0.0 || hi <= lo {
        return vec![lo.max(hi)];
    }
    let (a, b) = (lo.ln(), hi.ln());
    (0..n)
        .map(|i| (a + (b - a) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

/// Shapes worth trying for an effect on this trajectory (a single default shape for effects
/// without shape parameters). Grids are scaled to the trajectory (speed range, travel, input
/// range) so they work in any unit system.
pub fn shape_grid(kind: EffectKind, t: &Trajectory) -> Vec<Shape> {
    let base = Shape::default();
    let vmax = t.velocity.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (xmin, xmax) = t
        .position
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let range = (xmax - xmin).max(0.0);
    let umax = t.input.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    match kind {
        EffectKind::Stribeck if vmax > 0.0 => logspace(0.005 * vmax, 0.3 * vmax, 12)
            .into_iter()
            .map(|vs| Shape {
                stribeck_velocity: vs,
                ..base
            })
            .collect(),
        EffectKind::Ripple if range > 0.0 => {
            // Spatial frequencies spaced by a quarter cycle over the travel: two periods closer
            // than that cannot be told apart on this record. Between 2 and 60 cycles per travel.
            let f0 = 2.0 / range;
            let df = 0.25 / range;
            (0..233)
                .map(|i| Shape {
                    ripple_period: 1.0 / (f0 + df * i as f64),
                    ..base
                })
                .collect()
        }
        EffectKind::Backlash if range > 0.0 => logspace(range * 1e-3, range * 0.1, 10)
            .into_iter()
            .map(|w| Shape {
                backlash_width: w,
                ..base
            })
            .collect(),
        EffectKind::Deadband if umax > 0.0 => logspace(umax * 0.01, umax * 0.3, 8)
            .into_iter()
            .map(|d| Shape {
                deadband_width: d,
                ..base
            })
            .collect(),
        EffectKind::Quantization if umax > 0.0 => logspace(umax * 0.005, umax * 0.2, 10)
            .into_iter()
            .map(|q| Shape { quantum: q, ..base })
            .collect(),
        EffectKind::Delay => logspace(0.25 * t.dt, 30.0 * t.dt, 16)
            .into_iter()
            .map(|d| Shape { delay: d, ..base })
            .collect(),
        EffectKind::Cogging => Vec::new(),
        _ => vec![base],
    }
}
