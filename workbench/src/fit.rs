//! Solvers: linear least squares and Levenberg–Marquardt, both with a batch-means (block
//! long-run variance) sandwich covariance. See [`super::stats`] for why the covariance is not
//! the textbook `σ²(XᵀX)⁻¹`: equation-error residuals are autocorrelated.

use nalgebra::{DMatrix, DVector};

use super::stats;

/// Number of contiguous blocks for the batch-means covariance (fewer on short records).
pub const BLOCKS: usize = 32;

/// A linear least-squares fit.
#[derive(Debug, Clone)]
pub struct LsFit {
    /// Estimates, one per column.
    pub theta: Vec<f64>,
    /// Batch-means sandwich covariance of the estimates.
    pub cov: DMatrix<f64>,
    /// Residual `y − Xθ`.
    pub residual: Vec<f64>,
    /// Residual sum of squares.
    pub rss: f64,
    /// Blocks used for the covariance.
    pub blocks: usize,
    /// `θᵀNθ`, N the regressors' noise covariance a compensated fit took off the Gram matrix
    /// (0 for plain least squares): the part of [`LsFit::rss`] that is the regressors' own
    /// noise passed through the fitted model. `rss − noise_rss` estimates the RSS the same
    /// parameters would leave on noise-free regressors — the criterion to compare shapes
    /// by (see [`least_squares_noise`]).
    pub noise_rss: f64,
    /// Standard deviation of the noise energy behind [`LsFit::noise_rss`] on a record of this
    /// length (0 when not computed; see `residual::noise_energy_sd`).
    pub noise_rss_sd: f64,
}

impl LsFit {
    /// 1σ of parameter `j`.
    pub fn sigma(&self, j: usize) -> f64 {
        self.cov[(j, j)].max(0.0).sqrt()
    }

    /// Wald test that the parameters `idx` are all zero, referred to `F(q, m−q)` with the
    /// Hotelling correction for `m` batch means. Returns (F statistic, p-value).
    pub fn wald(&self, idx: &[usize]) -> (f64, f64) {
        self.wald_scaled(idx, 1.0)
    }

    /// [`LsFit::wald`] with the statistic scaled by `scale` (the share of the fit's explained
    /// energy a correction keeps) before its p-value is taken.
    pub fn wald_scaled(&self, idx: &[usize], scale: f64) -> (f64, f64) {
        let q = idx.len();
        let m = self.blocks;
        if q == 0 || m <= q {
            return (0.0, 1.0);
        }
        let v = DMatrix::from_fn(q, q, |a, b| self.cov[(idx[a], idx[b])]);
        if v.iter().any(|x| !x.is_finite()) {
            return (0.0, 1.0);
        }
        let g = DVector::from_iterator(q, idx.iter().map(|&i| self.theta[i]));
        let w = match v.clone().try_inverse() {
            Some(vi) => (g.transpose() * vi * &g)[(0, 0)],
            None => match v.pseudo_inverse(1e-12) {
                Ok(vi) => (g.transpose() * vi * &g)[(0, 0)],
                Err(_) => 0.0,
            },
        };
        let f = scale * w.max(0.0) * (m - q) as f64 / ((m - 1) as f64 * q as f64);
        (f, stats::f_sf(f, q as f64, (m - q) as f64))
    }
}

/// Error from a solver.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Not enough data for the parameters.
    #[error("{0} samples are too few for {1} parameters")]
    TooFew(usize, usize),
    /// A regressor or the target holds NaN/inf.
    #[error("non-finite value in the regression data")]
    NonFinite,
    /// The data are finite but the solution is not: a sum of squares or a product
    /// overflowed (values near the largest `f64`).
    #[error(
        "the least-squares solution is not finite ({what}): the data's magnitudes overflow \
         double precision in its sums of squares"
    )]
    NonFiniteResult {
        /// Which output (estimates or residual sum of squares).
        what: &'static str,
    },
    /// There is nothing to fit.
    #[error("the model has no free parameter to fit (mark one `free = true`, or add an effect)")]
    NothingFree,
    /// The fitted model scores non-finite on a record.
    #[error("the fitted model's {what} on {record} is {value}: the fit overflowed")]
    NonFiniteScore {
        /// Which score.
        what: &'static str,
        /// Which record (estimation or validation).
        record: &'static str,
        /// Its value.
        value: f64,
    },
}

// The normal-equation pieces are sim-plant's (one solver for the workspace); the fits here
// add the batch-means covariance and the noise compensation.
use sim_plant::lstsq::inverse_sqrt_diagonal;
pub use sim_plant::lstsq::{gram, gram_inverse};

/// `Σₖ a[k]·b[k]` for each `b` in `bs`, each as `Iterator::sum` over the pair's common length
/// (in row order, from −0), to the bit. Four sums share a pass over the rows, their chains of
/// dependent additions overlapping: a candidate's cross products with the model's columns are
/// much of a shape search's time.
pub fn cross_sums(a: &[f64], bs: &[&[f64]]) -> Vec<f64> {
    let plain = |b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
    let mut out = Vec::with_capacity(bs.len());
    for group in bs.chunks(4) {
        match group {
            [b0, b1, b2, b3] if [b0, b1, b2, b3].iter().all(|b| b.len() == a.len()) => {
                let mut acc = [-0.0f64; 4];
                for ((((x, y0), y1), y2), y3) in a.iter().zip(*b0).zip(*b1).zip(*b2).zip(*b3) {
                    acc[0] += x * y0;
                    acc[1] += x * y1;
                    acc[2] += x * y2;
                    acc[3] += x * y3;
                }
                out.extend(acc);
            }
            _ => out.extend(group.iter().map(|b| plain(b))),
        }
    }
    out
}

/// Batch-means sandwich covariance for regressors `cols` and residual `e`.
pub fn batch_covariance(
    cols: &[Vec<f64>],
    e: &[f64],
    ginv: &DMatrix<f64>,
) -> (DMatrix<f64>, usize) {
    let n = e.len();
    let p = cols.len();
    let m = BLOCKS.min(n / 20).max(2);
    let mut omega = DMatrix::<f64>::zeros(p, p);
    for b in 0..m {
        let (lo, hi) = (b * n / m, (b + 1) * n / m);
        let batch: Vec<&[f64]> = cols.iter().map(|c| &c[lo..hi]).collect();
        let s = cross_sums(&e[lo..hi], &batch);
        for i in 0..p {
            for j in 0..p {
                omega[(i, j)] += s[i] * s[j];
            }
        }
    }
    omega *= m as f64 / (m - 1) as f64;
    (ginv * omega * ginv, m)
}

/// Ordinary least squares `y ≈ Σ θ_j·cols[j]` with batch-means covariance.
pub fn least_squares(cols: &[Vec<f64>], y: &[f64]) -> Result<LsFit, FitError> {
    least_squares_compensated(cols, y, &[])
}

/// Bias-compensated least squares: as [`least_squares`], with `noise[j]` (the summed variance
/// of column `j`'s own white measurement noise, `n·σ²`; missing entries are 0) taken off the
/// Gram matrix's diagonal. A regressor measured with noise inflates `XᵀX` but not `Xᵀy`, which
/// shrinks its coefficient (errors-in-variables); with the noise variance known the shrinkage
/// is undone. Compensation is capped at half the column's energy, so a misjudged noise level
/// cannot turn the Gram matrix indefinite.
pub fn least_squares_compensated(
    cols: &[Vec<f64>],
    y: &[f64],
    noise: &[f64],
) -> Result<LsFit, FitError> {
    let entries: Vec<(usize, usize, f64)> =
        noise.iter().enumerate().map(|(j, &v)| (j, j, v)).collect();
    least_squares_noise_cov(cols, y, &entries)
}

/// Bias-compensated least squares with a noise *covariance* given entry by entry: as
/// [`least_squares_compensated`], where `noise` lists `(j, k, v)`, the summed covariance `v`
/// of the white measurement noise of columns `j` and `k` (`j == k`: a variance; `j ≠ k` is
/// applied to both off-diagonal entries). Two columns built from the same noisy measurement
/// share its noise — the motor's acceleration and the measured deflection's δ̈ = a_motor −
/// a_load both hold the motor encoder's — and that shared noise inflates their cross product
/// in `XᵀX` just as a column's own noise inflates its diagonal. Diagonal entries are capped
/// at half the column's energy, off-diagonal ones at half the geometric mean of the two
/// (after the diagonal's cap), so a misjudged noise level cannot turn the Gram matrix
/// indefinite. ([`least_squares_noise`] takes a whole matrix and scales it instead.)
pub fn least_squares_noise_cov(
    cols: &[Vec<f64>],
    y: &[f64],
    noise: &[(usize, usize, f64)],
) -> Result<LsFit, FitError> {
    solve_compensated(cols, y, |g| {
        let p = g.nrows();
        let mut nm = DMatrix::<f64>::zeros(p, p);
        // max/min, not clamp: a non-finite Gram matrix is the solver's error to report.
        for &(j, _, v) in noise.iter().filter(|e| e.0 == e.1 && e.0 < p) {
            nm[(j, j)] += v.max(0.0).min(0.5 * g[(j, j)]);
        }
        for &(j, k, v) in noise.iter().filter(|e| e.0 != e.1 && e.0 < p && e.1 < p) {
            let cap = 0.5
                * ((g[(j, j)] - nm[(j, j)]) * (g[(k, k)] - nm[(k, k)]))
                    .max(0.0)
                    .sqrt();
            let v = v.max(-cap).min(cap);
            nm[(j, k)] += v;
            nm[(k, j)] += v;
        }
        nm
    })
}

/// Bias-compensated least squares with the regressors' noise covariance `noise` (p×p,
/// summed over the rows: `n·Cov(noise)`; smaller matrices are padded with zeros): solves
/// `(XᵀX − N)·θ = Xᵀy`, which minimises `‖y − Xθ‖² − θᵀNθ`, the residual the same θ would
/// leave on noise-free regressors (plus a constant). The errors-in-variables case of several
/// columns filtered from one noisy signal (the acceleration and a resonant filter of it): the
/// noise is correlated across them and the off-diagonal terms matter. N is scaled down, if
/// need be, so that `XᵀX − N` keeps at least half of `XᵀX` in every direction (a misjudged
/// noise level cannot make the problem indefinite).
pub fn least_squares_noise(
    cols: &[Vec<f64>],
    y: &[f64],
    noise: &DMatrix<f64>,
) -> Result<LsFit, FitError> {
    solve_compensated(cols, y, |g| {
        let p = g.nrows();
        let nm = DMatrix::from_fn(p, p, |i, j| {
            if i < noise.nrows() && j < noise.ncols() {
                noise[(i, j)]
            } else {
                0.0
            }
        });
        nm.scale(noise_scale(g, &nm))
    })
}

/// Whether every value is finite: `x·0` is ±0 for a finite `x` and NaN for ±∞ and NaN, so
/// a block's sum of them is zero exactly when all are. Summed in four lanes, which the
/// compiler vectorises (a short-circuiting `any` over a design's columns was a tenth of a
/// compliance search's time), block by block to stop at the first that holds one.
fn all_finite(xs: &[f64]) -> bool {
    xs.chunks(2048).all(|block| {
        let rows = block.chunks_exact(4);
        let tail = rows.remainder().iter().fold(0.0, |a, x| a + x * 0.0);
        let mut acc = [0.0f64; 4];
        for x in rows {
            for k in 0..4 {
                acc[k] += x[k] * 0.0;
            }
        }
        (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail == 0.0
    })
}

/// Solves `(XᵀX − N)·θ = Xᵀy` with `N = noise_of(XᵀX)` (the callers' caps need the Gram
/// matrix, which is formed once here).
fn solve_compensated(
    cols: &[Vec<f64>],
    y: &[f64],
    noise_of: impl Fn(&DMatrix<f64>) -> DMatrix<f64>,
) -> Result<LsFit, FitError> {
    let n = y.len();
    let p = cols.len();
    if n < p + 2 {
        return Err(FitError::TooFew(n, p));
    }
    if !all_finite(y) || !cols.iter().all(|c| all_finite(c)) {
        return Err(FitError::NonFinite);
    }
    let mut g = gram(cols);
    let nm = noise_of(&g);
    g -= &nm;
    let ginv = gram_inverse(&g);
    let xty = DVector::from_iterator(p, cols.iter().map(|c| sim_plant::lstsq::dot(c, y)));
    let theta = &ginv * xty;
    let mut residual = y.to_vec();
    for (j, c) in cols.iter().enumerate() {
        let t = theta[j];
        for (r, x) in residual.iter_mut().zip(c) {
            *r -= t * x;
        }
    }
    let rss = sim_plant::lstsq::dot(&residual, &residual);
    if theta.iter().any(|t| !t.is_finite()) {
        return Err(FitError::NonFiniteResult { what: "estimates" });
    }
    if !rss.is_finite() {
        return Err(FitError::NonFiniteResult {
            what: "residual sum of squares",
        });
    }
    let noise_rss = (theta.transpose() * &nm * &theta)[(0, 0)];
    let (cov, blocks) = batch_covariance(cols, &residual, &ginv);
    Ok(LsFit {
        theta: theta.iter().copied().collect(),
        cov,
        residual,
        rss,
        blocks,
        noise_rss: if noise_rss.is_finite() {
            noise_rss
        } else {
            0.0
        },
        noise_rss_sd: 0.0,
    })
}

/// Factor in (0, 1] for the noise matrix `nm` so that `g − factor·nm ⪰ ½·g`: the largest
/// eigenvalue λ of `D·nm·D` relative to `D·g·D` (D the Gram diagonal's inverse square roots,
/// then a Cholesky whitening of the scaled Gram) is held to ½. 1 when it already is, or when
/// nothing is to be compensated; 0 when the Gram matrix is not positive definite.
fn noise_scale(g: &DMatrix<f64>, nm: &DMatrix<f64>) -> f64 {
    if nm.iter().all(|v| *v == 0.0) {
        return 1.0;
    }
    let p = g.nrows();
    let d = inverse_sqrt_diagonal(g);
    let gs = DMatrix::from_fn(p, p, |i, j| {
        g[(i, j)] * d[i] * d[j] + if i == j && d[i] == 0.0 { 1.0 } else { 0.0 }
    });
    let ns = DMatrix::from_fn(p, p, |i, j| nm[(i, j)] * d[i] * d[j]);
    let Some(ch) = gs.cholesky() else {
        return 0.0;
    };
    let l = ch.l();
    let Some(li) = l.try_inverse() else {
        return 0.0;
    };
    let m = &li * ns * li.transpose();
    let m = (&m + m.transpose()).scale(0.5);
    let lmax = m
        .symmetric_eigenvalues()
        .iter()
        .fold(0.0f64, |a, &b| a.max(b));
    if lmax.is_finite() && lmax > 0.5 {
        0.5 / lmax
    } else if lmax.is_finite() {
        1.0
    } else {
        0.0
    }
}

/// Result of a Levenberg–Marquardt fit.
#[derive(Debug, Clone)]
pub struct LmFit {
    /// Estimates.
    pub x: Vec<f64>,
    /// Batch-means sandwich covariance from the final Jacobian.
    pub cov: DMatrix<f64>,
    /// Final residual.
    pub residual: Vec<f64>,
    /// Iterations used.
    pub iterations: usize,
}

/// Levenberg–Marquardt on `f(x) = residual` with a forward-difference Jacobian (relative
/// step). Marquardt's diagonal scaling makes it indifferent to parameter units.
pub fn levenberg_marquardt<F: Fn(&[f64]) -> Vec<f64>>(f: F, x0: &[f64], max_iter: usize) -> LmFit {
    let p = x0.len();
    let mut x = x0.to_vec();
    let mut r = f(&x);
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    let jac = |x: &[f64], r: &[f64]| -> Vec<Vec<f64>> {
        (0..p)
            .map(|j| {
                let h = 1e-6 * x[j].abs().max(1e-8);
                let mut xp = x.to_vec();
                xp[j] += h;
                let rp = f(&xp);
                rp.iter().zip(r).map(|(a, b)| (a - b) / h).collect()
            })
            .collect()
    };
    let mut it = 0;
    let mut j = jac(&x, &r);
    while it < max_iter {
        it += 1;
        let g = gram(&j);
        let grad = DVector::from_iterator(
            p,
            j.iter().map(|c| c.iter().zip(&r).map(|(a, b)| a * b).sum()),
        );
        let mut improved = false;
        for _ in 0..20 {
            let mut a = g.clone();
            for i in 0..p {
                a[(i, i)] += lambda * g[(i, i)].max(1e-300);
            }
            let step = match a.clone().lu().solve(&(-&grad)) {
                Some(s) => s,
                None => break,
            };
            let xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            let rn = f(&xn);
            let cn: f64 = rn.iter().map(|v| v * v).sum();
            if cn.is_finite() && cn < cost {
                let rel = (cost - cn) / cost.max(1e-300);
                x = xn;
                r = rn;
                cost = cn;
                lambda = (lambda * 0.3).max(1e-12);
                improved = true;
                if rel < 1e-10 {
                    it = max_iter;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
        j = jac(&x, &r);
    }
    let g = gram(&j);
    let ginv = gram_inverse(&g);
    let (cov, _) = batch_covariance(&j, &r, &ginv);
    LmFit {
        x,
        cov,
        residual: r,
        iterations: it,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    /// The cross products in one pass are the plain sums, to the bit (equal lengths), and
    /// the plain sums over each pair's common length otherwise.
    #[test]
    fn cross_sums_are_the_plain_sums_to_the_bit() {
        let a: Vec<f64> = (0..1001).map(|k| (k as f64 * 0.37).sin()).collect();
        let b: Vec<f64> = (0..1001)
            .map(|k| ((k * 7 % 11) as f64 - 5.0) * 0.3)
            .collect();
        let c: Vec<f64> = (0..1001).map(|k| (k as f64).sqrt()).collect();
        let plain = |x: &[f64], y: &[f64]| -> f64 { x.iter().zip(y).map(|(p, q)| p * q).sum() };
        // Signed zeros too: a zero column against negative values.
        let (zeros, minus) = (vec![0.0; 1001], vec![-1.0; 1001]);
        let got = cross_sums(&zeros, &[&minus, &b, &minus, &c]);
        for (g, y) in got.iter().zip([&minus, &b, &minus, &c]) {
            assert_eq!(g.to_bits(), plain(&zeros, y).to_bits());
        }
        let got = cross_sums(&a, &[&b, &c, &a, &zeros, &minus, &c]);
        for (g, y) in got.iter().zip([&b, &c, &a, &zeros, &minus, &c]) {
            assert_eq!(g.to_bits(), plain(&a, y).to_bits());
        }
        let got = cross_sums(&a, &[&b[..500], &c, &a, &b]);
        for (g, y) in got.iter().zip([&b[..500], &c, &a, &b]) {
            assert_eq!(g.to_bits(), plain(&a, y).to_bits());
        }
    }

    /// The batch sums, taken column by column with `Iterator::sum` over each batch: the
    /// covariance is the same to the bit however the loop is arranged.
    #[test]
    fn batch_sums_are_the_plain_sums_to_the_bit() {
        let n = 1003;
        let e: Vec<f64> = (0..n)
            .map(|k| ((k * 37 % 101) as f64 - 50.0) * 1e-3)
            .collect();
        let cols: Vec<Vec<f64>> = vec![
            (0..n).map(|k| (k as f64 * 0.01).sin()).collect(),
            vec![0.0; n],
            (0..n).map(|k| ((k % 13) as f64).sqrt() - 1.7).collect(),
        ];
        let ginv = gram_inverse(&gram(&cols));
        let (cov, m) = batch_covariance(&cols, &e, &ginv);
        let p = cols.len();
        let mut omega = DMatrix::<f64>::zeros(p, p);
        for b in 0..m {
            let (lo, hi) = (b * n / m, (b + 1) * n / m);
            let s: Vec<f64> = cols
                .iter()
                .map(|c| c[lo..hi].iter().zip(&e[lo..hi]).map(|(x, r)| x * r).sum())
                .collect();
            for i in 0..p {
                for j in 0..p {
                    omega[(i, j)] += s[i] * s[j];
                }
            }
        }
        omega *= m as f64 / (m - 1) as f64;
        let reference = &ginv * omega * &ginv;
        assert!(cov
            .iter()
            .zip(reference.iter())
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn ls_recovers_coefficients() {
        let n = 2000;
        let x1: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin()).collect();
        let x2: Vec<f64> = vec![1.0; n];
        let y: Vec<f64> = (0..n)
            .map(|i| 3.0 * x1[i] - 2.0 + 0.01 * ((i * 7919 % 101) as f64 / 50.0 - 1.0))
            .collect();
        let f = least_squares(&[x1, x2], &y).unwrap();
        assert!((f.theta[0] - 3.0).abs() < 1e-2 && (f.theta[1] + 2.0).abs() < 1e-2);
        assert!(f.sigma(0) > 0.0 && f.sigma(0) < 0.01);
        let (_, p) = f.wald(&[0]);
        assert!(p < 1e-6);
    }

    /// A regressor measured with white noise of known variance: plain least squares shrinks
    /// its coefficient by var(x)/(var(x) + σ²); the compensated fit does not.
    #[test]
    fn compensation_undoes_errors_in_variables_shrinkage() {
        let n = 20_000;
        // Deterministic pseudo-noise, uniform on ±0.5·√12·σ (variance σ²), uncorrelated with x.
        let sigma: f64 = 0.5;
        let noise = |i: usize| {
            let u = super::super::stats::tests_support::unit_uniform(i as u64);
            (u - 0.5) * 12f64.sqrt() * sigma
        };
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.013).sin()).collect();
        let y: Vec<f64> = x.iter().map(|x| 2.0 * x).collect();
        let xm: Vec<f64> = x.iter().enumerate().map(|(i, x)| x + noise(i)).collect();
        let ols = least_squares(std::slice::from_ref(&xm), &y).unwrap();
        // var(sin) = ½: OLS gives 2·0.5/(0.5 + 0.25) = 1.33.
        assert!((ols.theta[0] - 4.0 / 3.0).abs() < 0.03, "{}", ols.theta[0]);
        let bc = least_squares_compensated(&[xm], &y, &[n as f64 * sigma * sigma]).unwrap();
        assert!((bc.theta[0] - 2.0).abs() < 0.05, "{}", bc.theta[0]);
    }

    /// Two regressors sharing one measurement's noise (x1 + n1 and a difference x1 − x2 +
    /// n1 − n2, as the motor's acceleration and the measured deflection's δ̈): the diagonal
    /// compensation alone leaves a bias through the shared noise; with the covariance both
    /// coefficients come out right.
    #[test]
    fn covariance_compensation_handles_shared_noise() {
        let n = 40_000;
        // Noise variance below half the difference column's signal (0.125): the compensation's
        // cap (half a column's energy) is not reached.
        let s1: f64 = 0.2;
        let s2: f64 = 0.2;
        let noise = |i: u64, s: f64| {
            let u = super::super::stats::tests_support::unit_uniform(i);
            (u - 0.5) * 12f64.sqrt() * s
        };
        let x1: Vec<f64> = (0..n).map(|i| (i as f64 * 0.013).sin()).collect();
        let x2: Vec<f64> = (0..n)
            .map(|i| (i as f64 * 0.013).sin() + 0.5 * (i as f64 * 0.0071).cos())
            .collect();
        // y = 3·x1 + 2·(x1 − x2) … written with a motor and a load measurement.
        let y: Vec<f64> = (0..n)
            .map(|i| 3.0 * x1[i] + 2.0 * (x1[i] - x2[i]))
            .collect();
        let n1: Vec<f64> = (0..n).map(|i| noise(i as u64, s1)).collect();
        let n2: Vec<f64> = (0..n)
            .map(|i| noise(i as u64 + 10 * n as u64, s2))
            .collect();
        let a: Vec<f64> = (0..n).map(|i| x1[i] + n1[i]).collect();
        let d: Vec<f64> = (0..n).map(|i| x1[i] - x2[i] + n1[i] - n2[i]).collect();
        let nf = n as f64;
        let (v1, v2) = (nf * s1 * s1, nf * s2 * s2);
        let diag = least_squares_compensated(&[a.clone(), d.clone()], &y, &[v1, v1 + v2]).unwrap();
        let full = least_squares_noise_cov(&[a, d], &y, &[(0, 0, v1), (1, 1, v1 + v2), (0, 1, v1)])
            .unwrap();
        assert!(
            (full.theta[0] - 3.0).abs() < 0.1 && (full.theta[1] - 2.0).abs() < 0.1,
            "{:?}",
            full.theta
        );
        assert!((diag.theta[1] - 2.0).abs() > 0.3, "{:?}", diag.theta);
    }

    /// Two regressors filtered from one noisy signal (the signal and its sum with its previous
    /// sample): their noise is correlated, and the full noise matrix `n·σ²·[[1, 1], [1, 2]]`
    /// undoes a shrinkage plain least squares shows in both coefficients.
    #[test]
    fn full_noise_matrix_undoes_correlated_shrinkage() {
        let n = 40_000;
        let sigma: f64 = 0.5;
        let uniform = super::super::stats::tests_support::unit_uniform;
        let x: Vec<f64> = (0..n as u64)
            .map(|i| (uniform(i + 1_000_000) - 0.5) * 12f64.sqrt())
            .collect();
        let e: Vec<f64> = (0..n as u64)
            .map(|i| (uniform(i) - 0.5) * 12f64.sqrt() * sigma)
            .collect();
        let pair = |v: &[f64]| -> Vec<f64> {
            (0..v.len())
                .map(|i| v[i] + if i > 0 { v[i - 1] } else { 0.0 })
                .collect()
        };
        let y: Vec<f64> = x.iter().zip(pair(&x)).map(|(a, b)| 2.0 * a + b).collect();
        let xm: Vec<f64> = x.iter().zip(&e).map(|(a, b)| a + b).collect();
        let cols = [xm.clone(), pair(&xm)];
        let ols = least_squares(&cols, &y).unwrap();
        assert!((ols.theta[0] - 2.0).abs() > 0.1, "{:?}", ols.theta);
        let s2 = n as f64 * sigma * sigma;
        let nm = DMatrix::from_row_slice(2, 2, &[s2, s2, s2, 2.0 * s2]);
        let bc = least_squares_noise(&cols, &y, &nm).unwrap();
        assert!(
            (bc.theta[0] - 2.0).abs() < 0.05 && (bc.theta[1] - 1.0).abs() < 0.05,
            "{:?}",
            bc.theta
        );
        // The noise those coefficients pass, θᵀNθ, is what the residual holds.
        assert!(
            (bc.noise_rss / bc.rss - 1.0).abs() < 0.05,
            "{} vs {}",
            bc.noise_rss,
            bc.rss
        );
    }

    /// Non-finite data is an error, not a panic (a diverged record holds NaN).
    #[test]
    fn non_finite_data_is_an_error() {
        let cols = [vec![1.0, f64::NAN, 2.0, 3.0, 4.0]];
        let y = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert!(matches!(least_squares(&cols, &y), Err(FitError::NonFinite)));
        assert!(matches!(
            least_squares_compensated(&cols, &y, &[1.0]),
            Err(FitError::NonFinite)
        ));
    }

    /// `all_finite` is `is_finite` on every value: ±∞ and every NaN refused wherever they
    /// sit (the first block, a later one, the last value), the extremes of the finite range
    /// and both zeros accepted.
    #[test]
    fn all_finite_is_is_finite_everywhere() {
        let finite = [
            0.0,
            -0.0,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
            -1.5,
        ];
        let bad = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff0_0000_0000_0001),
        ];
        for n in [1usize, 7, 2048, 2049, 5000] {
            let xs: Vec<f64> = (0..n).map(|k| finite[k % finite.len()]).collect();
            assert!(all_finite(&xs), "n {n}");
            for at in [0, n / 2, n - 1] {
                for &b in &bad {
                    let mut ys = xs.clone();
                    ys[at] = b;
                    assert!(!all_finite(&ys), "n {n}, {b} at {at}");
                }
            }
        }
        assert!(all_finite(&[]));
    }

    /// A noise matrix larger than half the Gram matrix is scaled down to it.
    #[test]
    fn noise_scale_keeps_half_the_gram() {
        let g = DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 2.0]);
        assert_eq!(noise_scale(&g, &DMatrix::zeros(2, 2)), 1.0);
        assert_eq!(noise_scale(&g, &g.scale(0.3)), 1.0);
        let f = noise_scale(&g, &g.scale(0.8));
        assert!((f - 0.625).abs() < 1e-9, "{f}");
    }

    #[test]
    fn lm_fits_an_exponential() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = t.iter().map(|&t| 2.0 * (-0.7 * t).exp()).collect();
        let fit = levenberg_marquardt(
            |p| {
                t.iter()
                    .zip(&y)
                    .map(|(&t, &y)| y - p[0] * (-p[1] * t).exp())
                    .collect()
            },
            &[1.0, 0.2],
            100,
        );
        assert!(
            (fit.x[0] - 2.0).abs() < 1e-6 && (fit.x[1] - 0.7).abs() < 1e-6,
            "{:?}",
            fit.x
        );
    }
}
