//! The same closed loop as the card runs it: the plant held over each period T (zero-order
//! hold) and the law's derivatives taken as backward differences, (x_k − x_{k−1})/T, as the
//! card differentiates (§2.1 of the notes: "Only a discrete-domain analysis can show …").
//! Beside the continuous Routh boundary it shows what the sampling alone moves.

use nalgebra::DMatrix;

use super::routh::{Law, TwoMass};

/// The card's period, s.
pub const PERIOD_S: f64 = 1e-3;

/// The largest |z| of the sampled closed loop of `law` on `p` at period `t`: stable below 1.
pub fn spectral_radius(p: &TwoMass, law: &Law, t: f64) -> f64 {
    let (p1, d1, p2, d2) = law.feedback(p);
    // Continuous plant, state [x1, v1, x2, v2], input τ at the rotor.
    #[rustfmt::skip]
    let a = DMatrix::from_row_slice(4, 4, &[
        0.0, 1.0, 0.0, 0.0,
        -p.kt / p.j1, -p.b1 / p.j1, p.kt / p.j1, 0.0,
        0.0, 0.0, 0.0, 1.0,
        p.kt / p.j2, 0.0, -(p.kt + p.kf) / p.j2, -p.b2 / p.j2,
    ]);
    // Zero-order hold: exp of [[A, B], [0, 0]]·T gives Φ and Γ.
    let mut aug = DMatrix::<f64>::zeros(5, 5);
    aug.view_mut((0, 0), (4, 4)).copy_from(&(a * t));
    aug[(1, 4)] = t / p.j1;
    let e = aug.exp();
    let phi = e.view((0, 0), (4, 4)).clone_owned();
    let gamma = e.view((0, 4), (4, 1)).clone_owned();
    // Sampled law on Z = [x1, v1, x2, v2, x1(k−1), x2(k−1)]:
    // τ_k = −p1·x1 − d1·(x1 − x1⁻)/T − p2·x2 − d2·(x2 − x2⁻)/T.
    let k = [-(p1 + d1 / t), 0.0, -(p2 + d2 / t), 0.0, d1 / t, d2 / t];
    let mut m = DMatrix::<f64>::zeros(6, 6);
    for r in 0..4 {
        for c in 0..4 {
            m[(r, c)] = phi[(r, c)];
        }
        for (c, kc) in k.iter().enumerate() {
            m[(r, c)] += gamma[(r, 0)] * kc;
        }
    }
    m[(4, 0)] = 1.0;
    m[(5, 2)] = 1.0;
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// Stable as the card samples it.
pub fn stable(p: &TwoMass, law: &Law) -> bool {
    spectral_radius(p, law, PERIOD_S) < 1.0
}

#[cfg(test)]
mod tests {
    use super::super::routh;
    use super::*;

    /// As the period shrinks the sampled boundary tends to the continuous one.
    #[test]
    fn the_sampled_boundary_tends_to_routh() {
        let p = super::super::FREE;
        let be = 40.0;
        let law = |ke| Law::PdNonColocated { ke, be };
        let closed = routh::pd_noncolocated_ke_max(&p, be).unwrap();
        let mut last = f64::INFINITY;
        for t in [1e-2, 1e-3, 1e-4] {
            let b = routh::boundary(|ke| spectral_radius(&p, &law(ke), t) < 1.0, 10.0, 1e5, 1e-7)
                .unwrap();
            let err = (b / closed - 1.0).abs();
            assert!(err < last, "T {t}: {b} vs {closed}");
            last = err;
        }
        assert!(last < 1e-3, "{last}");
    }
}
