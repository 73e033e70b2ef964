//! Backlash: a dead zone of lost motion in the transmission (thesis §3.2 "Backlash": Cyclo
//! 29:1 0.8°, KAMO 10:1 1.1° at low preload; §4.63 inside the gap only the motor-side inertia
//! remains, ωn* = ωn·√(M_total/M_s)).
//!
//! Dynamics: the transmission spring sees the deflection minus the gap,
//! `δ_e = dead_zone(δ, b/2)`; inside the gap no torque and no structural damping is
//! transmitted, so the plant switches between "motor alone" and "motor + load" (contact and
//! separation fall out of the spring law, no event logic needed). Lumped at the output, in
//! output radians (the thesis lumps it at the input; the two differ by N).
//!
//! Fingerprint (rigid model, position measured on the motor side): with δ = x_motor − x_load
//! the true input is `J1·a + J2·a_load + b·v_load`, so a rigid model `J·a + b·v` (J = J1 + J2)
//! leaves exactly `r = −J2·(δ̈ + δ̇/τ)`, τ = J2/b the load's viscous time constant — zero while
//! the gap is closed (δ = ±b/2 constant), the lost motion while it is crossed. The column is
//! that expression for a δ(t) simulated from the measured motion: the load is a mass that
//! coasts through the gap with its own viscous decay (velocity × e^(−t/τ)) and is pushed along
//! when the motor reaches an edge of the gap (a play operator with inertia). Separation needs
//! no trigger: it happens when the motor decelerates faster than the coasting load, whether
//! because the velocity reverses, the input reverses or the loop chatters; the impact at the
//! far edge is inelastic (the load takes on the motor's velocity if that pushes it faster).
//! δ goes through the residual's low-pass before it is differentiated, as the motion did.
//! Amplitude: the load inertia J2 (kg·m², not a model parameter); shapes: the width b and τ.
//! Thesis-notes §7.13: flat dead zone of width b at torque reversal, load lags after reversal.

use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "backlash dead zone of width b in the transmission; flat zone of \
     width b at torque reversal in a stiffness test, load lags after each reversal, \
     residual −J_load·a while crossing the gap";

/// Amplitude of the fingerprint column: the inertia beyond the gap (kg·m²), a derived
/// quantity, not a model parameter.
pub const AMPLITUDES: &[&str] = &["load_inertia"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    search: ShapeSearch::Gap,
    file_shape: &[same_shape!("width" => backlash_width)],
    band_limit: false,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Total width of the dead zone (rad at the output).
    width: "rad" = 0.0, [0.0, 1.0], Shape;
}

/// `x` minus its clamp to ±half: zero inside the gap, shifted outside.
#[inline(always)]
pub fn dead_zone(x: f64, half: f64) -> f64 {
    if x > half {
        x - half
    } else if x < -half {
        x + half
    } else {
        0.0
    }
}

/// A spring must exist for backlash to mean anything; compliance sets its stiffness.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.spring.present = true;
    laws.spring.backlash = p.width.value;
    if laws.spring.k_hard == 0.0 {
        // No compliance effect: contact stiffness of the compliance default.
        laws.spring.k_hard = super::compliance::DEFAULT_STIFFNESS;
        laws.spring.k_soft = super::compliance::DEFAULT_STIFFNESS;
    }
}

/// Motor-minus-load deflection δ(t) of a load that coasts inside a gap of total width `b`
/// (viscous time constant `tau`, 0 = none) and is pushed along at its edges by the motor
/// (`position`, `velocity`).
pub fn gap_deflection(position: &[f64], velocity: &[f64], b: f64, tau: f64, dt: f64) -> Vec<f64> {
    let half = 0.5 * b;
    let n = position.len().min(velocity.len());
    let (decay, drift) = if tau > 0.0 {
        let d = (-dt / tau).exp();
        (d, tau * (1.0 - d))
    } else {
        (1.0, dt)
    };
    let mut out = Vec::with_capacity(n);
    let (mut x2, mut v2) = match (position.first(), velocity.first()) {
        (Some(&x), Some(&v)) => (x, v),
        _ => return out,
    };
    for i in 0..n {
        if i > 0 {
            x2 += drift * v2;
            v2 *= decay;
        }
        let (x, v) = (position[i], velocity[i]);
        let d = x - x2;
        if d > half {
            x2 = x - half;
            v2 = v2.max(v);
        } else if d < -half {
            x2 = x + half;
            v2 = v2.min(v);
        }
        out.push(x - x2);
    }
    out
}

/// The backlash column `−(δ̈ + δ̇/τ)`: of the deflection δ = x_motor − x_load *measured*
/// (both positions low-passed as the motion) when the trajectory has a load position, else of
/// the low-passed [`gap_deflection`] estimated from the motor's motion alone.
///
/// With a load encoder the column is the rigid model's exact remainder whatever the load
/// does — the motor encoder alone cannot say where the load sits in the gap while a light
/// motor chatters against it (`tests/examples/backlash_probe.rs`), the load encoder measures
/// it — so the width does not shape it (the width a fit reports is [`measured_width`]). The
/// same law holds for *any* motor–load pair, a compliant shaft too: what makes the deflection
/// a gap is checked separately ([`ruled_out`], used by the diagnosis).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let tau = shape.backlash_load_time;
    let d = match traj.load() {
        Some(load) => measured_deflection(&traj.position[..n], load),
        None => traj.lowpass(&gap_deflection(
            &traj.position[..n],
            &traj.velocity[..n],
            shape.backlash_width,
            tau,
            traj.dt,
        )),
    };
    vec![deflection_column(&d, tau, traj.dt)]
}

/// What a motor encoder alone tells of a transmission with a gap and a spring: whichever
/// explains more ranks first. The spring's column and the gap's each carry the load's
/// inertia, and fitted apart they disagree, so a model holds one of them (a model file has
/// one J2); the light motor's chatter inside the gap is faster than the differentiator's band.
pub const MOTOR_ONLY: &str = "from the motor encoder alone a transmission's spring and a gap \
     in it are told apart only roughly: whichever explains more ranks first, and a model \
     holds one of them (each names the load's inertia, and fitted apart they disagree, so \
     `--auto` does not add the other after it); the motor's chatter inside the gap is above \
     the differentiator's band — a load-side encoder (--load-output) measures the deflection \
     itself";

/// Why the record rules a backlash out, if it does: it has a load position whose deflection
/// shows no gap ([`shows_gap`]). The measured-deflection column (see [`fingerprint`]) is
/// Newton's law for any motor–load pair, so without this test it explains a compliant
/// transmission as well as a gap: on the compliance trials with a load encoder it took rank 1
/// from compliance in 24 of 24.
pub fn ruled_out(traj: &Trajectory) -> Option<&'static str> {
    let n = traj.len();
    let load = traj.load()?;
    (!shows_gap(&measured_deflection(&traj.position[..n], load))).then_some(
        "the load-side position shows no gap (the deflection lingers mid-range, as a \
         spring's or a rigid joint's encoder noise does, instead of dwelling at two edges)",
    )
}

/// Whether a measured deflection `d` looks like a gap: it spends at most [`GAP_CENTRE_MAX`] of
/// the time in the central [`GAP_CENTRE`] of its extent. A load in a gap is pushed at one
/// edge or the other and the gap is crossed quickly (the light motor alone accelerates
/// through it), so the low-passed δ piles up at two levels; a spring's deflection follows the
/// transmitted torque through zero and lingers there, and a rigid joint's δ is encoder noise,
/// Gaussian about its mean. Measured with `tests/examples/load_encoder_probe.rs` (40 trials
/// each, both records): backlash 76 of 80 records ≤ 8 % in the central 40 % (the others 13,
/// 29, 46, 71 %: tiny gaps of 1.7–2.8 counts, or a loop rattling across the gap faster than
/// the cut-off, whose low-passed δ then sits mid-gap), compliance 27–97 %, null trials
/// 40–88 %. This keeps a compliant transmission's deflection from being read as a gap.
pub fn shows_gap(d: &[f64]) -> bool {
    let Some((lo, hi)) = extent(d) else {
        return false;
    };
    let (c, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    if half <= 0.0 {
        return false;
    }
    let centre = d
        .iter()
        .filter(|x| (*x - c).abs() < GAP_CENTRE * half)
        .count();
    (centre as f64) <= GAP_CENTRE_MAX * d.len() as f64
}

/// Central part of the measured extent (a fraction of it) a gap's deflection crosses quickly.
pub const GAP_CENTRE: f64 = 0.4;

/// Largest share of the samples a gap's deflection spends in the [`GAP_CENTRE`].
pub const GAP_CENTRE_MAX: f64 = 0.15;

/// δ = motor − load position, sample by sample.
fn measured_deflection(motor: &[f64], load: &[f64]) -> Vec<f64> {
    motor.iter().zip(load).map(|(x1, x2)| x1 - x2).collect()
}

/// The 1st and 99th percentiles of `d` (None if empty): its extent without single noise
/// samples and the filter's overshoot at impacts.
fn extent(d: &[f64]) -> Option<(f64, f64)> {
    if d.is_empty() {
        return None;
    }
    let mut s = d.to_vec();
    s.sort_by(f64::total_cmp);
    let q = |p: f64| s[((s.len() - 1) as f64 * p).round() as usize];
    Some((q(0.01), q(0.99)))
}

/// `−(ẍ + ẋ/τ)` by central differences (τ = 0: no viscous term), edges copied.
fn deflection_column(d: &[f64], tau: f64, dt: f64) -> Vec<f64> {
    let n = d.len();
    let mut col = vec![0.0; n];
    for i in 1..n.saturating_sub(1) {
        let acc = (d[i + 1] - 2.0 * d[i] + d[i - 1]) / (dt * dt);
        let vel = (d[i + 1] - d[i - 1]) / (2.0 * dt);
        col[i] = -(acc + if tau > 0.0 { vel / tau } else { 0.0 });
    }
    if n >= 3 {
        col[0] = col[1];
        col[n - 1] = col[n - 2];
    }
    col
}

/// The gap's width as the load encoder measures it (None without a load position): the
/// spread between the 1st and 99th percentiles of δ = motor − load (low-passed). A gap's δ
/// dwells at ±b/2 whenever the motor pushes (a stiff contact's compression is far below an
/// encoder count), so its extent is the gap; the percentiles keep single noise samples and
/// the filter's overshoot at impacts out of it. A fit with a load position reports it as the
/// width (the column itself is built from the measured deflection, see
/// `measured_deflection`).
pub fn measured_width(traj: &Trajectory) -> Option<f64> {
    let n = traj.len();
    let load = traj.load()?;
    let (lo, hi) = extent(&measured_deflection(&traj.position[..n], load))?;
    Some((hi - lo).max(0.0))
}

/// Load time constants of the shape grid (s; 0 = no decay), besides the ones scaled on the
/// record's own rigid time constant (see [`shape_grid`]).
pub const LOAD_TIMES: [f64; 4] = [0.1, 0.5, 2.5, 0.0];

/// Fractions of the rigid time constant J/b in the shape grid: the load's own J2/b_load is
/// that fraction J2/J when all the viscous friction is on the load side.
pub const LOAD_FRACTIONS: [f64; 4] = [0.3, 0.5, 0.7, 0.9];

/// J/b of the rigid fit `input ≈ J·a + b·v + c·sign v + d` on the trajectory (None if either
/// is not positive): the scale of the load's viscous time constant.
pub fn rigid_time_constant(traj: &Trajectory) -> Option<f64> {
    let rows = (0..traj.len()).map(|i| {
        let (v, a) = (traj.velocity[i], traj.acceleration[i]);
        let s = if v == 0.0 { 0.0 } else { v.signum() };
        ([a, v, s, 1.0], traj.input[i])
    });
    let x = crate::lstsq::solve_rows(rows)?;
    let (j, b) = (x[0], x[1]);
    (j > 0.0 && b > 0.0 && (j / b).is_finite()).then(|| j / b)
}

/// Widths log-spaced from 3e-4 (or one count) to 0.1 of the position span, for each of
/// [`LOAD_TIMES`] and [`LOAD_FRACTIONS`] of the record's [`rigid_time_constant`]. The fit is
/// sharp in τ (it sets the load's deceleration while it crosses the gap, against a relative
/// deceleration of the motor that is often a small fraction of it), so the generic ×5 steps
/// alone miss it.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = positive_or(hi - lo, 1.0);
    let mut taus = LOAD_TIMES.to_vec();
    if let Some(t) = rigid_time_constant(traj) {
        taus.extend(LOAD_FRACTIONS.iter().map(|f| f * t));
    }
    // With a load position the width is measured and does not shape the column: one per τ
    // (a grid over widths would only multiply the search's multiplicity).
    let widths = match measured_width(traj) {
        Some(b) => vec![b],
        None => {
            // From 3e-4 of the span, continued at the same steps down to one count where the
            // encoder resolves finer: a gap of a few counts in a stiff transmission still
            // shows (its impacts), a finer one does not. The coarse grid stays a subset, so a
            // fine encoder only adds widths.
            let lo = 3e-4 * span;
            let mut w = log_space(lo, 0.1 * span, 7);
            let step = traj.position_step;
            let ratio = w[1] / w[0];
            if step > 0.0 && step < lo && ratio > 1.0 {
                let below = ((lo / step).ln() / ratio.ln()).ceil() as i32;
                w.splice(0..0, (1..=below).rev().map(|k| lo / ratio.powi(k)));
            }
            w
        }
    };
    let mut out = Vec::new();
    for tau in taus {
        for &b in &widths {
            out.push(Shape {
                backlash_width: b,
                backlash_load_time: tau,
                ..Shape::default()
            });
        }
    }
    out
}

/// Around the best grid shape: widths within ±60 % (steps of 8 %; the coarse grid's step is
/// ×2.6 and the fit's minimum in the width only about ±15 % wide) and load time constants
/// within a factor 2 (steps of 20 %; from "no decay": the long ones above the grid's 2.5 s).
/// With a load position only τ (the width is measured).
pub fn refine_grid(traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    let (b0, t0) = (best.backlash_width, best.backlash_load_time);
    let taus: Vec<f64> = if t0 > 0.0 {
        (-4..=4).map(|k| t0 * 1.2f64.powi(k)).collect()
    } else {
        vec![4.0, 6.3, 10.0, 0.0]
    };
    let ks = if traj.load().is_some() { 0..=0 } else { -6..=6 };
    // A cross through the best grid shape, not the whole rectangle: the widths at its τ and
    // the τ's at its width (the refit then searches both jointly).
    let shape = |b: f64, tau: f64| Shape {
        backlash_width: b,
        backlash_load_time: tau,
        ..Shape::default()
    };
    let mut out: Vec<Shape> = ks
        .filter(|&k| k != 0)
        .map(|k| shape(b0 * 1.08f64.powi(k), t0))
        .collect();
    out.extend(taus.iter().filter(|&&tau| tau != t0).map(|&tau| shape(b0, tau)));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-mass joint, any transmission: motor x1, load x2, u = J1·ẍ1 + J2·ẍ2 + b·ẋ2. The
    /// rigid model J·ẍ1 + b·ẋ1 leaves exactly J2·(−(δ̈ + δ̇/τ)), τ = J2/b, with δ = x1 − x2 —
    /// the column with a load position, whatever the width in the shape.
    #[test]
    fn measured_column_is_the_rigid_models_exact_remainder() {
        let (n, dt) = (4000, 1e-3);
        let (j1, j2, b) = (0.003, 0.02, 0.04);
        let x1: Vec<f64> = (0..n)
            .map(|i| (2.0 * i as f64 * dt).sin() + 0.3 * (7.0 * i as f64 * dt).sin())
            .collect();
        let x2: Vec<f64> = (0..n)
            .map(|i| x1[i] - 1e-3 * (13.0 * i as f64 * dt).sin())
            .collect();
        let d1 = |x: &[f64], i: usize| (x[i + 1] - x[i - 1]) / (2.0 * dt);
        let d2 = |x: &[f64], i: usize| (x[i + 1] - 2.0 * x[i] + x[i - 1]) / (dt * dt);
        let v: Vec<f64> = (0..n).map(|i| if i == 0 || i == n - 1 { 0.0 } else { d1(&x1, i) }).collect();
        let a: Vec<f64> = (0..n).map(|i| if i == 0 || i == n - 1 { 0.0 } else { d2(&x1, i) }).collect();
        let u = vec![0.0; n];
        let traj = Trajectory {
            load_position: &x2,
            ..Trajectory::unfiltered(dt, &u, &x1, &v, &a)
        };
        for width in [1e-4, 0.5] {
            let shape = Shape {
                backlash_width: width,
                backlash_load_time: j2 / b,
                ..Shape::default()
            };
            let col = &fingerprint(&traj, &shape)[0];
            for (i, c) in col.iter().enumerate().take(n - 1).skip(1) {
                let u = j1 * d2(&x1, i) + j2 * d2(&x2, i) + b * d1(&x2, i);
                let r = u - (j1 + j2) * d2(&x1, i) - b * d1(&x1, i);
                let err = (r - j2 * c).abs();
                assert!(err < 1e-9 * (1.0 + r.abs()), "{i}: {r} vs {}", j2 * c);
            }
        }
        // Without a load position the play operator is used: another column.
        let plain = Trajectory::unfiltered(dt, &u, &x1, &v, &a);
        assert!(plain.load().is_none() && traj.load().is_some());
        let shape = Shape::default();
        assert_ne!(fingerprint(&plain, &shape), fingerprint(&traj, &shape));
    }

    /// A gap's deflection dwells at two edges and is measured as the gap's width; a spring's
    /// (sinusoidal) deflection and a rigid joint's encoder noise linger mid-range and rule a
    /// backlash out.
    #[test]
    fn a_gap_is_told_from_a_spring_and_from_noise() {
        let n = 20_000;
        let b = 2e-3;
        // Pushed at one edge or the other, crossing in 5 ms every 0.5 s, plus a little noise.
        let noise = |i: usize| 2e-5 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
        let gap: Vec<f64> = (0..n)
            .map(|i| {
                let ph = i % 1000;
                let edge = if ph < 500 { 0.5 * b } else { -0.5 * b };
                let cross = match ph {
                    0..5 => -0.5 * b + b * ph as f64 / 5.0,
                    500..505 => 0.5 * b - b * (ph - 500) as f64 / 5.0,
                    _ => edge,
                };
                cross + noise(i) + 0.7
            })
            .collect();
        let spring: Vec<f64> = (0..n).map(|i| b * (i as f64 * 0.01).sin()).collect();
        let rigid: Vec<f64> = (0..n)
            .map(|i| {
                let u1 = ((i * 7919 + 13) % 1009) as f64 / 1009.0;
                let u2 = ((i * 104_729 + 7) % 1013) as f64 / 1013.0;
                1e-5 * (u1 + u2 - 1.0)
            })
            .collect();
        assert!(shows_gap(&gap));
        assert!(!shows_gap(&spring));
        assert!(!shows_gap(&rigid));
        let zero = vec![0.0; n];
        let traj = |load: &[f64]| -> (Option<f64>, bool) {
            let t = Trajectory {
                load_position: load,
                ..Trajectory::unfiltered(1e-3, &zero, &zero, &zero, &zero)
            };
            (measured_width(&t), ruled_out(&t).is_some())
        };
        // δ = motor − load = −load here.
        let neg = |x: &[f64]| -> Vec<f64> { x.iter().map(|v| -v).collect() };
        let (w, out) = traj(&neg(&gap));
        assert!(!out);
        assert!((w.expect("load") / b - 1.0).abs() < 0.05, "{w:?}");
        assert!(traj(&neg(&spring)).1 && traj(&neg(&rigid)).1);
        let none = Trajectory::unfiltered(1e-3, &zero, &zero, &zero, &zero);
        assert!(measured_width(&none).is_none() && ruled_out(&none).is_none());
        // One width per τ in the grid with a load position.
        let t = Trajectory {
            load_position: &gap,
            ..Trajectory::unfiltered(1e-3, &zero, &zero, &zero, &zero)
        };
        assert!(shape_grid(&t).iter().all(|s| s.backlash_width == shape_grid(&t)[0].backlash_width));
        assert!(refine_grid(&t, &shape_grid(&t)[0]).len() <= 9);
    }

    /// The shape grid's time-constant scale is J/b of the rigid fit, whatever the Coulomb
    /// level and offset riding on the input.
    #[test]
    fn rigid_time_constant_is_inertia_over_damping() {
        let n = 2000;
        let dt = 1e-3;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let q: Vec<f64> = t.iter().map(|t| (3.0 * t).sin() + 0.3 * (11.0 * t).sin()).collect();
        let v: Vec<f64> = t
            .iter()
            .map(|t| 3.0 * (3.0 * t).cos() + 3.3 * (11.0 * t).cos())
            .collect();
        let a: Vec<f64> = t
            .iter()
            .map(|t| -9.0 * (3.0 * t).sin() - 36.3 * (11.0 * t).sin())
            .collect();
        let u: Vec<f64> = v
            .iter()
            .zip(&a)
            .map(|(v, a)| 0.02 * a + 0.05 * v + 0.1 * v.signum() - 0.03)
            .collect();
        let traj = Trajectory::unfiltered(dt, &u, &q, &v, &a);
        let tau = rigid_time_constant(&traj).expect("J and b positive");
        assert!((tau - 0.4).abs() < 1e-9, "J/b = {tau}");
        assert_eq!(shape_grid(&traj).len(), 7 * (LOAD_TIMES.len() + LOAD_FRACTIONS.len()));
    }

    /// A fine encoder takes the widths down to one count at the coarse grid's step or finer;
    /// a coarse one (a count above 3e-4 of the span) or an unknown one leaves the grid as it is.
    #[test]
    fn widths_reach_down_to_one_count() {
        let n = 2000;
        let dt = 1e-3;
        let q: Vec<f64> = (0..n).map(|k| 4.0 * (k as f64 * dt * 3.0).sin()).collect();
        let span = q.iter().cloned().fold(f64::MIN, f64::max) - q.iter().cloned().fold(f64::MAX, f64::min);
        let zero = vec![0.0; n];
        let widths = |step: f64| -> Vec<f64> {
            let t = Trajectory {
                position_step: step,
                ..Trajectory::unfiltered(dt, &zero, &q, &zero, &zero)
            };
            let mut w: Vec<f64> = shape_grid(&t).iter().map(|s| s.backlash_width).collect();
            w.sort_by(f64::total_cmp);
            w.dedup();
            w
        };
        let coarse = widths(0.0);
        assert_eq!(coarse.len(), 7);
        assert!((coarse[0] / (3e-4 * span) - 1.0).abs() < 1e-9);
        assert_eq!(widths(1e-3 * span), coarse);
        let count = 2.0 * std::f64::consts::PI / f64::from(1u32 << 20);
        let fine = widths(count);
        let ratio = coarse[1] / coarse[0];
        assert!(fine[0] <= count && fine[0] * ratio > count, "{} vs {count}", fine[0]);
        assert!(coarse.iter().all(|c| fine.iter().any(|f| (f / c - 1.0).abs() < 1e-9)));
        assert!(fine.windows(2).all(|w| (w[1] / w[0] / ratio - 1.0).abs() < 1e-9));
    }
}
