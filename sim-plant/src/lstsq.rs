//! Linear least squares through the normal equations, the one solver every fit in the
//! workspace uses (the workbench's regressions, the simulated thesis experiments, the
//! backlash grid's rigid fit, the lab's friction summary).
//!
//! The Gram matrix is scaled to a unit diagonal before its SVD pseudo-inverse is taken, so
//! badly scaled columns (a jerk next to a constant, metres next to newtons) and nearly
//! collinear ones do not blow the solution up.

use nalgebra::{DMatrix, DVector};

/// Relative singular-value tolerance of the scaled Gram matrix's pseudo-inverse.
pub const RCOND: f64 = 1e-12;

/// `Σ aₖ·bₖ` over the shorter of the two, in four interleaved partial sums: a sum in one
/// strict order cannot be vectorised, and the Gram matrix of a refit's design was a quarter
/// of a shape search's time. Deterministic: the order depends on the length only.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// [`dot`] of `a` with each of four columns of `a`'s length, to the bit, in one pass: `a` is
/// read once for the four sums. A design's columns are longer than the core's cache, so the
/// Gram matrix pair by pair was bound by reading them.
fn dot4(a: &[f64], b: [&[f64]; 4]) -> [f64; 4] {
    let mut acc = [[0.0f64; 4]; 4];
    let ca = a.chunks_exact(4);
    let tail = |bm: &[f64]| -> f64 {
        let rem = ca.remainder();
        rem.iter()
            .zip(&bm[bm.len() - rem.len()..])
            .map(|(x, y)| x * y)
            .sum()
    };
    let tails = [tail(b[0]), tail(b[1]), tail(b[2]), tail(b[3])];
    let rows = ca
        .zip(b[0].chunks_exact(4))
        .zip(b[1].chunks_exact(4))
        .zip(b[2].chunks_exact(4))
        .zip(b[3].chunks_exact(4));
    for ((((x, y0), y1), y2), y3) in rows {
        for k in 0..4 {
            acc[0][k] += x[k] * y0[k];
            acc[1][k] += x[k] * y1[k];
            acc[2][k] += x[k] * y2[k];
            acc[3][k] += x[k] * y3[k];
        }
    }
    let mut out = [0.0; 4];
    for ((o, a), t) in out.iter_mut().zip(acc).zip(tails) {
        *o = (a[0] + a[1]) + (a[2] + a[3]) + t;
    }
    out
}

/// Gram matrix `XᵀX` of column-major data: each entry [`dot`] of its two columns, to the
/// bit, four of a row's entries per pass where the columns have one length.
pub fn gram(cols: &[Vec<f64>]) -> DMatrix<f64> {
    let p = cols.len();
    let mut g = DMatrix::zeros(p, p);
    for i in 0..p {
        let a = &cols[i];
        let mut j = 0;
        while j <= i {
            let block = &cols[j..(j + 4).min(i + 1)];
            let mut sums = [0.0; 4];
            match block {
                [b0, b1, b2, b3] if block.iter().all(|b| b.len() == a.len()) => {
                    sums = dot4(a, [b0, b1, b2, b3]);
                }
                _ => {
                    for (s, b) in sums.iter_mut().zip(block) {
                        *s = dot(a, b);
                    }
                }
            }
            for (k, &s) in sums.iter().take(block.len()).enumerate() {
                g[(i, j + k)] = s;
                g[(j + k, i)] = s;
            }
            j += block.len();
        }
    }
    g
}

/// `1/√g_ii` (0 where the diagonal is not positive): the column scaling that puts a Gram
/// matrix's diagonal at 1.
pub fn inverse_sqrt_diagonal(g: &DMatrix<f64>) -> Vec<f64> {
    (0..g.nrows())
        .map(|i| {
            if g[(i, i)] > 0.0 {
                1.0 / g[(i, i)].sqrt()
            } else {
                0.0
            }
        })
        .collect()
}

/// Inverse of a Gram matrix through column scaling and an SVD pseudo-inverse, so nearly
/// collinear or badly scaled columns (jerk next to a constant) do not blow up. All NaN when
/// `g` is not finite.
pub fn gram_inverse(g: &DMatrix<f64>) -> DMatrix<f64> {
    let p = g.nrows();
    // No free parameter: nothing to invert (nalgebra's SVD panics on an empty matrix).
    if p == 0 {
        return DMatrix::zeros(0, 0);
    }
    // nalgebra's SVD does not terminate on NaN/inf input.
    if g.iter().any(|v| !v.is_finite()) {
        return DMatrix::from_element(p, p, f64::NAN);
    }
    let d = inverse_sqrt_diagonal(g);
    let gs = DMatrix::from_fn(p, p, |i, j| g[(i, j)] * d[i] * d[j]);
    let inv = gs
        .pseudo_inverse(RCOND)
        .unwrap_or_else(|_| DMatrix::zeros(p, p));
    DMatrix::from_fn(p, p, |i, j| inv[(i, j)] * d[i] * d[j])
}

/// Whether the scaled Gram matrix has full rank: every column carries energy and none is a
/// combination of the others (within [`RCOND`]). A fit that must identify every parameter
/// (a slope whose inverse is a stiffness) asks this before it trusts the solution.
pub fn full_rank(g: &DMatrix<f64>) -> bool {
    let p = g.nrows();
    if p == 0 || g.iter().any(|v| !v.is_finite()) {
        return false;
    }
    let d = inverse_sqrt_diagonal(g);
    if d.contains(&0.0) {
        return false;
    }
    let gs = DMatrix::from_fn(p, p, |i, j| g[(i, j)] * d[i] * d[j]);
    let sv = gs.singular_values();
    let max = sv.max();
    sv.iter().all(|&s| s > RCOND * max)
}

/// Ordinary least squares `y ≈ Σ θ_j·x_j` over rows `(x, y)` with `P` regressors; `None` if
/// the regressors do not identify every parameter ([`full_rank`]) or the solution is not
/// finite.
pub fn solve_rows<const P: usize>(rows: impl Iterator<Item = ([f64; P], f64)>) -> Option<[f64; P]> {
    let mut g = DMatrix::<f64>::zeros(P, P);
    let mut b = DVector::<f64>::zeros(P);
    for (x, y) in rows {
        let x = DVector::from_column_slice(&x);
        g += &x * x.transpose();
        b += x * y;
    }
    if !full_rank(&g) {
        return None;
    }
    let beta = gram_inverse(&g) * b;
    let mut out = [0.0; P];
    out.copy_from_slice(beta.as_slice());
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Ordinary least squares `y ≈ Σ θ_j·cols[j]` (columns of equal length); `None` as
/// [`solve_rows`].
pub fn solve(cols: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let g = gram(cols);
    if !full_rank(&g) {
        return None;
    }
    let xty = DVector::from_iterator(
        cols.len(),
        cols.iter()
            .map(|c| c.iter().zip(y).map(|(a, b)| a * b).sum()),
    );
    let theta = gram_inverse(&g) * xty;
    theta
        .iter()
        .all(|v| v.is_finite())
        .then(|| theta.iter().copied().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every length's tail is summed (0–3 left over), the shorter slice bounds it, and the
    /// value is the exact sum of integers.
    #[test]
    fn dot_sums_every_term() {
        for n in 0..13usize {
            let a: Vec<f64> = (0..n).map(|k| k as f64 + 1.0).collect();
            let b: Vec<f64> = (0..n + 2).map(|k| 2.0 * k as f64 - 3.0).collect();
            let want: f64 = (0..n)
                .map(|k| (k as f64 + 1.0) * (2.0 * k as f64 - 3.0))
                .sum();
            assert_eq!(dot(&a, &b), want, "n = {n}");
            assert_eq!(dot(&b, &a), want, "n = {n}");
        }
    }

    /// The Gram matrix is each pair's [`dot`] to the bit, whatever the column count (blocks of
    /// four and the rest), the length's tail, or a column of another length.
    #[test]
    fn gram_is_the_pairwise_dots_to_the_bit() {
        // Values with rounding in every product and sum (not integers, which sum exactly in
        // any order).
        let value = |c: usize, k: usize| ((c * 31 + k * 17) as f64 * 0.7371).sin() * 1e3 + 0.1;
        for n in [0usize, 1, 5, 64, 1001, 1002, 1003] {
            for p in 1..=10usize {
                let mut cols: Vec<Vec<f64>> = (0..p)
                    .map(|c| (0..n).map(|k| value(c, k)).collect())
                    .collect();
                if p == 7 {
                    cols[5].push(2.5);
                }
                let g = gram(&cols);
                for i in 0..p {
                    for j in 0..p {
                        let want = dot(&cols[i], &cols[j]);
                        assert_eq!(
                            g[(i, j)].to_bits(),
                            want.to_bits(),
                            "n {n} p {p} ({i}, {j})"
                        );
                    }
                }
            }
        }
    }

    /// A known line and plane come back; a constant column next to a scaled copy of itself,
    /// or an empty column, is refused rather than answered with an arbitrary split.
    #[test]
    fn recovers_exact_fits_and_refuses_rank_deficient_ones() {
        let rows = (0..20).map(|i| {
            let x = i as f64 * 0.1;
            ([1.0, x, x * x * 1e3], 2.0 - 3.0 * x + 0.5 * x * x * 1e3)
        });
        let b = solve_rows(rows).expect("full rank");
        for (got, want) in b.iter().zip([2.0, -3.0, 0.5]) {
            assert!((got - want).abs() < 1e-9, "{b:?}");
        }
        let twins = (0..20).map(|i| ([1.0, 2.0], i as f64));
        assert_eq!(solve_rows(twins), None);
        let empty = (0..20).map(|i| ([i as f64, 0.0], i as f64));
        assert_eq!(solve_rows(empty), None);

        let x: Vec<f64> = (0..50).map(|i| (i as f64 * 0.3).sin()).collect();
        let one = vec![1.0; 50];
        let y: Vec<f64> = x.iter().map(|v| 4.0 * v - 1.0).collect();
        let t = solve(&[x, one], &y).expect("full rank");
        assert!(
            (t[0] - 4.0).abs() < 1e-12 && (t[1] + 1.0).abs() < 1e-12,
            "{t:?}"
        );
        assert_eq!(solve(&[vec![0.0; 50]], &y), None);
    }
}
