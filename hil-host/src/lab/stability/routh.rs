//! The thesis's continuous-time analysis (§3.3): the two-mass plant (I1, B1 | KT | I2, B2 | Kf)
//! closed by one of the card's laws gives a quartic A s⁴ + B s³ + C s² + D s + E whose Routh
//! array decides stability. Everything is output-referred: inertias and damping of the motor
//! side multiplied by N², gains in the thesis's units at the output.

/// The two-mass plant of the thesis's Eqn 3.3.1, output-referred.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TwoMass {
    /// Input (rotor) inertia I1, kg·m².
    pub j1: f64,
    /// Input damping B1 to ground, N·m·s/rad.
    pub b1: f64,
    /// Transmission stiffness KT, N·m/rad.
    pub kt: f64,
    /// Output inertia I2, kg·m².
    pub j2: f64,
    /// Output damping B2 to ground, N·m·s/rad.
    pub b2: f64,
    /// Environment (sensor + surface) stiffness Kf, N·m/rad; 0 in free space.
    pub kf: f64,
}

/// A law of the card with its gains, output-referred (the thesis's Ke, Be, Km).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Law {
    /// τ = Ke(xD − x1) − Be·ẋ1.
    PdColocated { ke: f64, be: f64 },
    /// τ = Ke(xD − x2) − Be·ẋ2 (needs an output encoder).
    PdNonColocated { ke: f64, be: f64 },
    /// τ = Ke(τD − τenv) − Be·ẋ1: P force with input-velocity damping (Eqn 3.3.16); Ke is
    /// dimensionless, Be in N·m·s/rad.
    ForceInputDamping { ke: f64, be: f64 },
    /// τ = Ke(τD − τenv) − Be·τ̇env: PD force on the force rate (Eqn 3.3.14); Be in s.
    ForceRate { ke: f64, be: f64 },
    /// τ = Ke(xD − x1) − Be·ẋ1 + Km·τenv (Eqn 3.3.20).
    ImpedanceColocated { ke: f64, be: f64, km: f64 },
    /// τ = Ke(xD − x2) − Be·ẋ2 + Km·τenv (Eqn 3.3.19).
    ImpedanceNonColocated { ke: f64, be: f64, km: f64 },
}

impl Law {
    /// The law as feedback τ = −(p1 + d1·s)·x1 − (p2 + d2·s)·x2 on the plant `p`:
    /// (p1, d1, p2, d2). τenv = Kf·x2.
    pub(super) fn feedback(&self, p: &TwoMass) -> (f64, f64, f64, f64) {
        match *self {
            Law::PdColocated { ke, be } => (ke, be, 0.0, 0.0),
            Law::PdNonColocated { ke, be } => (0.0, 0.0, ke, be),
            Law::ForceInputDamping { ke, be } => (0.0, be, ke * p.kf, 0.0),
            Law::ForceRate { ke, be } => (0.0, 0.0, ke * p.kf, be * p.kf),
            Law::ImpedanceColocated { ke, be, km } => (ke, be, -km * p.kf, 0.0),
            Law::ImpedanceNonColocated { ke, be, km } => (0.0, 0.0, ke - km * p.kf, be),
        }
    }
}

/// The closed loop's characteristic polynomial [A, B, C, D, E] (s⁴ … s⁰): the determinant of
///
/// ```text
/// | I1 s² + (B1 + d1) s + KT + p1     −KT + p2 + d2 s    |
/// | −KT                               I2 s² + B2 s + KT + Kf |
/// ```
pub fn characteristic(p: &TwoMass, law: &Law) -> [f64; 5] {
    let (p1, d1, p2, d2) = law.feedback(p);
    let a = [p.j1, p.b1 + d1, p.kt + p1];
    let b = [p.j2, p.b2, p.kt + p.kf];
    let mut c = [0.0; 5];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            c[i + j] += x * y;
        }
    }
    // + KT·(−KT + p2 + d2 s)
    c[3] += p.kt * d2;
    c[4] += p.kt * (p2 - p.kt);
    c
}

/// The Routh array's first column for polynomial `c` (highest power first). It stops at a
/// zero pivot, whose 0 it keeps: a root on (or mirrored about) the imaginary axis, which
/// [`stable`] reads as not stable.
pub fn first_column(c: &[f64]) -> Vec<f64> {
    let n = c.len();
    let width = n.div_ceil(2);
    let mut rows: Vec<Vec<f64>> = vec![vec![0.0; width + 1]; n];
    for (k, v) in c.iter().enumerate() {
        rows[k % 2][k / 2] = *v;
    }
    let mut column: Vec<f64> = rows.iter().take(2.min(n)).map(|r| r[0]).collect();
    for r in 2..n {
        let pivot = rows[r - 1][0];
        if pivot == 0.0 {
            return column;
        }
        for k in 0..width {
            rows[r][k] = (pivot * rows[r - 2][k + 1] - rows[r - 2][0] * rows[r - 1][k + 1]) / pivot;
        }
        column.push(rows[r][0]);
    }
    column
}

/// Every root in the open left half-plane: the first column complete and all positive (for
/// a positive leading coefficient).
pub fn stable(c: &[f64]) -> bool {
    let col = first_column(c);
    col.len() == c.len() && col.iter().all(|v| *v > 0.0)
}

/// The largest gain in `lo..hi` below which `stable_at` holds, found by bisection in log
/// space to a relative width of `rel`: `None` if `stable_at(lo)` fails, `Some(hi)` if the
/// whole range is stable.
pub fn boundary(stable_at: impl Fn(f64) -> bool, lo: f64, hi: f64, rel: f64) -> Option<f64> {
    if !stable_at(lo) {
        return None;
    }
    if stable_at(hi) {
        return Some(hi);
    }
    let (mut a, mut b) = (lo.ln(), hi.ln());
    while b - a > rel {
        let m = 0.5 * (a + b);
        if stable_at(m.exp()) {
            a = m;
        } else {
            b = m;
        }
    }
    Some((0.5 * (a + b)).exp())
}

/// The thesis's closed form for non-colocated PD in free space (§3.3, the quartic's
/// next-to-last Routh term D − B²E/(BC − AD) = 0 solved for Ke): the largest stable Ke at
/// damping `be`. `None` where BC − AD ≤ 0 (no Ke is stable).
pub fn pd_noncolocated_ke_max(p: &TwoMass, be: f64) -> Option<f64> {
    let a = p.j1 * p.j2;
    let b = p.b1 * p.j2 + p.b2 * p.j1;
    let c = p.kt * (p.j1 + p.j2) + p.b1 * p.b2;
    let d = p.kt * (p.b1 + p.b2 + be);
    let bc_ad = b * c - a * d;
    (bc_ad > 0.0).then(|| d * bc_ad / (b * b * p.kt))
}

/// The thesis's closed forms for P force control in contact (Eqns 3.3.14 and 3.3.18, the same
/// Routh term solved for Ke): the largest stable force gain with force-rate damping `be` (s)
/// or with input-velocity damping `be` (N·m·s/rad).
pub fn force_ke_max(p: &TwoMass, be: f64, input_damping: bool) -> Option<f64> {
    let (b1, bf) = if input_damping {
        (p.b1 + be, 0.0)
    } else {
        (p.b1, be)
    };
    let a = p.j1 * p.j2;
    let b = b1 * p.j2 + p.b2 * p.j1;
    let c = p.kt * (p.j1 + p.j2) + p.kf * p.j1 + b1 * p.b2;
    let d = b1 * (p.kt + p.kf) + p.b2 * p.kt + bf * p.kf * p.kt;
    let bc_ad = b * c - a * d;
    (bc_ad > 0.0).then(|| d * bc_ad / (b * b * p.kt * p.kf) - 1.0)
}

/// The roots of polynomial `c` (highest power first, `c[0] ≠ 0`): the eigenvalues of its
/// companion matrix.
pub fn roots(c: &[f64]) -> Vec<nalgebra::Complex<f64>> {
    let n = c.len().saturating_sub(1);
    if n == 0 || c[0] == 0.0 {
        return Vec::new();
    }
    let mut m = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        m[(0, i)] = -c[i + 1] / c[0];
        if i + 1 < n {
            m[(i + 1, i)] = 1.0;
        }
    }
    m.complex_eigenvalues().iter().copied().collect()
}

/// The dominant pair among `poles`: of those that oscillate, the one closest to the
/// imaginary axis (decaying slowest), as (ζ, ωn in rad/s). `None` when no pole oscillates.
pub fn dominant(poles: &[nalgebra::Complex<f64>]) -> Option<(f64, f64)> {
    poles
        .iter()
        .filter(|s| s.im > 1e-6 * s.norm().max(1e-12))
        .max_by(|a, b| a.re.total_cmp(&b.re))
        .map(|s| (-s.re / s.norm(), s.norm()))
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: TwoMass = TwoMass {
        j1: 2.0,
        b1: 0.7,
        kt: 300.0,
        j2: 3.0,
        b2: 1.1,
        kf: 0.0,
    };

    fn close(a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{a:?} vs {b:?}");
        }
    }

    /// The coefficient lists the thesis prints (§3.3: the free non-colocated and colocated PD,
    /// Eqn 3.3.14's force-rate PD, Eqn 3.3.18's P force with input damping), written out term
    /// by term, against the determinant.
    #[test]
    fn the_determinant_gives_the_thesis_coefficients() {
        let (j1, b1, kt, j2, b2) = (P.j1, P.b1, P.kt, P.j2, P.b2);
        let (ke, be) = (40.0, 3.0);
        close(
            &characteristic(&P, &Law::PdNonColocated { ke, be }),
            &[
                j1 * j2,
                b1 * j2 + b2 * j1,
                kt * (j1 + j2) + b1 * b2,
                kt * (b1 + b2 + be),
                kt * ke,
            ],
        );
        close(
            &characteristic(&P, &Law::PdColocated { ke, be }),
            &[
                j1 * j2,
                b1 * j2 + b2 * j1 + be * j2,
                kt * (j1 + j2) + ke * j2 + b2 * (b1 + be),
                kt * (b1 + b2 + be) + b2 * ke,
                kt * ke,
            ],
        );
        let c = TwoMass { kf: 5000.0, ..P };
        let kf = c.kf;
        let (kp, bf) = (2.0, 0.004);
        close(
            &characteristic(&c, &Law::ForceRate { ke: kp, be: bf }),
            &[
                j1 * j2,
                b1 * j2 + b2 * j1,
                kt * (j1 + j2) + kf * j1 + b1 * b2,
                b1 * (kt + kf) + b2 * kt + bf * kf * kt,
                kt * kf * (1.0 + kp),
            ],
        );
        close(
            &characteristic(&c, &Law::ForceInputDamping { ke: kp, be }),
            &[
                j1 * j2,
                b1 * j2 + b2 * j1 + be * j2,
                kt * (j1 + j2) + kf * j1 + b2 * (b1 + be),
                (kt + kf) * (b1 + be) + kt * b2,
                kt * kf * (1.0 + kp),
            ],
        );
        // Impedance: the constant and s¹ terms the thesis gives.
        let km = -0.4;
        let co = characteristic(&c, &Law::ImpedanceColocated { ke, be, km });
        close(
            &co[3..],
            &[
                (b1 + be) * (kt + kf) + b2 * (kt + ke),
                ke * (kt + kf) + kt * kf * (1.0 - km),
            ],
        );
        let nc = characteristic(&c, &Law::ImpedanceNonColocated { ke, be, km });
        close(
            &nc[3..],
            &[
                kt * (b1 + b2 + be) + b1 * kf,
                ke * kt + kt * kf * (1.0 - km),
            ],
        );
    }

    /// The Routh array and the closed forms find the same boundaries.
    #[test]
    fn routh_and_the_closed_forms_agree() {
        for be in [0.0, 0.5, 1.0, 1.5] {
            let closed = pd_noncolocated_ke_max(&P, be).unwrap();
            let r = boundary(
                |ke| stable(&characteristic(&P, &Law::PdNonColocated { ke, be })),
                1e-3,
                1e7,
                1e-9,
            )
            .unwrap();
            assert!((r / closed - 1.0).abs() < 1e-6, "Be {be}: {r} vs {closed}");
        }
        let c = TwoMass { kf: 5000.0, ..P };
        for (be, input) in [(1e-4, false), (1e-3, false), (1.0, true), (30.0, true)] {
            let closed = force_ke_max(&c, be, input).unwrap();
            let law = |ke| {
                if input {
                    Law::ForceInputDamping { ke, be }
                } else {
                    Law::ForceRate { ke, be }
                }
            };
            let r = boundary(|ke| stable(&characteristic(&c, &law(ke))), 1e-4, 1e4, 1e-9).unwrap();
            assert!(
                (r / closed - 1.0).abs() < 1e-6,
                "{be} {input}: {r} vs {closed}"
            );
        }
    }

    /// The Routh verdict agrees with the roots on random quartics.
    #[test]
    fn routh_matches_the_roots() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let c: Vec<f64> = std::iter::once(1.0)
                .chain((0..4).map(|_| 10f64.powf(3.0 * next() - 1.0)))
                .collect();
            let by_roots = roots(&c).iter().all(|s| s.re < 0.0);
            assert_eq!(stable(&c), by_roots, "{c:?}: {:?}", roots(&c));
        }
        // Roots on the imaginary axis are not stable: s² + 1 and (s² + 1)(s + 1)².
        assert!(!stable(&[1.0, 0.0, 1.0]));
        assert!(!stable(&[1.0, 2.0, 2.0, 2.0, 1.0]));
        // (s + 1)(s + 2)(s² + 2s + 5): roots −1, −2, −1 ± 2j.
        let mut r: Vec<(f64, f64)> = roots(&[1.0, 5.0, 13.0, 19.0, 10.0])
            .iter()
            .map(|z| (z.re, z.im))
            .collect();
        r.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.total_cmp(&b.0)));
        let want = [(-1.0, -2.0), (-2.0, 0.0), (-1.0, 0.0), (-1.0, 2.0)];
        for (g, w) in r.iter().zip(want) {
            assert!(
                (g.0 - w.0).abs() < 1e-9 && (g.1 - w.1).abs() < 1e-9,
                "{r:?}"
            );
        }
        let (zeta, wn) = dominant(&roots(&[1.0, 5.0, 13.0, 19.0, 10.0])).unwrap();
        assert!((wn - 5f64.sqrt()).abs() < 1e-9 && (zeta - 1.0 / 5f64.sqrt()).abs() < 1e-9);
    }
}
