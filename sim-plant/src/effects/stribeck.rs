//! Stiction above Coulomb and the Stribeck transition (thesis §3.2, §2.11 Armstrong 1988;
//! Table 4.1 stiction columns: τs/τc ≈ 1.6–2.5).
//!
//! Dynamics: the breakaway level is τc + excess; while sliding the dry friction is
//! `τc + excess·exp(−(|v|/vs)^δ)` — a negative slope at low speed that drives stick-slip. The
//! stick state itself (hold below breakaway, release above) lives in the integrator.
//!
//! Fingerprint: `[sign_ε(v)·exp(−(|v|/vs)^δ)]`, shapes vs and δ (thesis-notes §7.2/7.3: residual
//! peaks near velocity zero-crossings and grows as speed falls). The refit's form adds the
//! bristle-damping transient and the stick hold (see [`fingerprint`]).

use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};
use super::{EffectKind, FitTraits, ShapeSearch, SmoothShape};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "stiction above Coulomb with a Stribeck transition, \
     τc + Δ·exp(-(|v|/vs)^δ); residual peaks at low speed and velocity zero-crossings, \
     delayed breakaway, stick-slip";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names). Only
/// `excess` is a simulator parameter: the refit's `transient` (Δ·σ1/σ0) and `hold` (1) are the
/// equation-error view of what the simulator's stick state and friction dynamics do.
pub const AMPLITUDES: &[&str] = &["excess", "transient", "hold"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    smooth_shape: Some(SmoothShape {
        get: |s| s.stribeck_velocity,
        unit: "rad/s",
        set: |s, v| s.stribeck_velocity = v,
    }),
    search: ShapeSearch::Stick,
    file_shape: &[
        same_shape!("velocity" => stribeck_velocity),
        same_shape!("exponent" => stribeck_exponent),
    ],
    // At rest the friction is the applied torque (see `fingerprint`).
    held: &[("hold", 1.0)],
    dry_friction: true,
    requires: &[EffectKind::Coulomb],
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Stiction minus Coulomb, Δ = τs − τc (N·m), both directions.
    excess: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
    /// Stribeck velocity vs (rad/s, output).
    velocity: "rad/s" = 0.02, [1e-9, 1e6], Shape;
    /// Stribeck exponent δ (1 = exponential, 2 = Gaussian).
    exponent: "1" = 2.0, [0.1, 10.0], Shape;
}

/// `exp(−(v/vs)^δ)` for `v ≥ 0`, cheap for the common δ = 2 and far from zero.
#[inline(always)]
pub fn decay(v: f64, vs: f64, delta: f64) -> f64 {
    if vs <= 0.0 {
        return 0.0;
    }
    decay_inv(v, 1.0 / vs, delta)
}

/// [`decay`] with 1/vs precomputed.
#[inline(always)]
pub fn decay_inv(v: f64, inv_vs: f64, delta: f64) -> f64 {
    excess_decay(v, inv_vs, delta, 1.0)
}

/// `excess·exp(−(v/vs)^δ)` for `v ≥ 0` with 1/vs precomputed: the integrator's form, with no
/// division on the friction node's dependency chain and the excess folded into the exp
/// ([`crate::fastmath::exp_neg_scaled`], inline and table-based: at low speed this is on the
/// chain every substep).
#[inline(always)]
pub fn excess_decay(v: f64, inv_vs: f64, delta: f64, excess: f64) -> f64 {
    if delta == 2.0 {
        // The common Gaussian case: the exp's argument straight from v² (the constant is
        // loop-invariant in the integrator), one multiply shorter than (v/vs)² then ·256/ln2.
        let v2 = v * v;
        let e = v2 * (inv_vs * inv_vs);
        // exp(−36) ≈ 2e-16: below f64 resolution of any friction level, skip the exp().
        return if e > 36.0 {
            0.0
        } else {
            let t = v2 * (inv_vs * inv_vs * -crate::fastmath::EXP_PER_LN2);
            crate::fastmath::exp_neg_scaled_t(t, excess)
        };
    }
    let x = v * inv_vs;
    let e = if delta == 1.0 { x } else { x.powf(delta) };
    if e > 36.0 {
        0.0
    } else {
        crate::fastmath::exp_neg_scaled(e, excess)
    }
}

/// [`excess_decay`] and the same times `h` (the friction node's h/I), from one exp.
#[inline(always)]
pub fn excess_decay_pair(v: f64, inv_vs: f64, delta: f64, excess: f64, h: f64) -> (f64, f64) {
    if delta == 2.0 {
        let v2 = v * v;
        let e = v2 * (inv_vs * inv_vs);
        return if e > 36.0 {
            (0.0, 0.0)
        } else {
            let t = v2 * (inv_vs * inv_vs * -crate::fastmath::EXP_PER_LN2);
            crate::fastmath::exp_neg_scaled_t2(t, excess, excess * h)
        };
    }
    let d = excess_decay(v, inv_vs, delta, excess);
    (d, d * h)
}

/// Add the excess to both directions and set the transition shape.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    let f = &mut laws.friction;
    f.excess_pos += p.excess.value;
    f.excess_neg += p.excess.value;
    f.stribeck_velocity = p.velocity.value;
    f.stribeck_exponent = p.exponent.value;
}

/// `[sign_ε(v + lead·a)·exp(−(|v|/vs)^δ)]` (exact exponent, no cut-off; lead =
/// `Shape::sign_lead`, which a fitter shares with Coulomb) — the diagnosis's column.
///
/// With a stick window (`Shape::stick_velocity` = vh > 0, set by the refit) three columns,
/// w = [`stick_window_mean`]`(v, a, dt, vh)` (the window averaged over the sample):
///
/// * **slip** `(1 − w)·sign_ε(v + lead·a)·e(|v|)`, e = exp(−(|v|/vs)^δ), amplitude `excess`;
/// * **transient** `(1 − w)·a·e'(|v|)`: the bristle damping of dynamic (LuGre) friction. While
///   sliding, the bristle deflection z tracks its steady state g(|v|)·sign(v)/σ0, so its rate
///   is ż = g'(|v|)·a/σ0 and the damping adds σ1·ż = (σ1/σ0)·Δ·e'(|v|)·a: an
///   acceleration-proportional torque across the Stribeck transition, which a static curve
///   leaves to the inertia (a biased J that then mispredicts faster records). Amplitude
///   `transient` = Δ·σ1/σ0 (N·m·s);
/// * **hold** `w·u` (u = the recorded input): at rest dry friction is a constraint torque,
///   whatever holds the joint up to breakaway (Karnopp's model). A static law sign(v)·g(v)
///   evaluated on a measured velocity that is noise around zero predicts a random ±τs there,
///   while the truth is the applied torque; the stick phases then dominate the residual and
///   bias every other parameter. Amplitude `hold`, physically 1 (the refit holds it there).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let vs = positive_or(shape.stribeck_velocity, 1e-3);
    let d = shape.stribeck_exponent;
    let n = traj.len();
    let (v, a) = (&traj.velocity[..n], &traj.acceleration[..n]);
    let slip = v
        .iter()
        .zip(a)
        .map(|(&v, &a)| super::coulomb::dry_sign(v, a, shape) * (-(v.abs() / vs).powf(d)).exp());
    let vh = shape.stick_velocity;
    let Some(u) = traj.raw_input.get(traj.raw_offset..traj.raw_offset + n) else {
        return vec![slip.collect()];
    };
    if vh <= 0.0 {
        return vec![slip.collect()];
    }
    let w = stick_weights(traj, vh);
    // d/d|v| exp(−x^δ), x = |v|/vs: −(δ/vs)·x^(δ−1)·exp(−x^δ).
    let de = |v: f64| {
        let x = v.abs() / vs;
        -d / vs * x.powf(d - 1.0) * (-x.powf(d)).exp()
    };
    vec![
        slip.zip(&w).map(|(s, w)| (1.0 - w) * s).collect(),
        v.iter()
            .zip(a)
            .zip(&w)
            .map(|((&v, &a), w)| (1.0 - w) * a * de(v))
            .collect(),
        w.iter().zip(u).map(|(w, u)| w * u).collect(),
    ]
}

/// The stick window's weight at each sample of `traj` (all 0 for `vh` ≤ 0, no window):
/// [`stick_window_mean`] of the measured motion.
pub fn stick_weights(traj: &Trajectory, vh: f64) -> Vec<f64> {
    let n = traj.len();
    if vh <= 0.0 {
        return vec![0.0; n];
    }
    traj.velocity[..n]
        .iter()
        .zip(&traj.acceleration[..n])
        .map(|(&v, &a)| stick_window_mean(v, a, traj.dt, vh))
        .collect()
}

/// Weight of "stuck" at measured velocity `v`: exp(−(v/vh)⁴), ≈ 1 for |v| < vh/2 (the
/// measured velocity of a joint at rest is the differentiator's noise), ≈ 0 beyond 1.5·vh.
/// Dry-friction columns of other effects (Coulomb, asymmetry) are switched off by the same
/// window: at rest the hold column is the friction.
#[inline]
pub fn stick_window(v: f64, vh: f64) -> f64 {
    let x = v / vh;
    let x2 = x * x;
    (-(x2 * x2)).exp()
}

/// [`stick_window`] averaged over one sample period `dt` of a motion at velocity `v` (mid
/// sample) and acceleration `a`: the time-average of "at rest" over the sample, which is what
/// the hold column's sample represents (the recorded input is held over the sample).
///
/// Why: a fast reversal crosses the window in 2·vh/|a|, a small fraction of a sample (50 rad/s²
/// through vh = 9 mrad/s: 0.35 ms), yet the sample whose mid-point falls inside it gets w ≈ 1
/// and its hold predicts friction = u — at that instant mostly J·a, about the whole torque.
/// Band-limited like the input, that one sample became a bump of ±10 ms at every fast reversal
/// it hit (9 floors on a hidden-effect trial). At rest (|a|·dt ≪ vh) the mean is w(v).
pub fn stick_window_mean(v: f64, a: f64, dt: f64, vh: f64) -> f64 {
    let half = 0.5 * (a * dt).abs();
    if half.is_nan() || half <= 0.125 * vh {
        return stick_window(v, vh);
    }
    // The window is ≈ 0 beyond 2·vh: integrate over the overlap of [v − half, v + half] with
    // [−2vh, 2vh] (Simpson, 16 intervals), divided by the whole span.
    let (lo, hi) = ((v - half).max(-2.0 * vh), (v + half).min(2.0 * vh));
    if hi <= lo {
        return 0.0;
    }
    let m = 16;
    let h = (hi - lo) / m as f64;
    let sum: f64 = (0..=m)
        .map(|i| {
            let c = if i == 0 || i == m {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            c * stick_window(lo + i as f64 * h, vh)
        })
        .sum();
    sum * h / 3.0 / (2.0 * half)
}

/// Log grid of vs from 0.3 % to 30 % of the largest |v|, for δ = 1 and 2.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    let mut out = Vec::new();
    for delta in [1.0, 2.0] {
        for vs in log_space(3e-3 * vmax, 0.3 * vmax, 8) {
            out.push(Shape {
                stribeck_velocity: vs,
                stribeck_exponent: delta,
                sign_epsilon: 1e-3 * vmax,
                ..Shape::default()
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sample-averaged window: the point window at rest, the time fraction spent inside
    /// the window on a fly-through, a brute-force average in between.
    #[test]
    fn stick_window_mean_is_the_sample_average() {
        let (vh, dt) = (0.01, 1e-3);
        for v in [0.0, 0.004, -0.009, 0.03] {
            assert_eq!(stick_window_mean(v, 0.0, dt, vh), stick_window(v, vh));
        }
        // Fly-through at v = 0 with a·dt = 20·vh: ∫exp(−x⁴)dx = 2Γ(5/4) = 1.8128 over 20.
        let w = stick_window_mean(0.0, 20.0 * vh / dt, dt, vh);
        assert!((w - 1.8128 / 20.0).abs() < 1e-3, "{w}");
        // In between, against a fine average over the sample.
        for (v, a) in [(0.005, 8.0), (-0.012, -15.0), (0.02, 30.0), (0.0, 3.0)] {
            let m = 20_000;
            let brute: f64 = (0..m)
                .map(|i| stick_window(v + a * dt * ((i as f64 + 0.5) / m as f64 - 0.5), vh))
                .sum::<f64>()
                / m as f64;
            let w = stick_window_mean(v, a, dt, vh);
            assert!((w - brute).abs() < 2e-3, "v {v} a {a}: {w} vs {brute}");
        }
    }

    /// The refit's form: at rest the hold column is the recorded input and the slip column is
    /// off; sliding, the slip column is the diagnosis's and the transient is a·de/d|v|.
    #[test]
    fn refit_form_holds_at_rest_and_slides_otherwise() {
        let v = [0.0, 1e-4, 0.05, -0.05, 1.0];
        let a = [0.3, -0.2, 2.0, 2.0, 0.0];
        let u = [0.7, -0.4, 1.0, 1.0, 1.0];
        let q = [0.0; 5];
        let traj = Trajectory::unfiltered(1e-3, &u, &q, &v, &a);
        let mut shape = Shape {
            stribeck_velocity: 0.1,
            stribeck_exponent: 2.0,
            sign_epsilon: 1e-6,
            ..Shape::default()
        };
        let slip_only = fingerprint(&traj, &shape);
        assert_eq!(slip_only.len(), 1);
        shape.stick_velocity = 0.01;
        let c = fingerprint(&traj, &shape);
        assert_eq!(c.len(), 3);
        // At rest: hold = u, slip and transient off.
        for i in 0..2 {
            assert!((c[2][i] - u[i]).abs() < 1e-6, "hold {i}");
            assert!(c[0][i].abs() < 1e-6 && c[1][i].abs() < 1e-6, "slip {i}");
        }
        // Sliding: the diagnosis's slip column, no hold.
        for i in 2..5 {
            assert!(c[2][i].abs() < 1e-9);
            assert!((c[0][i] - slip_only[0][i]).abs() < 1e-9);
        }
        // Transient = a·d/d|v| exp(−(|v|/vs)²), by a central difference.
        let h = 1e-7;
        let e = |x: f64| (-(x / 0.1f64).powi(2)).exp();
        let want = 2.0 * (e(0.05 + h) - e(0.05 - h)) / (2.0 * h);
        assert!((c[1][2] - want).abs() < 1e-5 && (c[1][3] - want).abs() < 1e-5);
    }
}
