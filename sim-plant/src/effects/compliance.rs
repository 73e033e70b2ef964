//! Transmission compliance with soft-zone / stiffening (thesis §3.1 2-mass plant KT, §3.2
//! "Soft-zone / wind-up / stiffening", Table 4.2 min/max stiffness: e.g. HD 3,000/6,300,
//! KAMO 4,300/8,600 N·m/rad; HD soft zone over ±20 % of rated torque).
//!
//! Dynamics: a spring between the motor side (reflected to the output) and the output:
//! torque = `k_soft·δ` up to the knee torque, then `knee + k_hard·(|δ| − δ_knee)` — a
//! piecewise-linear stiffening curve, continuous in torque, plus structural damping `c·δ̇`
//! while engaged. Without this effect (and without backlash) the transmission is rigid and
//! the plant is one inertia `J = N²·I1 + I2`.
//!
//! Fingerprint (linearised, rigid model → 2-mass): with the motor position measured,
//! the load lags by `J2·a2/K`, so `a2 ≈ a − (J2/K)·q⁽⁴⁾` and
//! `u = J1·a + J2·a2 = J·a − (J2²/K)·q⁽⁴⁾`; measured at the output instead,
//! `u = J·a + (J1·J2/K)·q⁽⁴⁾`. Either way the residual is `α·d²a/dt²` with `α` of either sign
//! and magnitude `J_far²/K` (kg·m²·s²): column `[d²a/dt²]` (smoothed, `Shape::smoothing`).
//! Its amplitude is a combination, not a model parameter. Thesis-notes §7.10/7.11: ringing
//! at the transmission mode after steps, motor and load velocities differ at that mode; a
//! soft zone makes that frequency depend on load.

use super::signal::{derivative, moving_average};
use super::{EffectLaws, Shape, Trajectory};

/// Stiffness used when backlash is present without a compliance effect (N·m/rad).
pub const DEFAULT_STIFFNESS: f64 = 1.0e4;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "transmission spring KT with soft zone (k_soft up to a knee torque, \
     then k_hard); ringing at the transmission mode, residual ∝ d²a/dt², resonance frequency \
     that varies with load";

/// Amplitude of the fingerprint column: −J_far²/K seen from the motor side (kg·m²·s²), a
/// derived quantity, not a model parameter.
pub const AMPLITUDES: &[&str] = &["inertia_sq_over_stiffness"];

/// Admissible sign of the first amplitude: negative for a motor-side position sensor.
pub const SIGN: Option<f64> = Some(-1.0);

crate::define_params! {
    /// Stiffness beyond the knee, or of the whole spring without a knee (N·m/rad, output).
    stiffness: "N·m/rad" = DEFAULT_STIFFNESS, [1e-6, 1e12], Setting;
    /// Soft-zone stiffness near zero load (N·m/rad); 0 = same as `stiffness`.
    soft_stiffness: "N·m/rad" = 0.0, [0.0, 1e12], Setting;
    /// Transmitted torque at which the soft zone ends (N·m); 0 = no soft zone.
    knee: "N·m" = 0.0, [0.0, 1e9], Setting;
    /// Structural damping across the spring while engaged (N·m·s/rad).
    damping: "N·m·s/rad" = 0.0, [0.0, 1e9], Setting;
}

/// Elastic torque of an engaged deflection `e` (rad) for the piecewise-linear soft-zone spring.
#[inline(always)]
pub fn elastic(e: f64, k_soft: f64, k_hard: f64, knee: f64) -> f64 {
    elastic_with(e, k_soft, k_hard, knee, knee_deflection(k_soft, knee))
}

/// Deflection at the knee (0 without a soft zone).
pub fn knee_deflection(k_soft: f64, knee: f64) -> f64 {
    if knee > 0.0 && k_soft > 0.0 {
        knee / k_soft
    } else {
        0.0
    }
}

/// [`elastic`] with the knee deflection precomputed (the integrator's form: no division
/// per substep). With `ek = 0` it is the linear spring `k_hard·e`.
#[inline(always)]
pub fn elastic_with(e: f64, k_soft: f64, k_hard: f64, knee: f64, ek: f64) -> f64 {
    if e > ek {
        knee + k_hard * (e - ek)
    } else if e < -ek {
        -knee + k_hard * (e + ek)
    } else {
        k_soft * e
    }
}

/// Set the transmission spring.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    let s = &mut laws.spring;
    s.present = true;
    s.k_hard = p.stiffness.value;
    s.k_soft = if p.soft_stiffness.value > 0.0 {
        p.soft_stiffness.value
    } else {
        p.stiffness.value
    };
    s.knee_torque = p.knee.value;
    s.damping = p.damping.value;
}

/// `[d²a/dt²]`, each differentiation preceded by a moving average.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let a = moving_average(&traj.acceleration[..n], shape.smoothing);
    let j = moving_average(&derivative(&a, traj.dt), shape.smoothing);
    vec![derivative(&j, traj.dt)]
}

/// Smoothing lengths 1, 5, 11 samples.
pub fn shape_grid(_traj: &Trajectory) -> Vec<Shape> {
    [1, 5, 11]
        .into_iter()
        .map(|smoothing| Shape {
            smoothing,
            ..Shape::default()
        })
        .collect()
}

/// Elastic energy of an engaged deflection `e` for the soft-zone spring (J): the integral of
/// [`elastic`].
pub fn potential(e: f64, k_soft: f64, k_hard: f64, knee: f64) -> f64 {
    let a = e.abs();
    let ek = knee_deflection(k_soft, knee);
    if ek == 0.0 {
        return 0.5 * k_hard * a * a;
    }
    if a <= ek {
        0.5 * k_soft * a * a
    } else {
        0.5 * k_soft * ek * ek + knee * (a - ek) + 0.5 * k_hard * (a - ek) * (a - ek)
    }
}
