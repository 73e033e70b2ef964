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
//! Fingerprint (rigid model → 2-mass, motor-side sensor, linear spring): with J = J1 + J2,
//! ω² = K·(1/J1 + 1/J2) and 2ζω = c·(1/J1 + 1/J2), the motor acceleration answers the input
//! as `J·a1 = u·((J/J1)·s² + 2ζω·s + ω²)/(s² + 2ζω·s + ω²)`, so the rigid residual is
//! `r = u − J·a1 = −(J2/J1) · H(s)·u`, `H = s²/(s² + 2ζω·s + ω²)`: the command high-passed at
//! the coupled mode (ringing there), exactly, for any excitation. Column `[H·u]` built from the
//! *recorded* command and low-passed as the residual was (`Trajectory::lowpass_hz`, so
//! overall a band-pass around the mode); amplitude `−J2/J1` (dimensionless, negative for a
//! motor-side sensor). The mode frequency and damping are shapes (`Shape::compliance_frequency`,
//! `Shape::compliance_damping`); K and c follow from them and the inertias. Far above the
//! excitation the column tends to `u⁽²⁾/ω²` — the classic `−(J2²/K)·q⁽⁴⁾` term. Thesis-notes
//! §7.10/7.11: ringing at the transmission mode after steps, motor and load velocities differ
//! at that mode; a soft zone makes that frequency depend on load.

use super::signal::{biquad2, free_response2, highpass2, log_space};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// Stiffness used when backlash is present without a compliance effect (N·m/rad).
pub const DEFAULT_STIFFNESS: f64 = 1.0e4;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "transmission spring KT with soft zone (k_soft up to a knee torque, \
     then k_hard); ringing at the transmission mode, residual is the command high-passed at the \
     coupled mode (ringing there), resonance frequency that varies with load";

/// Amplitude of the fingerprint column: −J2/J1 seen from a motor-side sensor (dimensionless),
/// a derived quantity, not a model parameter.
pub const AMPLITUDES: &[&str] = &["inertia_ratio"];

/// Admissible sign of the first amplitude: negative for a motor-side position sensor.
pub const SIGN: Option<f64> = Some(-1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    search: ShapeSearch::Mode,
    band_limit: false,
    // The motion form is a resonant filter of the acceleration; the command form is built
    // from the recorded input and carries none of the position's noise.
    motion_linear: |s| s.compliance_near_inertia > 0.0,
    ..FitTraits::PLAIN
};

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

/// `[lowpass(H·u)]`, H the second-order high-pass at the shape's mode (zeros for records too
/// short to carry a mode: the effect has no memoryless part).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    if n < 8 || traj.dt <= 0.0 {
        return vec![vec![0.0; n]];
    }
    if shape.compliance_near_inertia > 0.0 {
        return vec![motion_column(traj, shape)];
    }
    let (u, window) = traj.recorded_input();
    let hp = highpass2(
        u,
        shape.compliance_frequency,
        shape.compliance_damping,
        1.0 / traj.dt,
    );
    vec![traj.input_lowpass(&hp)[window].to_vec()]
}

/// The motion form of the column: the same residual of the 2-mass plant written with the
/// measured motion instead of the command, so the command's own noise does not enter the
/// column (the fit of `H·u` to `r` pays |J2/J1|× the command noise in the mode's band). With
/// viscous friction b on the load, `r = −(J2·s + b)²·a1/(J2·s² + (b + c)·s + K)`: the column
/// is `J1·(s + β)²/(s² + 2ζ₂ω₂·s + ω₂²)·a1` with β = b/J2 and the locked-motor (load-side)
/// mode ω₂² = K/J2 = ω²/(1 + J2/J1) (ζ₂ = ζ/√(1 + J2/J1), the searched damping then also
/// carrying b), amplitude −J2/J1 as before. The acceleration is already low-passed as the
/// residual was.
fn motion_column(traj: &Trajectory, shape: &Shape) -> Vec<f64> {
    let ratio = shape.compliance_ratio.max(0.0);
    let s = (1.0 + ratio).sqrt();
    let (f2, z2) = (shape.compliance_frequency / s, shape.compliance_damping / s);
    let j2 = ratio * shape.compliance_near_inertia;
    let beta = if j2 > 0.0 {
        shape.compliance_load_damping.max(0.0) / j2
    } else {
        0.0
    };
    // Filtered from the record's start: the mode rings for 1/(ζ₂ω₂) (0.3 s and more at the
    // light damping of a transmission), so a filter started at rest where the trajectory
    // begins would miss the ringing of any transient before it.
    let (a, window) = traj.recorded_acceleration();
    let y = biquad2(
        a,
        [1.0, 2.0 * beta, beta * beta],
        f2,
        z2,
        1.0 / traj.dt,
    );
    y[window]
        .iter()
        .map(|v| shape.compliance_near_inertia * v)
        .collect()
}

/// Columns spanning the column's dependence on the state its filter starts from: the free
/// responses of the mode it filters through, as the column carries them. The load's position
/// and velocity relative to the motor when the record (or its trusted window) begins are not
/// measured, and the mode rings them out for 1/(ζω) — seconds at the light damping of a
/// transmission, and longer for the motion form's locked-motor mode (ζ₂ = ζ/√(1 + J2/J1)).
/// Filtered from the record's start, the motion form also rings out whatever error the
/// differentiator's edge (odd reflection) puts into the first samples' acceleration, and that
/// ringing, not the record's dynamics, would dominate the refit. Fitted per record as
/// nuisance regressors (`hil_host::workbench::residual`), as a simulation's initial state is.
pub fn initial_state(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    if n < 8 || traj.dt <= 0.0 {
        return Vec::new();
    }
    // The column's filter state where the trajectory's window starts summarises everything
    // before it (the record's unseen past, and for the motion form the edge samples). The
    // command form is low-passed after its high-pass; a damped sinusoid comes out of that
    // zero-phase low-pass as itself times a complex gain, so the unfiltered free responses
    // span the same columns past the filter's settling (the trajectory starts after the
    // differentiator's edge samples).
    let (f, zeta) = if shape.compliance_near_inertia > 0.0 {
        let s = (1.0 + shape.compliance_ratio.max(0.0)).sqrt();
        (shape.compliance_frequency / s, shape.compliance_damping / s)
    } else {
        (shape.compliance_frequency, shape.compliance_damping)
    };
    free_response2(n, f, zeta, 1.0 / traj.dt)
}

/// Lowest mode frequency searched (Hz): below it a transmission mode is inside the motion band
/// and no longer a "missing effect" of a rigid model.
pub const MIN_FREQUENCY: f64 = 2.0;

/// Mode frequencies log-spaced (steps of ≈ 25 %) from [`MIN_FREQUENCY`] to the lower of 0.4× the
/// sample rate and 2× the residual’s low-pass, each at a light (0.05) and a moderate (0.3)
/// damping ratio; [`refine_grid`] narrows the best one down.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let hi = top_frequency(traj);
    let lo = MIN_FREQUENCY.min(0.5 * hi);
    let count = (((hi / lo).ln() / 1.25f64.ln()).ceil() as usize).max(2);
    let mut out = Vec::new();
    for f in log_space(lo, hi, count) {
        for zeta in [0.05, 0.3] {
            out.push(Shape {
                compliance_frequency: f,
                compliance_damping: zeta,
                ..Shape::default()
            });
        }
    }
    out
}

/// Highest mode frequency of [`shape_grid`] (Hz): the lower of 0.4× the sample rate and 2× the
/// residual's low-pass.
pub fn top_frequency(traj: &Trajectory) -> f64 {
    let fs = if traj.dt > 0.0 { 1.0 / traj.dt } else { 1.0e3 };
    let mut hi = 0.4 * fs;
    if traj.lowpass_hz > 0.0 {
        hi = hi.min(2.0 * traj.lowpass_hz);
    }
    hi
}

/// Switch `shape` to the motion form in its search coordinates: unit J1, no inertia ratio, no
/// load damping — the column is then `H₂·a` at the locked-motor mode (frequency and damping
/// as `shape` holds them) and its amplitude is −J2, linear. Both the refit's motion-form
/// search and the diagnosis's ranking check start from it.
pub fn set_unit_motion_form(shape: &mut Shape) {
    shape.compliance_near_inertia = 1.0;
    shape.compliance_ratio = 0.0;
    shape.compliance_load_damping = 0.0;
}

/// A mode is resolved when it lies below the top of the grid: a search that ends at or above
/// the top has found a mode above the record's bandwidth, whose frequency the record does not
/// identify (the column is then `≈ u⁽²⁾/ω²`, any ω above the band fits).
pub fn resolved(traj: &Trajectory, shape: &Shape) -> bool {
    shape.compliance_frequency < top_frequency(traj) * (1.0 - 1e-9)
}

/// Finer frequencies (±15 % in 5 % steps) and damping ratios around `best`.
pub fn refine_grid(_traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    let mut out = Vec::new();
    for i in -3i32..=3 {
        let f = best.compliance_frequency * 1.05f64.powi(i);
        for zeta in [0.03, 0.05, 0.1, 0.2, 0.4] {
            out.push(Shape {
                compliance_frequency: f,
                compliance_damping: zeta,
                ..best.clone()
            });
        }
    }
    out
}

/// Stiffness and damping of the spring from the mode (`Shape::compliance_frequency`, Hz, and
/// `compliance_damping`) and the inertias on each side: K = ω²·J1·J2/(J1 + J2),
/// c = 2ζω·J1·J2/(J1 + J2).
pub fn spring_from_mode(frequency: f64, damping: f64, j1: f64, j2: f64) -> (f64, f64) {
    let w = std::f64::consts::TAU * frequency;
    let jr = j1 * j2 / (j1 + j2);
    (w * w * jr, 2.0 * damping * w * jr)
}

/// Inverse of [`spring_from_mode`]: (frequency in Hz, damping ratio) of the coupled mode.
pub fn mode_from_spring(k: f64, c: f64, j1: f64, j2: f64) -> (f64, f64) {
    let jr = j1 * j2 / (j1 + j2);
    let w = (k / jr).sqrt();
    (w / std::f64::consts::TAU, c / (2.0 * w * jr))
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
