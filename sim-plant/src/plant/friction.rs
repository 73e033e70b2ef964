//! The friction node's velocity update with a proper stick state (thesis §3.2 friction,
//! §2.11 breakaway; the Karnopp idea of a zero-velocity band is replaced by an exact stick
//! flag because the integrator can clamp velocity to exactly 0).
//!
//! * Stuck (v = 0): if the non-friction torque τ is within the breakaway level for its
//!   direction, friction cancels it exactly and the node stays at v = 0 — no chattering sign().
//!   Otherwise it breaks away; the kinetic friction at v → 0 equals the breakaway level (the
//!   Stribeck curve is continuous), so motion starts smoothly.
//! * Sliding: friction follows the sliding curve. If a substep would carry v through zero, the
//!   node stops at v = 0 and sticks; the next substep's static check decides whether it stays
//!   (friction cannot reverse motion by itself). This costs at most one substep of extra rest
//!   at a genuine reversal.

use crate::effects::FrictionLaw;

/// Velocity after one substep and the resisting friction torque used (same sign as the
/// motion it resists). Every other torque on the node is `drive − load`, split so that the
/// integrator's position-dependent `load` (ripple, gravity, …) can enter late: the sliding
/// update is `(v − h/I·f) + h/I·(drive − load)`, a reassociation of `v + h/I·(drive − load −
/// f)` with two short branches — the friction (late at low speed, where it has the Stribeck
/// exp) and the torques from the positions (late at speed) — each two operations from the
/// result. `h_over_i` is the substep divided by the node's inertia.
#[inline(always)]
pub fn advance(
    v: f64,
    stuck: &mut bool,
    drive: f64,
    load: f64,
    h_over_i: f64,
    law: &FrictionLaw,
    dry: bool,
) -> (f64, f64) {
    if !dry {
        let f = law.sliding(v);
        return ((v - h_over_i * f) + h_over_i * (drive - load), f);
    }
    if *stuck {
        let tau = drive - load;
        // The level for τ's direction as a select of two sums rather than a branch: a held
        // node's τ hovers around zero and flips sign unpredictably.
        let pos = law.coulomb_pos + law.excess_pos;
        let neg = law.coulomb_neg + law.excess_neg;
        let level = if tau >= 0.0 { pos } else { neg };
        if tau.abs() <= level {
            return (0.0, tau);
        }
        *stuck = false;
        // Breaking away means |τ| > level ≥ 0, so τ ≠ 0 and its sign is the direction.
        let f = level.copysign(tau);
        return (h_over_i * (tau - f), f);
    }
    // f = base + stribeck, with the Stribeck part (late: an exp of v) entering last, already
    // times h/I.
    let (base, stribeck, h_stribeck) = law.sliding_parts(v, h_over_i);
    let f = base + stribeck;
    let vn = ((v - h_over_i * base) - h_stribeck) + h_over_i * (drive - load);
    if vn * v <= 0.0 {
        *stuck = true;
        return (0.0, f);
    }
    (vn, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> FrictionLaw {
        FrictionLaw {
            coulomb_pos: 1.0,
            coulomb_neg: 1.0,
            excess_pos: 0.5,
            excess_neg: 0.5,
            stribeck_velocity: 0.01,
            stribeck_exponent: 2.0,
            viscous_pos: 0.0,
            viscous_neg: 0.0,
            inv_stribeck_velocity: 100.0,
        }
    }

    #[test]
    fn holds_below_breakaway_and_releases_above() {
        let mut stuck = true;
        let (v, f) = advance(0.0, &mut stuck, 1.49, 0.0, 1e-4, &law(), true);
        assert_eq!((v, f), (0.0, 1.49));
        assert!(stuck);
        let (v, _) = advance(0.0, &mut stuck, -1.51, 0.0, 1e-4, &law(), true);
        assert!(v < 0.0 && !stuck);
    }

    #[test]
    fn sliding_node_stops_instead_of_reversing() {
        let mut stuck = false;
        // Moving slowly positive with no drive: friction would overshoot through zero.
        let (v, _) = advance(1e-5, &mut stuck, 0.0, 0.0, 1e-4, &law(), true);
        assert_eq!(v, 0.0);
        assert!(stuck);
    }
}
