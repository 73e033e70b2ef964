//! Coulomb (kinetic dry) friction: constant magnitude opposing motion, thesis §3.2 "Friction",
//! Table 4.1 Coulomb columns. Direction-dependent levels are `coulomb` + `asymmetry`.
//!
//! Dynamics: while sliding `R = τc·sign(v)`; at rest the friction node sticks (see
//! [`crate::plant`]) and holds any torque up to the breakaway level (= τc without a
//! `stribeck` excess) — a stick state, not a chattering sign().
//!
//! Fingerprint: `[sign_ε(v)]`, a sign with a linear zone |v| < ε + |a|·T (thesis-notes §7.1:
//! residual ±τc flipping at reversals; torque-position loop 2τc wide). ε
//! (`Shape::sign_epsilon`) covers the noise of a measured velocity at rest; T
//! (`Shape::sign_time`) spreads each reversal over a time, as the residual's band limit and
//! a pre-sliding displacement do, at any reversal speed. A fitter may shift the switch by a
//! small time lead (`Shape::sign_lead`, the sign of v + lead·a): real (dynamic) friction
//! reverses over a pre-sliding displacement, not exactly at the measured v = 0.

use super::signal::{log_space, positive_or, smooth_sign};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "Coulomb friction R = τc·sign(v), sticks at rest; residual is a \
     ±τc square wave flipping at velocity reversals (loop 2τc wide)";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["torque"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    search: ShapeSearch::Sign,
    dry_friction: true,
    sign_shaped: true,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Coulomb friction level (N·m, output-referred), both directions.
    torque: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
}

/// Add to both directions of the friction curve.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.friction.coulomb_pos += p.torque.value;
    laws.friction.coulomb_neg += p.torque.value;
}

/// `[dry_sign(v, a)]` (see [`dry_sign`]), times
/// `1 − w(v)` inside a stick window (`Shape::stick_velocity` > 0, see
/// [`super::stribeck::fingerprint`]): at rest the stiction hold is the friction.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let vh = shape.stick_velocity;
    let w = super::stribeck::stick_weights(traj, vh);
    vec![traj.velocity[..n]
        .iter()
        .zip(&traj.acceleration[..n])
        .zip(&w)
        .map(|((&v, &a), w)| (1.0 - w) * dry_sign(v, a, shape))
        .collect()]
}

/// The sign of dry friction at velocity `v` and acceleration `a`, as every dry-friction column
/// takes it: `sign_ε(v + lead·a)` with the linear zone ε + |a|·T (`Shape::sign_epsilon`,
/// `Shape::sign_time`, `Shape::sign_lead`).
#[inline]
pub fn dry_sign(v: f64, a: f64, shape: &Shape) -> f64 {
    smooth_sign(
        v + shape.sign_lead * a,
        shape.sign_epsilon + a.abs() * shape.sign_time,
    )
}

/// Grid of sign smoothings: five zones in velocity (ε from 10⁻⁴ to 3·10⁻² of the largest
/// |v|) and five in time (T from 1 % to 100 % of the band's 1/f_c, ε the speed at rest).
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    sign_grid(traj)
}

/// Shared by coulomb, asymmetry: the sign's zone ε + |a|·T in two forms, each on a log grid
/// of five. In velocity: ε from 10⁻⁴ to 3·10⁻² of the largest |v|, T = 0 (a low-speed zone
/// that a wide band or a pre-sliding friction shows at every reversal). In time: ε the speed
/// a joint at rest shows (`Trajectory::rest_velocity`, at least 10⁻⁴ of the largest |v|) and
/// T from 1 % to 100 % of the band's time scale 1/f_c (the residual's low-pass; f_s/10 on
/// an unfiltered trajectory): a record whose reversals are all fast fits both, and only the
/// time form carries over to a slow one.
pub(crate) fn sign_grid(traj: &Trajectory) -> Vec<Shape> {
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    let at_rest = traj.rest_velocity.max(1e-4 * vmax);
    let fc = if traj.lowpass_hz > 0.0 {
        traj.lowpass_hz
    } else {
        0.1 / positive_or(traj.dt, 1e-3)
    };
    let shape = |sign_epsilon, sign_time| Shape {
        sign_epsilon,
        sign_time,
        ..Shape::default()
    };
    let velocity = log_space(1e-4 * vmax, 3e-2 * vmax, 5).into_iter().map(|e| shape(e, 0.0));
    let time = log_space(0.01 / fc, 1.0 / fc, 5).into_iter().map(|t| shape(at_rest, t));
    velocity.chain(time).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Time (s) the sign takes from −0.9 to +0.9 through a reversal v = a·t, sampled at 1 µs.
    fn crossing_time(a: f64, shape: &Shape) -> f64 {
        let (mut first, mut last) = (None, None);
        for k in -200_000..=200_000 {
            let t = k as f64 * 1e-6;
            let s = dry_sign(a * t, a, shape);
            if s > -0.9 && first.is_none() {
                first = Some(t);
            }
            if s < 0.9 {
                last = Some(t);
            }
        }
        last.unwrap_or(0.0) - first.unwrap_or(0.0)
    }

    /// With the zone's time part, a slow reversal and one a hundred times faster switch over
    /// the same time, 2·0.9·T; a zone in velocity alone takes a hundred times longer on the
    /// slow one.
    #[test]
    fn a_reversal_switches_over_the_same_time_at_any_speed() {
        let timed = Shape {
            sign_epsilon: 0.0,
            sign_time: 2e-3,
            ..Shape::default()
        };
        let (slow, fast) = (crossing_time(1.0, &timed), crossing_time(100.0, &timed));
        assert!((slow - 3.6e-3).abs() < 1e-5 && (fast - 3.6e-3).abs() < 1e-5, "{slow} {fast}");
        let velocity = Shape {
            sign_epsilon: 0.2,
            sign_time: 0.0,
            ..Shape::default()
        };
        let (slow, fast) = (crossing_time(1.0, &velocity), crossing_time(100.0, &velocity));
        assert!((slow / fast - 100.0).abs() < 1.0, "{slow} {fast}");
    }

    /// The velocity form spans 10⁻⁴–3·10⁻² of the peak speed with no time part; the time form
    /// spans 1 %–100 % of the band's time scale 1/f_c (f_s/10 unfiltered) with ε the speed at
    /// rest, or at least 10⁻⁴ of the peak speed.
    #[test]
    fn the_sign_grid_has_a_velocity_form_and_a_time_form() {
        let v: Vec<f64> = (0..100).map(|k| (k as f64 * 0.1).sin() * 2.0).collect();
        let z = vec![0.0; v.len()];
        let mut traj = Trajectory::unfiltered(1e-3, &z, &z, &v, &z);
        let vmax = traj.max_abs_velocity();
        let close = |a: f64, b: f64| (a / b - 1.0).abs() < 1e-9;
        let forms = |t: &Trajectory| -> (Vec<Shape>, Vec<Shape>) {
            sign_grid(t).into_iter().partition(|s| s.sign_time == 0.0)
        };
        let (velocity, time) = forms(&traj);
        assert_eq!((velocity.len(), time.len()), (5, 5));
        assert!(close(velocity[0].sign_epsilon, 1e-4 * vmax));
        assert!(close(velocity[4].sign_epsilon, 3e-2 * vmax));
        assert!(close(time[0].sign_time, 1e-4) && close(time[4].sign_time, 1e-2));
        assert!(time.iter().all(|s| close(s.sign_epsilon, 1e-4 * vmax)));
        traj.lowpass_hz = 50.0;
        traj.rest_velocity = 0.05;
        let (_, time) = forms(&traj);
        assert!(close(time[0].sign_time, 2e-4) && close(time[4].sign_time, 2e-2));
        assert!(time.iter().all(|s| s.sign_epsilon == 0.05));
    }
}
