//! The equation error's design: each effect's regressor columns on a prepared record, the
//! model's design matrix, the bias-compensated least-squares refit (the position noise's
//! covariance through the differentiator), and the predicted input.

use std::sync::Arc;

use sim_plant::effects::{fingerprint, EffectKind, Shape, Trajectory};

use super::super::diff;
use super::super::fit::{self, LsFit};
use super::super::model::Model;
use super::{ColumnMemo, Prepared};

/// Whether `kind`'s fingerprint columns get the input's zero-phase low-pass ("parallel
/// filtering"): the measured input is filtered (see [`Prepared::input`]), so a torque that is
/// a *nonlinear* function of the motion (a sign at each reversal, a short-period ripple)
/// reaches the residual band-limited; its column must be too, or every sharp edge leaves a
/// residual spike. Columns already built from filtered signals (v, derivatives of the filtered
/// position, the instrument: delay, dead zone, quantiser; backlash, built from the filtered
/// motion) and constants are left as they are (filtering the instrument-based dead-zone
/// columns again made them fit null records; filtering backlash cost it rank 1 in the bench).
fn filtered(kind: EffectKind) -> bool {
    kind.fit_traits().band_limit
}

fn band_limit(kind: EffectKind, t: &Trajectory, mut z: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    if filtered(kind) && t.dt > 0.0 && t.lowpass_hz > 0.0 {
        z = diff::filtfilt_each(z, t.lowpass_hz, 1.0 / t.dt);
    }
    z
}

/// Fingerprint columns of a *candidate* effect on prepared data, as the diagnosis tests them
/// (input-based columns from the instrument, nonlinear columns band-limited like the input).
pub fn candidate_columns(kind: EffectKind, p: &Prepared, shape: &Shape) -> Vec<Vec<f64>> {
    candidate_columns_on(kind, &p.trajectory(), shape)
}

/// [`candidate_columns`] on a trajectory (the diagnosis searches shapes on a window of a long
/// record).
pub fn candidate_columns_on(kind: EffectKind, t: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    band_limit(kind, t, fingerprint(kind, t, shape))
}

/// Fingerprint columns of an effect *in the model*. As [`candidate_columns`], except that a
/// delay acts on the measured input: once its τ is fitted (by a 1-D search, see
/// [`crate::refine`]; its amplitude is never a free least-squares column, see
/// [`design`]), the model's prediction is the input actually delayed, `û = u − (u − u(t − τ))`.
pub fn model_columns(kind: EffectKind, p: &Prepared, shape: &Shape) -> Vec<Vec<f64>> {
    if kind.fit_traits().amplitude_by_search {
        let t = Trajectory {
            input: &p.input,
            ..p.trajectory()
        };
        return fingerprint(kind, &t, shape);
    }
    candidate_columns(kind, p, shape)
}

/// Regressor columns of every parameter of a model, in [`Model::params`] order.
pub fn columns(model: &Model, p: &Prepared) -> Vec<Vec<f64>> {
    let sets = effect_columns(model, p, None);
    let zeros = vec![0.0; p.len()];
    per_param(model, p, &sets, &zeros).cloned().collect()
}

/// Every parameter's column in [`Model::params`] order, from each effect's `sets`: the
/// inertia's acceleration, then each effect's, `zeros` for a parameter without one.
fn per_param<'a>(
    model: &'a Model,
    p: &'a Prepared,
    sets: &'a [Arc<Vec<Vec<f64>>>],
    zeros: &'a Vec<f64>,
) -> impl Iterator<Item = &'a Vec<f64>> {
    std::iter::once(&p.acceleration).chain(
        model.effects.iter().zip(sets).flat_map(move |(e, set)| {
            (0..e.params.len()).map(move |j| set.get(j).unwrap_or(zeros))
        }),
    )
}

/// Each effect's columns, from `memo` when it holds them (on the worker pool: a shape search
/// builds them at every refit).
fn effect_columns(
    model: &Model,
    p: &Prepared,
    memo: Option<&ColumnMemo>,
) -> Vec<Arc<Vec<Vec<f64>>>> {
    use rayon::prelude::*;
    model
        .effects
        .par_iter()
        .map(|e| match memo {
            Some(m) => m.columns(e.kind, p, &e.shape),
            None => Arc::new(model_columns(e.kind, p, &e.shape)),
        })
        .collect()
}

/// Whether a parameter is fitted by linear least squares: free, and not a delay (a delay's
/// column holds the measured input, whose noise would bias a least-squares amplitude; τ is
/// fitted by a 1-D search on the delayed input instead).
fn ls_free(kind: Option<EffectKind>, free: bool) -> bool {
    free && !kind.is_some_and(|k| k.fit_traits().amplitude_by_search)
}

/// The record's initial-state columns of a model's effects with internal dynamics (see
/// `sim_plant::effects::initial_state`): nuisance regressors of this record, fitted with the
/// free amplitudes ([`design`]) and again on any record the model predicts ([`predict`]).
fn initial_state_columns(model: &Model, p: &Prepared) -> Vec<Vec<f64>> {
    let t = p.trajectory();
    model
        .effects
        .iter()
        .flat_map(|e| sim_plant::effects::initial_state(e.kind, &t, &e.shape))
        .collect()
}

/// The free-parameter regression: columns of free parameters and the input minus the
/// contribution of fixed ones.
#[derive(Debug, Clone)]
pub struct Design {
    /// Free columns, then the record's initial-state columns (`cols.len() − free.len()` of
    /// them; see `initial_state_columns`).
    pub cols: Vec<Vec<f64>>,
    /// Target.
    pub y: Vec<f64>,
    /// Index into [`Model::params`] of each free column.
    pub free: Vec<usize>,
    /// Rows that carry information (the record's samples minus those held at rest).
    pub live_rows: usize,
}

/// Build the free-parameter regression of a model. Samples where the joint is held by static
/// friction (see [`static_friction`]) carry no information on the amplitudes: their rows are
/// zeroed.
pub fn design(model: &Model, p: &Prepared) -> Design {
    design_with(model, p, None)
}

/// [`design`], the effects' columns from `memo` when it holds them. Each free column is
/// copied once and its stuck rows zeroed; a fixed one is only read.
fn design_with(model: &Model, p: &Prepared, memo: Option<&ColumnMemo>) -> Design {
    let sets = effect_columns(model, p, memo);
    let stuck = breakaway_limit(model, p).map(|_| stuck_rows(p));
    let zeros = vec![0.0; p.len()];
    let all = per_param(model, p, &sets, &zeros);
    let params = model.params();
    let owner = model.param_owners();
    let mut y = p.input.clone();
    let mut cols = Vec::new();
    let mut free = Vec::new();
    for (i, (c, par)) in all.zip(params).enumerate() {
        if ls_free(owner[i], par.free) {
            let mut c = c.clone();
            for &k in stuck.iter().flatten() {
                c[k] = 0.0;
            }
            cols.push(c);
            free.push(i);
        } else {
            for (yy, x) in y.iter_mut().zip(c) {
                *yy -= par.value * x;
            }
        }
    }
    let first_state = cols.len();
    cols.extend(initial_state_columns(model, p));
    let mut live_rows = y.len();
    for &k in stuck.iter().flatten() {
        y[k] = 0.0;
        for c in &mut cols[first_state..] {
            c[k] = 0.0;
        }
        live_rows -= 1;
    }
    Design {
        cols,
        y,
        free,
        live_rows,
    }
}

/// Whether an effect is part of the dry friction that holds a joint at rest (Coulomb, and the
/// Stribeck excess that raises the breakaway level).
fn dry_friction(kind: EffectKind) -> bool {
    kind.fit_traits().dry_friction
}

/// The stick state of a model with dry friction: a joint at rest is held by static friction,
/// which is a reaction — it takes whatever value balances the rest of the torque, up to the
/// breakaway level (Coulomb + Stribeck excess) — not `τc·sign(v)` of a velocity that is only
/// sensor noise there. Where the joint is at rest by the measurement (`at_rest`: the speed
/// within the noise of rest, or the encoder's count held) the prediction's dry friction is the
/// balancing torque clipped to the breakaway level, as in the simulator's stick state: exact
/// when it balances, the excess when the joint should have broken away.
#[derive(Debug, Clone)]
pub struct StaticFriction {
    /// The prediction without dry friction.
    rest: Vec<f64>,
    /// The dry friction's prediction while sliding.
    sliding: Vec<f64>,
    /// Breakaway level.
    limit: f64,
}

/// The samples a model with static friction holds at rest: all of them, not only those
/// whose balancing torque the current breakaway level holds. That choice would depend on the
/// amplitudes being fitted and reward a larger level with fewer rows to explain (a Coulomb
/// term would grow to cover a Stribeck excess at rest). Their indices, in order.
fn stuck_rows(p: &Prepared) -> Vec<usize> {
    (0..p.len()).filter(|&k| at_rest(p, k)).collect()
}

impl StaticFriction {
    /// The prediction with the stick state.
    fn predict(&self, p: &Prepared) -> Vec<f64> {
        (0..p.len())
            .map(|k| {
                let f = if at_rest(p, k) {
                    (p.input[k] - self.rest[k]).clamp(-self.limit, self.limit)
                } else {
                    self.sliding[k]
                };
                self.rest[k] + f
            })
            .collect()
    }
}

/// Whether the joint is at rest at sample `k`, as far as the measurement tells: its measured
/// speed is within the noise of rest, or its encoder held the count for as long as a joint at
/// that speed takes to move one (`Prepared::held`). The second matters at a breakaway or a
/// stop: the zero-phase differentiator spreads the motion over its support, both ways, and on
/// the samples before a breakaway it reads a speed — often backwards — the encoder never
/// saw, where the sliding law then predicts friction of the wrong sign.
fn at_rest(p: &Prepared, k: usize) -> bool {
    p.velocity[k].abs() < p.stick_velocity || p.held.get(k).copied().unwrap_or(false)
}

/// The breakaway level of `model`'s dry friction (Coulomb + Stribeck excess), when the
/// model has a stick state on `p`: a Coulomb term with a positive level, and a record whose
/// rest is measurable.
fn breakaway_limit(model: &Model, p: &Prepared) -> Option<f64> {
    if p.stick_velocity.is_nan() || p.stick_velocity <= 0.0 {
        return None;
    }
    let limit = model
        .effects
        .iter()
        .filter(|e| dry_friction(e.kind))
        .filter_map(|e| e.params.first())
        .map(|q| q.value.max(0.0))
        .sum::<f64>();
    if !model.has(EffectKind::Coulomb) || limit <= 0.0 {
        return None;
    }
    Some(limit)
}

/// [`StaticFriction`] of a model from its columns (`None` without Coulomb friction, or for
/// unquantised positions, where rest is not distinguishable from slow motion).
pub fn static_friction(model: &Model, p: &Prepared, cols: &[Vec<f64>]) -> Option<StaticFriction> {
    let limit = breakaway_limit(model, p)?;
    let owner = model.param_owners();
    let mut rest = vec![0.0; p.len()];
    let mut sliding = vec![0.0; p.len()];
    for ((c, par), o) in cols.iter().zip(model.params()).zip(owner) {
        let target = if o.is_some_and(dry_friction) {
            &mut sliding
        } else {
            &mut rest
        };
        for (t, x) in target.iter_mut().zip(c) {
            *t += par.value * x;
        }
    }
    Some(StaticFriction {
        rest,
        sliding,
        limit,
    })
}

/// Summed noise (co)variances of the design's free columns, `(j, k, v)` for
/// [`fit::least_squares_noise_cov`]: the encoder noise that reaches them through the
/// differentiator. The inertia column (the first) carries the motor encoder's acceleration
/// noise σ₁²; a backlash column built from a *measured* deflection, −(δ̈ + δ̇/τ) with
/// δ = x_motor − x_load, carries σ₁² + σ₂² (the load encoder's too) and shares −σ₁² with the
/// inertia column; without the shared term the load inertia is biased low (errors in
/// variables). The velocity parts (ẋ/τ, the viscous column) are left out:
/// relative to its signal a velocity's noise is ~ω_c² below an acceleration's.
fn column_noise(model: &Model, p: &Prepared, d: &Design) -> Vec<(usize, usize, f64)> {
    let rows = d.live_rows as f64;
    let owner = model.param_owners();
    let inertia = (d.free.first() == Some(&0)).then_some(0);
    let mut out = Vec::new();
    if inertia.is_some() {
        out.push((0, 0, rows * p.acceleration_noise_var));
    }
    if !p.load_position.is_empty() {
        for (k, &i) in d.free.iter().enumerate() {
            if owner[i] == Some(EffectKind::Backlash) {
                let (s1, s2) = (p.acceleration_noise_var, p.load_acceleration_noise_var);
                out.push((k, k, rows * (s1 + s2)));
                if let Some(j) = inertia {
                    out.push((j, k, -rows * s1));
                }
            }
        }
    }
    out
}

/// Whether an effect's columns are linear functions of the measured motion (so the position's
/// noise reaches them through a linear filter [`noise_gram`] can follow): viscous friction
/// (the velocity) and compliance in its motion form (a resonant filter of the acceleration;
/// the command form is built from the recorded input and has none of the position's noise).
/// Nonlinear columns (a sign, a periodic function of the position) carry little of it.
fn motion_linear(kind: EffectKind, shape: &Shape) -> bool {
    (kind.fit_traits().motion_linear)(shape)
}

/// Impulse responses of the free columns of `d` to a unit impulse of the raw position, from
/// [`Prepared::noise_probe`] (`None` for columns not linear in the motion, for the
/// initial-state columns, and for all of them without a probe).
pub fn noise_responses(model: &Model, p: &Prepared, d: &Design) -> Vec<Option<Vec<f64>>> {
    let mut out = vec![None; d.cols.len()];
    let Some(probe) = p.noise_probe.as_deref() else {
        return out;
    };
    // Also none for a NaN variance.
    if p.position_noise_var.is_nan() || p.position_noise_var <= 0.0 {
        return out;
    }
    let mut resp: Vec<Option<Vec<f64>>> = vec![Some(probe.acceleration.clone())];
    for e in &model.effects {
        if motion_linear(e.kind, &e.shape) {
            let mut c = model_columns(e.kind, probe, &e.shape);
            c.resize(e.params.len(), vec![0.0; probe.len()]);
            resp.extend(c.into_iter().map(Some));
        } else {
            resp.extend(std::iter::repeat_n(None, e.params.len()));
        }
    }
    for (o, &i) in out.iter_mut().zip(&d.free) {
        *o = resp.get(i).cloned().flatten();
    }
    out
}

/// Covariance of the position noise in the free columns of `d`: `live_rows·σ²·⟨hᵢ, hⱼ⟩`, hᵢ
/// from [`noise_responses`] (zero where it is `None`).
///
/// Why the whole matrix and not only the inertia's diagonal: a regressor that is a *resonant*
/// filter of the acceleration — compliance's motion form `J1·(s + β)²/(s² + 2ζ₂ω₂s + ω₂²)·a` —
/// carries the encoder's noise amplified about 1/(2ζ₂) around the locked-motor mode, and
/// correlated with the inertia column's. Least squares then prefers a damped, shifted mode
/// that does not amplify it: on the hidden-compliance trials the fitted mode beat the true
/// one on the estimation record (0.41 vs 0.86× the floor) and missed on validation (1.26×),
/// where the truth scores 0.90×. With the noise's covariance taken off the Gram matrix (and
/// the criterion, see `refine::ls_rss`) the fit measures the mode on the motion, not on how
/// much noise it passes.
pub fn noise_gram(p: &Prepared, d: &Design, resp: &[Option<Vec<f64>>]) -> nalgebra::DMatrix<f64> {
    let q = d.cols.len();
    let mut g = nalgebra::DMatrix::zeros(q, q);
    let scale = d.live_rows as f64 * p.position_noise_var;
    for a in 0..q.min(resp.len()) {
        for b in 0..=a {
            if let (Some(hi), Some(hj)) = (&resp[a], &resp[b]) {
                let v = scale * hi.iter().zip(hj).map(|(x, y)| x * y).sum::<f64>();
                g[(a, b)] = v;
                g[(b, a)] = v;
            }
        }
    }
    g
}

/// Standard deviation of the noise energy a fitted model passes (`LsFit::noise_rss` is its
/// mean): the position's white noise (variance σ², `rows` samples) through the combined
/// impulse response `h = Σ θᵢ·hᵢ` gives `Σ y²` with variance `2·rows·σ⁴·Σₖ Rₖ²`, R the
/// autocorrelation of h (`Σₖ Rₖ² = Σ|H|⁴/m` over an m-point DFT, m ≥ twice h's support).
/// A broadband h averages over many independent samples and its energy is sharp; a narrow
/// resonance (a compliance mode with ζ₂ → 0) passes a few degrees of freedom only, and its
/// energy on one record is far from the mean.
pub fn noise_energy_sd(h: &[f64], sigma2: f64, rows: usize) -> f64 {
    let total: f64 = h.iter().map(|v| v * v).sum();
    if total.is_nan() || sigma2.is_nan() || total <= 0.0 || sigma2 <= 0.0 {
        return 0.0;
    }
    // Support: drop the tail holding less than 1e-9 of the energy.
    let mut tail = 0.0;
    let mut len = h.len();
    while len > 1 && tail + h[len - 1] * h[len - 1] < 1e-9 * total {
        tail += h[len - 1] * h[len - 1];
        len -= 1;
    }
    let m = (2 * len).next_power_of_two();
    let mut re = vec![0.0; m];
    re[..len].copy_from_slice(&h[..len]);
    let mut im = vec![0.0; m];
    super::super::spectral::fft(&mut re, &mut im);
    let s4: f64 = re
        .iter()
        .zip(&im)
        .map(|(a, b)| {
            let p = a * a + b * b;
            p * p
        })
        .sum::<f64>()
        / m as f64;
    sigma2 * (2.0 * rows as f64 * s4).sqrt()
}

/// Fit all free amplitudes by linear least squares; writes values and 1σ into the model.
///
/// A parameter with `min`/`max` bounds (from its model file) is kept inside them: when the
/// unconstrained fit puts free parameters outside, the one furthest outside (relative to its
/// 1σ) is held at its bound and the rest refitted, until none is outside — an active set that
/// only grows, so at most one refit per bounded parameter. A parameter held at its bound stays
/// free in the model, with no 1σ (the fit did not estimate it; see [`Param::bound_reached`]).
///
/// [`Param::bound_reached`]: crate::model::Param::bound_reached
pub fn refit(model: &mut Model, p: &Prepared) -> Result<LsFit, fit::FitError> {
    refit_with(model, p, None)
}

/// [`refit`], the effects' columns from `memo` when it holds them (the shape searches': see
/// [`ColumnMemo`]). The same fit, bit for bit.
pub fn refit_with(
    model: &mut Model,
    p: &Prepared,
    memo: Option<&ColumnMemo>,
) -> Result<LsFit, fit::FitError> {
    let bounds: Vec<_> = model.params().iter().map(|q| (q.min, q.max)).collect();
    refit_bounded(model, p, memo, &bounds)
}

/// [`refit`] kept inside each parameter's [`Model::fit_bounds`]: the file's bounds and the
/// physical range. The shape searches refit without the physical range (a search passing
/// through a shape where, say, a Coulomb level trades below zero against an asymmetry would
/// otherwise steer by a clamped landscape: on the HIL identify record that cost 2 % of fit);
/// the model they settle on is then refitted in range.
pub fn refit_in_range(model: &mut Model, p: &Prepared) -> Result<LsFit, fit::FitError> {
    let bounds = model.fit_bounds();
    refit_bounded(model, p, None, &bounds)
}

/// Whether a free parameter of `model` lies outside its [`Model::fit_bounds`].
pub fn out_of_range(model: &Model) -> bool {
    model
        .params()
        .iter()
        .zip(model.fit_bounds())
        .any(|(q, (lo, hi))| {
            q.free && (lo.is_some_and(|lo| q.value < lo) || hi.is_some_and(|hi| q.value > hi))
        })
}

/// The active-set refit of [`refit`] with the bounds `bounds` (in [`Model::params`] order).
fn refit_bounded(
    model: &mut Model,
    p: &Prepared,
    memo: Option<&ColumnMemo>,
    bounds: &[(Option<f64>, Option<f64>)],
) -> Result<LsFit, fit::FitError> {
    let mut fit = refit_unbounded(model, p, memo)?;
    let mut held = Vec::new();
    loop {
        let params = model.params();
        let outside = params
            .iter()
            .zip(bounds)
            .enumerate()
            .filter(|(_, (q, _))| q.free)
            .filter_map(|(i, (q, &(lo, hi)))| {
                let bound = lo
                    .filter(|lo| q.value < *lo)
                    .or(hi.filter(|hi| q.value > *hi))?;
                let sigma = q.sigma.filter(|s| *s > 0.0).unwrap_or(1.0);
                Some((i, bound, (q.value - bound).abs() / sigma))
            })
            .max_by(|a, b| a.2.total_cmp(&b.2));
        let Some((i, bound, _)) = outside else { break };
        let mut params = model.params_mut();
        params[i].value = bound;
        params[i].free = false;
        held.push(i);
        let refit = refit_unbounded(model, p, memo);
        if refit.is_err() {
            // Leave the model as the caller gave it: free where it was free.
            let mut params = model.params_mut();
            for &j in &held {
                params[j].free = true;
            }
        }
        fit = refit?;
    }
    let mut params = model.params_mut();
    for &i in &held {
        params[i].free = true;
        params[i].sigma = None;
    }
    Ok(fit)
}

/// [`refit`] without the bounds.
fn refit_unbounded(
    model: &mut Model,
    p: &Prepared,
    memo: Option<&ColumnMemo>,
) -> Result<LsFit, fit::FitError> {
    let d = design_with(model, p, memo);
    // The compensation belongs to parameter estimation only: the diagnosis's projections
    // (`diagnose`, `refine::best_shape`) test what a column adds, for which plain least squares
    // is the right residual.
    //
    // Without a compliance term only the inertia's diagonal is compensated: the velocity's
    // share of the encoder noise is small against its signal (the differentiator's velocity
    // gain is ~ω_c below the acceleration's) and uncorrelated with the acceleration's (an odd
    // and an even zero-phase response), so the full matrix changes such fits by little — but
    // it does change them, and with them the hidden-effect referee's floor and ρ calibration,
    // which call this fit (the full matrix everywhere moved measured ρ by up to 10 % and lost
    // a Stribeck trial's rank 1 at 40/family). The full matrix is kept for where it is the
    // point: a compliance column, whose motion form is a resonant filter of the acceleration.
    //
    // Without compliance: the inertia's diagonal, and a measured-deflection backlash column's
    // encoder noise (see [`column_noise`]).
    if !model.has(EffectKind::Compliance) {
        let f = fit::least_squares_noise_cov(&d.cols, &d.y, &column_noise(model, p, &d))?;
        let mut params = model.params_mut();
        for (k, &i) in d.free.iter().enumerate() {
            params[i].value = f.theta[k];
            params[i].sigma = Some(f.sigma(k));
        }
        return Ok(f);
    }
    let resp = noise_responses(model, p, &d);
    let mut noise = noise_gram(p, &d, &resp);
    // A measured-deflection backlash column is not motion-linear in the motor position alone
    // (it holds the load encoder's noise too): its entries come from [`column_noise`]; the
    // inertia's own variance is already the probe's.
    for (j, k, v) in column_noise(model, p, &d) {
        if (j, k) != (0, 0) && j < noise.nrows() && k < noise.ncols() {
            noise[(j, k)] += v;
            if j != k {
                noise[(k, j)] += v;
            }
        }
    }
    let mut f = fit::least_squares_noise(&d.cols, &d.y, &noise)?;
    if resp.iter().any(Option::is_some) {
        let mut h = vec![0.0; p.noise_probe.as_ref().map_or(0, |q| q.len())];
        for (r, t) in resp.iter().zip(&f.theta) {
            if let Some(r) = r {
                for (a, b) in h.iter_mut().zip(r) {
                    *a += t * b;
                }
            }
        }
        f.noise_rss_sd = noise_energy_sd(&h, p.position_noise_var, d.live_rows);
    }
    let mut params = model.params_mut();
    for (k, &i) in d.free.iter().enumerate() {
        params[i].value = f.theta[k];
        params[i].sigma = Some(f.sigma(k));
    }
    Ok(f)
}

/// Equation-error prediction of the input. The effects' initial state on this record (see
/// `initial_state_columns`) is fitted to what the parameters leave, as a simulation's
/// initial state is estimated on the record it is compared with.
pub fn predict(model: &Model, p: &Prepared) -> Vec<f64> {
    let cols = columns(model, p);
    let mut u = if let Some(s) = static_friction(model, p, &cols) {
        s.predict(p)
    } else {
        let mut u = vec![0.0; p.len()];
        for (c, par) in cols.iter().zip(model.params()) {
            for (uu, x) in u.iter_mut().zip(c) {
                *uu += par.value * x;
            }
        }
        u
    };
    let x0 = initial_state_columns(model, p);
    if !x0.is_empty() {
        let left: Vec<f64> = p.input.iter().zip(&u).map(|(y, v)| y - v).collect();
        if let Ok(f) = fit::least_squares(&x0, &left) {
            for (uu, (l, r)) in u.iter_mut().zip(left.iter().zip(&f.residual)) {
                *uu += l - r;
            }
        }
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Recording;

    /// The spread of white noise's energy through an AR(1) response h = rᵏ: Σₖ Rₖ² =
    /// (1 + r²)/(1 − r²)³; and a unit impulse passes `rows` independent samples.
    #[test]
    fn noise_energy_sd_matches_closed_forms() {
        let sd = noise_energy_sd(&[1.0], 2.0, 100);
        assert!((sd - 2.0 * 200f64.sqrt()).abs() < 1e-9, "{sd}");
        let r: f64 = 0.95;
        let h: Vec<f64> = (0..2000).map(|k| r.powi(k)).collect();
        let want = (2.0 * 1000.0 * (1.0 + r * r) / (1.0 - r * r).powi(3)).sqrt();
        let sd = noise_energy_sd(&h, 1.0, 1000);
        assert!((sd / want - 1.0).abs() < 1e-6, "{sd} vs {want}");
        assert_eq!(noise_energy_sd(&[0.0; 8], 1.0, 100), 0.0);
    }

    /// Before a breakaway the zero-phase differentiator reads motion on samples at which the
    /// encoder never moved; the encoder's held count makes them rest, where the prediction's
    /// dry friction is the balancing torque (the input itself, below breakaway) rather than
    /// a sliding friction of whatever sign the smeared speed has.
    #[test]
    fn a_held_count_is_rest_before_a_breakaway() {
        let (n, dt, brk): (usize, f64, usize) = (2000, 1e-3, 1000);
        let count = std::f64::consts::TAU / 65536.0;
        let output: Vec<f64> = (0..n)
            .map(|k| match k.checked_sub(brk) {
                None | Some(0) => 0.0,
                Some(j) => (j as f64 * dt * 0.5 / count).floor() * count,
            })
            .collect();
        let rec = Recording {
            path: "synthetic".into(),
            time: (0..n).map(|k| k as f64 * dt).collect(),
            input: (0..n)
                .map(|k| {
                    if k < brk {
                        0.05 * k as f64 / brk as f64
                    } else {
                        0.12
                    }
                })
                .collect(),
            output,
            load_output: None,
            dt,
            units: ("N·m".into(), "rad".into()),
            columns: crate::data::Columns::new("u", "q"),
            resampled: None,
            recorded: None,
        };
        let p = Prepared::new(&rec, Some(40.0));
        let smeared: Vec<usize> = (0..p.len())
            .filter(|&k| p.held[k] && p.velocity[k].abs() >= p.stick_velocity)
            .collect();
        assert!(smeared.len() >= 3, "{smeared:?}");
        let mut m = Model::baseline();
        m.add(EffectKind::Coulomb, Shape::default());
        for (q, v) in m.params_mut().into_iter().zip([1e-3, 0.0, 0.1]) {
            q.value = v;
        }
        let u = predict(&m, &p);
        for k in smeared {
            assert!(
                (u[k] - p.input[k]).abs() < 1e-12,
                "{k}: {} vs {}",
                u[k],
                p.input[k]
            );
        }
        // The moving samples are not rest.
        assert!((0..p.len()).any(|k| !p.held[k] && !at_rest(&p, k)));
    }

    /// The noise matrix of the baseline model: the inertia's diagonal is the acceleration
    /// noise the differentiator's gain predicts, the velocity's is its own, and the two are
    /// uncorrelated (an even and an odd response).
    #[test]
    fn noise_gram_of_the_baseline() {
        let n = 4000;
        let sigma: f64 = 1e-4;
        let uniform = crate::stats::tests_support::unit_uniform;
        let rec = Recording {
            path: "synthetic".into(),
            time: (0..n).map(|k| k as f64 * 1e-3).collect(),
            input: (0..n).map(|k| (k as f64 * 3e-3).cos()).collect(),
            output: (0..n as u64)
                .map(|k| (k as f64 * 3e-3).sin() + (uniform(k) - 0.5) * 12f64.sqrt() * sigma)
                .collect(),
            load_output: None,
            dt: 1e-3,
            units: ("N·m".into(), "rad".into()),
            columns: crate::data::Columns::new("u", "q"),
            resampled: None,
            recorded: None,
        };
        let p = Prepared::new(&rec, Some(40.0));
        let m = Model::baseline();
        let d = design(&m, &p);
        let g = noise_gram(&p, &d, &noise_responses(&m, &p, &d));
        let scale = d.live_rows as f64 * p.position_noise_var;
        let ga = diff::acceleration_noise_gain(40.0, 1e-3).powi(2);
        let gv = diff::velocity_noise_gain(40.0, 1e-3).powi(2);
        assert!((g[(0, 0)] / scale / ga - 1.0).abs() < 1e-3, "{}", g[(0, 0)]);
        assert!((g[(1, 1)] / scale / gv - 1.0).abs() < 1e-3, "{}", g[(1, 1)]);
        assert!(g[(0, 1)].abs() < 1e-6 * g[(0, 0)], "{}", g[(0, 1)]);
    }
}
