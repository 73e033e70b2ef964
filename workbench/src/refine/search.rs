//! The shape searches of a refit: what least squares cannot place (a delay's τ on the
//! delayed input, Coulomb's sign lead, the ripple period, the compliance mode, the quantiser
//! step, the backlash width and the load's time constant, Stribeck's stick window), each a
//! line, grid or golden-section search on [`ls_rss`] (the choice between compliance's two
//! column forms on the plain RSS, see `search_compliance`).

use sim_plant::effects::{backlash, EffectKind, Shape, ShapeSearch, SmoothShape};

use super::super::diagnose;
use super::super::fit::{self, gram, gram_inverse};
use super::super::model::Model;
use super::super::residual::{self, ColumnMemo, Prepared};

/// A record as the shape searches refit on it: with the memo of effect columns that spares
/// the effects a search does not move their rebuilding at every one of its refits.
pub(super) struct On<'a> {
    pub(super) record: &'a Prepared,
    pub(super) memo: ColumnMemo,
}

impl<'a> On<'a> {
    pub(super) fn new(record: &'a Prepared) -> Self {
        On {
            record,
            memo: ColumnMemo::new(),
        }
    }

    /// [`residual::refit`] on the record, through the memo.
    pub(super) fn refit(&self, m: &mut Model) -> Result<fit::LsFit, fit::FitError> {
        residual::refit_with(m, self.record, Some(&self.memo))
    }
}

impl std::ops::Deref for On<'_> {
    type Target = Prepared;
    fn deref(&self) -> &Prepared {
        self.record
    }
}

/// Standard deviations of the passed noise's energy charged to a shape (see [`ls_rss`]): about
/// the most favourable deviation a search over a few hundred shapes finds by chance
/// (Φ⁻¹(1/500) ≈ −2.9).
const NOISE_SD_MARGIN: f64 = 3.0;

/// Criterion of the least-squares refit of `m` (∞ if it fails); `m` keeps the fitted
/// amplitudes. The RSS less the part that is the regressors' own (encoder) noise passed
/// through the fitted model (`LsFit::noise_rss`): the plain RSS rewards shapes that pass
/// less noise — a damped, shifted compliance mode that does not amplify the acceleration's
/// noise at its anti-resonance beat the true one (hidden-compliance trials: estimation RMS
/// 0.41 vs 0.86× the floor, validation 1.26 vs 0.90×) — rather than shapes that fit the
/// motion. That subtraction is the noise energy's *mean*; a narrow resonance passes few
/// degrees of freedom, so on one record its noise energy scatters widely, and a search over
/// modes picks the one whose noise happened to fall short (a trial's search went to ζ = 0.009
/// where the record's encoder noise density was 0.6× its mean: 3.8 passed against 6.8
/// subtracted, validation 4.3× the floor). So the subtraction's uncertainty is charged at
/// [`NOISE_SD_MARGIN`] standard deviations (`LsFit::noise_rss_sd`): negligible for broadband
/// columns, decisive against the narrowest modes.
///
/// Only for models with a compliance term: elsewhere the motion-linear columns are the
/// broadband acceleration and velocity, whose passed noise hardly moves with any shape, and
/// the plain RSS (at the compensated amplitudes) is kept.
///
/// A model with compliance whose split no model file can hold scores ∞
/// ([`Model::physical_split`]): a positive amplitude −J2/J1 — at such a shape the column is a
/// broadband correction no two-mass joint makes — or a backlash that disagrees with it on
/// J2. Such a model could not be saved, and `--auto` would not keep it.
fn ls_rss(m: &mut Model, p: &On) -> f64 {
    let noise_aware = m.has(EffectKind::Compliance);
    p.refit(m).map_or(f64::INFINITY, |f| {
        if noise_aware && m.physical_split().is_err() {
            f64::INFINITY
        } else if noise_aware {
            f.rss - f.noise_rss + NOISE_SD_MARGIN * f.noise_rss_sd
        } else {
            f.rss
        }
    })
}

/// Try each shape `set(shape, x)` for `x` in `xs` on effect `e`, keep the best by LS RSS.
/// Returns the best x and its RSS. The fits are independent: they run on the worker pool, and
/// the first best in `xs`'s order wins, as one after the other.
fn line_search(
    model: &mut Model,
    p: &On,
    e: usize,
    xs: &[f64],
    set: &(dyn Fn(&mut Model, usize, f64) + Sync),
) -> (f64, f64) {
    line_search_by(model, p, e, xs, set, &ls_rss)
}

/// What a search minimises over a refitted model.
type Cost = dyn Fn(&mut Model, &On) -> f64 + Sync;

/// [`line_search`] by `cost` instead of the LS RSS.
fn line_search_by(
    model: &mut Model,
    p: &On,
    e: usize,
    xs: &[f64],
    set: &(dyn Fn(&mut Model, usize, f64) + Sync),
    cost: &Cost,
) -> (f64, f64) {
    use rayon::prelude::*;
    let fits: Vec<(f64, Model)> = xs
        .par_iter()
        .map(|&x| {
            let mut m = model.clone();
            set(&mut m, e, x);
            (cost(&mut m, p), m)
        })
        .collect();
    let mut best = (f64::NAN, f64::INFINITY);
    let mut best_model = None;
    for (&x, (r, m)) in xs.iter().zip(fits) {
        if r < best.1 {
            best = (x, r);
            best_model = Some(m);
        }
    }
    if let Some(m) = best_model {
        *model = m;
    }
    best
}

/// Joint grid search of two shape values of effect `e`: for each `outer` value (set by
/// `set_outer`) a [`line_search`] over `inner`; `model` becomes the best pair's fit, its RSS
/// is returned (unchanged model and ∞ for an empty grid). Used where two shape values trade
/// off against each other (Coulomb smoothing × sign lead, mode damping × frequency).
fn grid_search(
    model: &mut Model,
    p: &On,
    e: usize,
    outer: &[f64],
    set_outer: &(dyn Fn(&mut Model, usize, f64) + Sync),
    inner: &[f64],
    set_inner: &(dyn Fn(&mut Model, usize, f64) + Sync),
) -> f64 {
    let mut best: Option<(f64, Model)> = None;
    for &x in outer {
        let mut m = model.clone();
        set_outer(&mut m, e, x);
        let (_, r) = line_search(&mut m, p, e, inner, set_inner);
        if best.as_ref().is_none_or(|b| r < b.0) {
            best = Some((r, m));
        }
    }
    match best {
        Some((r, m)) => {
            *model = m;
            r
        }
        None => f64::INFINITY,
    }
}

/// Golden-section minimum of the LS RSS over `x` ∈ [lo, hi] (unimodal near a grid minimum);
/// keeps `keep` (the grid point) if that is still better.
fn golden(
    model: &mut Model,
    p: &On,
    e: usize,
    bracket: (f64, f64),
    keep: f64,
    iters: usize,
    set: &(dyn Fn(&mut Model, usize, f64) + Sync),
) -> (f64, f64) {
    golden_by(model, p, e, bracket, keep, iters, set, &ls_rss)
}

/// [`golden`] by `cost` instead of the LS RSS.
#[allow(clippy::too_many_arguments)]
fn golden_by(
    model: &mut Model,
    p: &On,
    e: usize,
    (mut lo, mut hi): (f64, f64),
    keep: f64,
    iters: usize,
    set: &(dyn Fn(&mut Model, usize, f64) + Sync),
    cost: &Cost,
) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let eval = |x: f64| {
        let mut m = model.clone();
        set(&mut m, e, x);
        cost(&mut m, p)
    };
    let (mut a, mut b) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fa, mut fb) = (eval(a), eval(b));
    for _ in 0..iters {
        if fa < fb {
            hi = b;
            (b, fb) = (a, fa);
            a = hi - g * (hi - lo);
            fa = eval(a);
        } else {
            lo = a;
            (a, fa) = (b, fb);
            b = lo + g * (hi - lo);
            fb = eval(b);
        }
    }
    let x = if fa < fb { a } else { b };
    // Never worse than the grid point the bracket was built around.
    line_search_by(model, p, e, &[x, keep], set, cost)
}

/// The shapes `screen` (a periodogram of a residual, see `sim_plant::effects::screen`)
/// picks out of the residual of `model` without effect `e`.
fn screened(
    model: &Model,
    p: &On,
    e: usize,
    screen: impl Fn(&sim_plant::effects::Trajectory, &[f64]) -> (Vec<Shape>, usize),
) -> Vec<Shape> {
    let mut m = model.clone();
    m.effects.remove(e);
    let Ok(fit) = p.refit(&mut m) else {
        return Vec::new();
    };
    screen(&p.trajectory(), &fit.residual).0
}

/// The periods the effect's own screen (the position periodogram of a residual, in steps the
/// travel resolves) picks out of the residual of `model` without effect `e`.
fn screened_periods(model: &Model, p: &On, e: usize, acc: SmoothShape) -> Vec<f64> {
    let kind = model.effects[e].kind;
    screened(model, p, e, |t, r| sim_plant::effects::screen(kind, t, r))
        .iter()
        .map(|s| (acc.get)(s))
        .collect()
}

fn set_delay(m: &mut Model, e: usize, tau: f64) {
    let tau = tau.max(0.0);
    m.effects[e].shape.delay = tau;
    if let Some(q) = m.effects[e].params.first_mut() {
        q.value = tau;
    }
}

/// Shape searches the least-squares refit cannot do, before Levenberg–Marquardt:
///
/// * **Delay**: τ by a 1-D search on the residual re-formed with the measured input actually
///   delayed by τ (grid over 0–30 samples, then golden section; fractional delays by linear
///   interpolation), the rest by least squares at each τ. Not the linear column
///   (u − u(t − τs))/τs with a free amplitude: that column carries the input's own noise.
/// * **Coulomb**: the sign's time lead (`Shape::sign_lead`) and smoothing ε, by coordinate
///   search: dynamic friction reverses over a pre-sliding displacement, not exactly at v = 0.
/// * **Ripple**: the period on a fine grid (±1 step of the coarse grid, 1/10 step) and around
///   the peaks of the effect's screen (a position periodogram of the residual), because
///   the RSS oscillates in the period and LM only finds the nearest minimum.
///
/// * **Compliance**: the mode (f, ζ) by a joint grid and golden sections, in the command form
///   and in the motion form of the column (see `search_compliance`).
/// * **Quantization**: the step Δ by a dense scan, and the blur σ of the sawtooth (see
///   `search_quantum`).
/// * **Backlash**: the gap width and the load's time constant by a joint grid and golden
///   sections (see `search_backlash`).
/// * **Stribeck**: the refit's form of its column — stick hold, bristle transient — with the
///   stick window, the dry-friction sign shape shared with Coulomb, and vs × δ (see
///   `search_stick`).
///
/// An asymmetry next to a Coulomb term then takes Coulomb's sign shape.
pub(super) fn search_shapes(model: &mut Model, p: &On, start: StickStart, only: Only) {
    search_each(model, p, start, only);
    // Direction-dependent friction switches with the Coulomb friction: an asymmetry next to a
    // Coulomb term takes its sign shape (an independent one would buy reversal-shape freedom
    // with the second sign column and stand in for an offset).
    let sign = model
        .effects
        .iter()
        .find(|e| e.kind.fit_traits().search == ShapeSearch::Sign)
        .map(|e| e.shape.clone());
    if let Some(sign) = sign {
        for e in model.effects.iter_mut().filter(|e| {
            let f = e.kind.fit_traits();
            f.sign_shaped && f.search == ShapeSearch::None
        }) {
            e.shape.set_sign_zone(&sign);
            e.shape.sign_lead = sign.sign_lead;
        }
    }
}

/// Which effects' shapes a refit searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Only {
    /// Every effect's.
    All,
    /// The effects from this index on (those just added): the others keep the shapes an
    /// earlier refit searched.
    From(usize),
}

fn search_each(model: &mut Model, p: &On, start: StickStart, only: Only) {
    let dt = p.dt;
    let first = match only {
        Only::All => 0,
        Only::From(i) => i,
    };
    for e in first..model.effects.len() {
        let entry = &model.effects[e];
        if !entry.params.iter().any(|q| q.free) {
            continue;
        }
        match entry.kind.fit_traits().search {
            ShapeSearch::Delay => {
                let grid: Vec<f64> = (0..=30).map(|k| k as f64 * dt).collect();
                let (t0, _) = line_search(model, p, e, &grid, &set_delay);
                let (t1, r1) = golden(
                    model,
                    p,
                    e,
                    ((t0 - dt).max(0.0), t0 + dt),
                    t0,
                    14,
                    &set_delay,
                );
                // 1σ from the curvature of RSS(τ): var = 2·s²/RSS''.
                let h = 0.25 * dt;
                let at = |tau: f64| {
                    let mut m = model.clone();
                    set_delay(&mut m, e, tau);
                    ls_rss(&mut m, p)
                };
                let curv = (at(t1 + h) - 2.0 * r1 + at((t1 - h).max(0.0))) / (h * h);
                let s2 = r1 / (p.len() as f64 - model.params().len() as f64).max(1.0);
                if let Some(q) = model.effects[e].params.first_mut() {
                    q.sigma = Some(if curv > 0.0 {
                        (2.0 * s2 / curv).sqrt()
                    } else {
                        f64::NAN
                    });
                }
            }
            ShapeSearch::Sign => {
                let set_lead = |m: &mut Model, e: usize, x: f64| m.effects[e].shape.sign_lead = x;
                let set_zone =
                    |m: &mut Model, e: usize, s: &Shape| m.effects[e].shape.set_sign_zone(s);
                search_sign(model, p, e, &set_zone, &set_lead, true);
            }
            ShapeSearch::Period => {
                // The period is the effect's smooth shape (the registry test holds it to that).
                let Some(acc) = entry.kind.fit_traits().smooth_shape else {
                    continue;
                };
                let grid = sim_plant::effects::shape_grid(entry.kind, &p.trajectory());
                let step = if grid.len() > 1 {
                    (acc.get)(&grid[1]) / (acc.get)(&grid[0])
                } else {
                    1.0
                };
                let p0 = (acc.get)(&entry.shape);
                let mut xs: Vec<f64> = (-10..=10)
                    .map(|k| p0 * step.powf(k as f64 / 10.0))
                    .collect();
                // A ripple of many periods over the travel explains almost nothing one coarse
                // step (×1.25) off its period, so the coarse best can be anywhere: add the
                // peaks of the effect's screen of the residual without the ripple.
                for peak in screened_periods(model, p, e, acc) {
                    xs.extend((-4..=4).map(|k| peak * 1.0025f64.powi(k)));
                }
                let set_period =
                    |m: &mut Model, e: usize, x: f64| (acc.set)(&mut m.effects[e].shape, x);
                line_search(model, p, e, &xs, &set_period);
            }
            ShapeSearch::Mode => search_compliance(model, p, e),
            ShapeSearch::Quantum => search_quantum(model, p, e),
            ShapeSearch::Gap => search_backlash(model, p, e),
            ShapeSearch::Stick => search_stick(model, p, e, start),
            ShapeSearch::None => {}
        }
    }
}

fn set_mode_frequency(m: &mut Model, e: usize, f: f64) {
    m.effects[e].shape.compliance_frequency = f;
}

fn set_mode_damping(m: &mut Model, e: usize, z: f64) {
    m.effects[e].shape.compliance_damping = z;
}

/// Compliance: the coupled mode (frequency, damping ratio). The diagnosis places it on a
/// coarse grid (frequency steps of 25 %, two damping ratios); the column's fit is sharp in
/// both. A joint grid of frequencies (the diagnosis's own grid plus ±30 % around the current
/// mode in 5 % steps, up to 0.45× the sample rate) × damping ratios 0.02–0.8, then alternating
/// golden sections on ln f and ln ζ.
fn search_compliance(model: &mut Model, p: &On, e: usize) {
    let fs = 1.0 / p.dt;
    let f_max = 0.45 * fs;
    let f0 = model.effects[e].shape.compliance_frequency;
    let mut freqs: Vec<f64> =
        sim_plant::effects::shape_grid(EffectKind::Compliance, &p.trajectory())
            .iter()
            .map(|s| s.compliance_frequency)
            .collect();
    freqs.dedup();
    freqs.extend((-6..=6).map(|k| f0 * 1.05f64.powi(k)));
    // Above the record's band only J2/(J1·ω²) is identified; a few modes up there let the
    // refit take that limit instead of a resonance inside the band.
    if let Some(&top) = freqs.iter().max_by(|a, b| a.total_cmp(b)) {
        freqs.extend((1..=3).map(|k| top * 1.6f64.powi(k)));
    }
    freqs.retain(|&f| f > 0.0 && f < f_max);
    let zetas = [0.02, 0.035, 0.06, 0.1, 0.16, 0.25, 0.4, 0.6, 0.8];
    grid_search(
        model,
        p,
        e,
        &zetas,
        &set_mode_damping,
        &freqs,
        &set_mode_frequency,
    );
    // Coordinate golden sections in the logarithms.
    let set_lf = |m: &mut Model, e: usize, x: f64| set_mode_frequency(m, e, x.exp().min(f_max));
    let set_lz = |m: &mut Model, e: usize, x: f64| set_mode_damping(m, e, x.exp());
    let polish = |model: &mut Model| {
        let lf = model.effects[e].shape.compliance_frequency.ln();
        golden(model, p, e, (lf - 0.1, lf + 0.1), lf, 12, &set_lf);
        let lz = model.effects[e].shape.compliance_damping.ln();
        golden(model, p, e, (lz - 0.4, lz + 0.4), lz, 12, &set_lz);
    };
    for _ in 0..2 {
        polish(model);
    }
    // Then the motion form of the column (`J1·H₂·a`, no command noise in it), searched in its
    // own coordinates: with unit J1 and no ratio the column is `H₂·a` at the locked-motor mode
    // (f₂, ζ₂) and its amplitude is −J2, linear. The same joint grid and golden sections, then
    // the split J1 = J − J2 maps it back to the coupled mode (f = f₂·√(1 + J2/J1)) and the
    // amplitude −J2/J1; the load's viscous friction then enters as (J2·s + b)². Kept only if
    // its plain RSS, noise included, is the lower: the two forms pass different noise (the
    // command form the encoder's through the whole inertia and the command's own amplified
    // J/J1-fold above the mode, the motion form the encoder's through J1 + J2·G), and that
    // difference, which `ls_rss` takes out to compare shapes of one form, decides which
    // predicts a new record better.
    let command_form = model.clone();
    let plain = |m: &Model| {
        let mut c = m.clone();
        match p.refit(&mut c) {
            Ok(f) if c.physical_split().is_ok() => f.rss,
            _ => f64::INFINITY,
        }
    };
    let r0 = plain(model);
    let mut m = model.clone();
    sim_plant::effects::compliance::set_unit_motion_form(&mut m.effects[e].shape);
    let mut freqs2: Vec<f64> = freqs.iter().map(|f| f / 2.0).collect();
    freqs2.extend(&freqs);
    freqs2.retain(|&f| f > 0.5);
    grid_search(
        &mut m,
        p,
        e,
        &zetas,
        &set_mode_damping,
        &freqs2,
        &set_mode_frequency,
    );
    for _ in 0..2 {
        polish(&mut m);
    }
    ls_rss(&mut m, p);
    let j2 = -m.effects[e].params[0].value;
    let j1 = m.inertia.value - j2;
    if j2 > 0.0 && j1 > 0.0 && j2.is_finite() {
        let ratio = j2 / j1;
        let b = m
            .effects
            .iter()
            .find(|x| x.kind == EffectKind::Viscous)
            .and_then(|x| x.params.first())
            .map_or(0.0, |q| q.value);
        let sh = &mut m.effects[e].shape;
        let s = (1.0 + ratio).sqrt();
        sh.compliance_frequency *= s;
        sh.compliance_damping *= s;
        sh.compliance_near_inertia = j1;
        sh.compliance_ratio = ratio;
        sh.compliance_load_damping = b.max(0.0);
        ls_rss(&mut m, p);
        polish(&mut m);
        // The column holds the load's own drag, (J2·s + b₂)², and none of the motor's; the
        // rigid fit gives only their sum b. Where the drag sits is a property of the joint
        // (a bearing at the motor, a seal or a fluid at the load), so its share is searched.
        // The share and the mode's damping trade against each other along a narrow valley
        // (b₂ adds to the damping too): coordinate sections until the share settles.
        if b > 0.0 {
            let set_share = |m: &mut Model, e: usize, x: f64| {
                m.effects[e].shape.compliance_load_damping = b * x.clamp(0.0, 1.0);
            };
            let share = |m: &Model| m.effects[e].shape.compliance_load_damping / b;
            line_search(&mut m, p, e, &SHARES, &set_share);
            for _ in 0..SHARE_PASSES {
                let x = share(&m);
                golden(
                    &mut m,
                    p,
                    e,
                    ((x - 0.2).max(0.0), (x + 0.2).min(1.0)),
                    x,
                    10,
                    &set_share,
                );
                polish(&mut m);
                if (share(&m) - x).abs() < 0.02 {
                    break;
                }
            }
        }
        if plain(&m) < r0 {
            *model = m;
            return;
        }
    }
    *model = command_form;
}

/// The load's share of the viscous drag a compliance refit starts its search from.
const SHARES: [f64; 6] = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0];

/// Most coordinate passes of the load's drag share against the mode's shape.
const SHARE_PASSES: usize = 5;

fn set_backlash_width(m: &mut Model, e: usize, b: f64) {
    m.effects[e].shape.backlash_width = b;
}

fn set_load_time(m: &mut Model, e: usize, tau: f64) {
    m.effects[e].shape.backlash_load_time = tau;
}

/// Backlash: the gap width b and the load's viscous time constant τ. The fit is sharp and
/// multimodal in the width (it sets when each crossing of the gap ends, and a width off by a
/// step can lock onto a different set of crossings), smooth but not flat in τ. A joint grid of
/// τ (0.03–10 s in steps of ×1.6, and no decay) × widths over the diagnosis's whole width
/// range in steps of 10 % (the minimum in b is about ±15 % wide and moves with τ), then
/// widths ±15 % around the best in steps of 1.5 %, then alternating golden sections on ln τ
/// and ln b.
///
/// With a load position (see `backlash::measured_column`) the column does not depend on the
/// width: the width is the measured one (`backlash::measured_width`) and only τ is searched
/// (the same τ grid, then a golden section on ln τ).
fn search_backlash(model: &mut Model, p: &On, e: usize) {
    let taus = [
        0.03, 0.05, 0.08, 0.13, 0.2, 0.32, 0.5, 0.8, 1.3, 2.0, 3.2, 5.0, 10.0, 0.0,
    ];
    let set_lb = |m: &mut Model, e: usize, x: f64| set_backlash_width(m, e, x.exp());
    let set_lt = |m: &mut Model, e: usize, x: f64| set_load_time(m, e, x.exp());
    if let Some(b) = backlash::measured_width(&p.trajectory()) {
        set_backlash_width(model, e, b);
        line_search(model, p, e, &taus, &set_load_time);
        let tau = model.effects[e].shape.backlash_load_time;
        if tau > 0.0 {
            let lt = tau.ln();
            golden(model, p, e, (lt - 0.6, lt + 0.6), lt, 12, &set_lt);
        }
        return;
    }
    let grid = sim_plant::effects::shape_grid(EffectKind::Backlash, &p.trajectory());
    let (lo, hi) = grid.iter().fold((f64::INFINITY, 0.0f64), |(l, h), s| {
        (l.min(s.backlash_width), h.max(s.backlash_width))
    });
    if !(lo > 0.0 && hi > lo) {
        return;
    }
    let steps = ((hi / lo).ln() / 1.1f64.ln()).ceil() as i32;
    let widths: Vec<f64> = (0..=steps).map(|k| lo * 1.1f64.powi(k)).collect();
    grid_search(
        model,
        p,
        e,
        &taus,
        &set_load_time,
        &widths,
        &set_backlash_width,
    );
    let b0 = model.effects[e].shape.backlash_width;
    let fine: Vec<f64> = (-10..=10).map(|k| b0 * 1.015f64.powi(k)).collect();
    line_search(model, p, e, &fine, &set_backlash_width);
    for _ in 0..2 {
        let tau = model.effects[e].shape.backlash_load_time;
        if tau > 0.0 {
            let lt = tau.ln();
            golden(model, p, e, (lt - 0.6, lt + 0.6), lt, 10, &set_lt);
        }
        let lb = model.effects[e].shape.backlash_width.ln();
        golden(model, p, e, (lb - 0.015, lb + 0.015), lb, 8, &set_lb);
    }
}

/// Sets the stick window of the stribeck effect `e` and of the dry-friction terms it gates.
fn set_stick(m: &mut Model, e: usize, vh: f64) {
    let vh = vh.max(0.0);
    m.effects[e].shape.stick_velocity = vh;
    for x in m.effects.iter_mut() {
        if x.kind.fit_traits().sign_shaped {
            x.shape.stick_velocity = vh;
        }
    }
}

/// Stribeck: the refit's form of the column (see `sim_plant::effects::stribeck::fingerprint`:
/// slip, bristle transient, stick hold), its shapes searched in turn:
///
/// * the hold's amplitude is held at 1 — at rest the friction *is* the applied torque; a free
///   amplitude is not identified on a record that never sticks, and on one that does it only
///   trades with the motion terms;
/// * the sign shape (ε, lead) jointly with Coulomb's ([`search_dry_sign`]): the excess flips
///   with the Coulomb level at each reversal, and being the larger part near v = 0 it decides
///   where the flip is;
/// * the stick window vh on a log grid of 1e-4…1e-2 of the top speed, then golden section
///   (the motion terms are not gated, so a window wider than the rest's velocity noise costs
///   at every fast reversal and the RSS has an interior minimum);
/// * vs × δ on the diagnosis's grid again, each δ at its own best vs: the transition seen
///   by the slip column changes once the stick phases are no longer its to explain. LM then
///   refines vs.
fn search_stick(model: &mut Model, p: &On, e: usize, start: StickStart) {
    let vmax = p.velocity.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if vmax.is_nan() || vmax <= 0.0 {
        return;
    }
    if let Some(h) = model.effects[e]
        .params
        .iter_mut()
        .find(|q| q.name == "hold")
    {
        h.value = 1.0;
        h.free = false;
    }
    search_dry_sign(model, p, e, start.search_lead);
    let xs = sim_plant::effects::signal::log_space(1e-4 * vmax, 1e-2 * vmax, 9);
    let (v0, _) = line_search(model, p, e, &xs, &set_stick);
    if v0 > 0.0 {
        let set_l = |m: &mut Model, e: usize, x: f64| set_stick(m, e, x.exp());
        let l = v0.ln();
        golden(model, p, e, (l - 0.6, l + 0.6), l, 10, &set_l);
    }
    let grid = sim_plant::effects::shape_grid(EffectKind::Stribeck, &p.trajectory());
    let set_vs = |m: &mut Model, e: usize, x: f64| m.effects[e].shape.stribeck_velocity = x;
    let set_d = |m: &mut Model, e: usize, x: f64| m.effects[e].shape.stribeck_exponent = x;
    let vss = distinct(grid.iter().map(|s| s.stribeck_velocity));
    let ds = match start.exponent {
        Some(d) => vec![d],
        None => distinct(grid.iter().map(|s| s.stribeck_exponent)),
    };
    // Each δ at its own best vs (the grid, then golden section across a grid step either
    // way) before the δ are compared: at the grid's points, a grid step apart, the δ whose grid
    // passes nearer its own vs wins, and the LM that follows only polishes the δ so picked.
    let step = vss
        .windows(2)
        .map(|w| (w[1] / w[0]).ln())
        .fold(0.0f64, f64::max);
    let set_lvs = |m: &mut Model, e: usize, x: f64| m.effects[e].shape.stribeck_velocity = x.exp();
    let mut best: Option<(f64, Model)> = None;
    for &d in &ds {
        let mut m = model.clone();
        set_d(&mut m, e, d);
        let (v0, mut r) = line_search(&mut m, p, e, &vss, &set_vs);
        if v0 > 0.0 && step > 0.0 {
            let l = v0.ln();
            r = golden(&mut m, p, e, (l - step, l + step), l, 8, &set_lvs).1;
        }
        if best.as_ref().is_none_or(|b| r < b.0) {
            best = Some((r, m));
        }
    }
    if let Some((_, m)) = best {
        *model = m;
    }
}

/// Sets the sign shape of effect `e` and of every Coulomb / asymmetry term: dry friction
/// reverses as one.
fn set_dry(m: &mut Model, e: usize, f: impl Fn(&mut Shape)) {
    f(&mut m.effects[e].shape);
    for x in m.effects.iter_mut() {
        if x.kind.fit_traits().sign_shaped {
            f(&mut x.shape);
        }
    }
}

/// The sign lead and smoothing ε of a stribeck term together with the Coulomb terms' (see
/// [`search_sign`]).
fn search_dry_sign(model: &mut Model, p: &On, e: usize, search_lead: bool) {
    let set_lead = |m: &mut Model, e: usize, x: f64| set_dry(m, e, |s| s.sign_lead = x);
    let set_zone = |m: &mut Model, e: usize, z: &Shape| set_dry(m, e, |s| s.set_sign_zone(z));
    search_sign(model, p, e, &set_zone, &set_lead, search_lead);
}

/// The distinct values of a grid's shape coordinate, ascending.
fn distinct(xs: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = xs.collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

/// Where the Stribeck refit's searches start (see [`super::refit_all`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StickStart {
    /// Search the dry-friction sign lead jointly with the smoothing ε; otherwise hold it at 0
    /// (the reversal where the zero-phase velocity crosses zero) and search ε alone.
    search_lead: bool,
    /// Hold the Stribeck exponent δ at this value; `None` searches vs × δ on the grid.
    exponent: Option<f64>,
}

impl StickStart {
    /// Everything searched: the only start of a model without a free Stribeck term.
    pub(super) const SEARCHED: StickStart = StickStart {
        search_lead: true,
        exponent: None,
    };

    /// The starts of a Stribeck refit: everything searched; the lead held at 0; and the lead
    /// held at 0 with δ held at each exponent of the Stribeck shape grid (1 and 2).
    pub(super) fn all(p: &Prepared) -> Vec<StickStart> {
        let grid = sim_plant::effects::shape_grid(EffectKind::Stribeck, &p.trajectory());
        let ds = distinct(grid.iter().map(|s| s.stribeck_exponent));
        let mut out = vec![
            StickStart::SEARCHED,
            StickStart {
                search_lead: false,
                exponent: None,
            },
        ];
        out.extend(ds.into_iter().map(|d| StickStart {
            search_lead: false,
            exponent: Some(d),
        }));
        out
    }
}

/// A dry-friction sign shape: the zones in velocity of Coulomb's grid × sign lead (−6…8
/// samples) on a joint grid — the two trade off against each other — then every zone of the
/// grid (in velocity or in time) at that lead, then the lead by golden section.
fn search_sign(
    model: &mut Model,
    p: &On,
    e: usize,
    set_zone: &(dyn Fn(&mut Model, usize, &Shape) + Sync),
    set_lead: &(dyn Fn(&mut Model, usize, f64) + Sync),
    search_lead: bool,
) {
    let dt = p.dt;
    let grid = sim_plant::effects::shape_grid(EffectKind::Coulomb, &p.trajectory());
    // The grid's index as the searched coordinate: each point sets both ε and T.
    let points: Vec<f64> = (0..grid.len()).map(|i| i as f64).collect();
    let set_smoothing = |m: &mut Model, e: usize, x: f64| {
        if let Some(s) = grid.get(x as usize) {
            set_zone(m, e, s);
        }
    };
    if !search_lead {
        set_lead(model, e, 0.0);
        line_search(model, p, e, &points, &set_smoothing);
        return;
    }
    let leads: Vec<f64> = [
        -6.0, -4.0, -3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0,
    ]
    .iter()
    .map(|k| k * dt)
    .collect();
    // The lead with the zones in velocity, where it trades off against ε; then every zone
    // at that lead (a time zone is centred on the reversal, so the lead that places it
    // carries over), and the lead refined for the zone chosen.
    let velocity: Vec<f64> = points
        .iter()
        .copied()
        .filter(|&x| grid.get(x as usize).is_some_and(|s| s.sign_time == 0.0))
        .collect();
    grid_search(model, p, e, &velocity, &set_smoothing, &leads, set_lead);
    line_search(model, p, e, &points, &set_smoothing);
    let l = model.effects[e].shape.sign_lead;
    golden(model, p, e, (l - 0.5 * dt, l + 0.5 * dt), l, 8, set_lead);
}

fn set_quantum(m: &mut Model, e: usize, d: f64) {
    m.effects[e].shape.quantum = d;
    if let Some(q) = m.effects[e].params.iter_mut().find(|q| q.name == "step") {
        q.value = d;
    }
}

/// Quantization: the step Δ. The fit of the sawtooth `u − Q_Δ(u)` is very multimodal in Δ: at
/// a relative error ε the sawtooth slips by ε·K steps where the command spans K = max|u|/Δ
/// steps, so it decorrelates once ε·K ≈ ½. A dense scan ±5 % around the diagnosis's step, and
/// around each step the effect's screen (`quantization::screen`) picks out of the residual
/// without it, at a relative spacing of 0.15/K (0.01 %–0.5 %); then golden section between
/// the neighbours of the best.
fn search_quantum(model: &mut Model, p: &On, e: usize) {
    let d0 = model.effects[e].shape.quantum;
    if d0 <= 0.0 {
        return;
    }
    let traj = p.trajectory();
    let (u, w) = traj.recorded_input();
    let range = u[w].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let spacing = |d: f64| (0.15 / (range / d).max(1.0)).clamp(1e-4, 5e-3);
    // Around the diagnosis's step, and around each step the effect's screen picks out of the
    // residual without it (the grid's 6 % can pass over a peak that is a few per cent wide).
    let mut centres = vec![d0];
    let screen = |t: &sim_plant::effects::Trajectory, r: &[f64]| {
        sim_plant::effects::screen(EffectKind::Quantization, t, r)
    };
    for s in screened(model, p, e, screen) {
        if centres.iter().all(|c| (s.quantum / c).ln().abs() > 0.05) {
            centres.push(s.quantum);
        }
    }
    let mut xs = Vec::new();
    for &c in &centres {
        let step = spacing(c);
        let half = (0.05f64.ln_1p() / step.ln_1p()).ceil() as i32;
        xs.extend((-half..=half).map(|i| c * (1.0 + step).powi(i)));
    }
    let (d1, _) = line_search(model, p, e, &xs, &set_quantum);
    let step = spacing(d1);
    golden(
        model,
        p,
        e,
        (d1 / (1.0 + step), d1 * (1.0 + step)),
        d1,
        10,
        &set_quantum,
    );
    blur_then_step(model, p, e, step, &ls_rss);
    search_coarse_quantum(model, p, e, range);
}

/// The recorded command's noise blurs the sawtooth's jumps: σ/Δ on a grid, then golden
/// section, then Δ once more at that blur (within ±2 `step`, relative). Returns the cost.
fn blur_then_step(model: &mut Model, p: &On, e: usize, step: f64, cost: &Cost) -> f64 {
    let d = model.effects[e].shape.quantum;
    let set_blur = |m: &mut Model, e: usize, x: f64| m.effects[e].shape.quantum_blur = x.max(0.0);
    let blurs: Vec<f64> = [0.0, 0.02, 0.04, 0.06, 0.09, 0.13, 0.18, 0.25, 0.35]
        .iter()
        .map(|r| r * d)
        .collect();
    let (b0, _) = line_search_by(model, p, e, &blurs, &set_blur, cost);
    let h = 0.03 * d;
    golden_by(
        model,
        p,
        e,
        ((b0 - h).max(0.0), b0 + h),
        b0,
        10,
        &set_blur,
        cost,
    );
    let d = model.effects[e].shape.quantum;
    golden_by(
        model,
        p,
        e,
        (d / (1.0 + 2.0 * step), d * (1.0 + 2.0 * step)),
        d,
        10,
        &set_quantum,
        cost,
    )
    .1
}

/// Relative spacing of the coarse steps [`search_coarse_quantum`] scans.
const COARSE_QUANTUM_SPACING: f64 = 0.015;

/// A D/A coarser than the diagnosis's grid: fewer than three levels over the command. The
/// grid stops at ⅔ of the command's peak because there, with the gain free, the sawtooth is
/// nearly a copy of the command and explains any residual. With the gain held at its physical
/// 1 the quantiser must reproduce the applied torque itself, so steps from ⅔ of the peak to
/// just under twice it (beyond, every command rounds to 0) are searched that way, by
/// [`acceleration_rss`], and the best is kept where it fits better than the step found above,
/// or where the gain found above left its physical range [0, 1]. A gain the model file holds
/// fixed is left alone.
fn search_coarse_quantum(model: &mut Model, p: &On, e: usize, range: f64) {
    let Some(g) = model.effects[e]
        .params
        .iter()
        .position(|q| q.name == "gain")
    else {
        return;
    };
    if !(range > 0.0 && model.effects[e].params[g].free) {
        return;
    }
    let found = acceleration_rss(&mut model.clone(), p);
    let gain = model.effects[e].params[g].value;
    let mut held = model.clone();
    held.effects[e].shape.quantum_blur = 0.0;
    if let Some(q) = held.effects[e].params.get_mut(g) {
        q.value = 1.0;
        q.free = false;
        q.sigma = None;
    }
    let (lo, hi) = (range / 1.5, 1.95 * range);
    let count = ((hi / lo).ln() / COARSE_QUANTUM_SPACING.ln_1p()).ceil() as usize;
    let mut xs = sim_plant::effects::signal::log_space(lo, hi, count.max(2));
    xs.push(model.effects[e].shape.quantum);
    let (d, _) = line_search_by(&mut held, p, e, &xs, &set_quantum, &acceleration_rss);
    let h = COARSE_QUANTUM_SPACING;
    golden_by(
        &mut held,
        p,
        e,
        (d / (1.0 + h), d * (1.0 + h)),
        d,
        10,
        &set_quantum,
        &acceleration_rss,
    );
    let cost = blur_then_step(&mut held, p, e, 0.1 * h, &acceleration_rss);
    if cost < found || !(0.0..=1.0).contains(&gain) {
        *model = held;
    }
}

/// The equation error in acceleration, RSS/J², for comparing fits whose regressand differs.
/// With the quantiser's gain held at 1 the fitted torque is the quantiser's output, which a
/// step near twice the command's peak holds at 0 almost everywhere: a fit with J → 0 then
/// leaves a small RSS while explaining nothing. Over J² it does not. An inertia that is not
/// positive scores ∞.
fn acceleration_rss(m: &mut Model, p: &On) -> f64 {
    let rss = ls_rss(m, p);
    let j = m.inertia.value;
    if j > 0.0 && j.is_finite() {
        rss / (j * j)
    } else {
        f64::INFINITY
    }
}

/// Best grid shape of `kind` against the current model's residual (largest ERR).
pub fn best_shape(model: &Model, p: &Prepared, kind: EffectKind) -> Option<Shape> {
    let d = residual::design(model, p);
    let g0i = gram_inverse(&gram(&d.cols));
    let base = fit::least_squares(&d.cols, &d.y).ok()?;
    diagnose::scan_shape(
        kind,
        model,
        p,
        &d.cols,
        &g0i,
        &base.residual,
        base.rss.max(1e-300),
    )
    .map(|(s, _)| s)
}
