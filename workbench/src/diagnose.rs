//! Which library effect is the model missing?
//!
//! For every effect the model does not contain, its fingerprint columns `Z` (from
//! `sim_plant::effects::fingerprint` — the one source of truth) are tested against the
//! equation-error residual of the current model:
//!
//! 1. **Shape search.** Effects with shape parameters (Stribeck velocity, ripple period,
//!    backlash width, compliance mode, quantiser step, …) are scanned over `shape_grid` (a
//!    ripple's period also over the peaks of a dense screen of the residual against position,
//!    a quantiser's step over those of a screen against the command, whose wavenumbers count
//!    in the grid), and sharp ones again over a finer `refine_grid`
//!    around the best (`shape_search`); for each shape the error-reduction
//!    ratio ERR = ΔRSS/RSS of adding `Z` to the current regressors `X` is computed in closed
//!    form from `ZᵀZ`, `ZᵀX`, `Zᵀe` (a partial-regression update, no refit), and the best
//!    shape is kept.
//! 2. **Test.** At that shape the augmented model `[X Z]` is fitted and the amplitudes are
//!    Wald-tested with a batch-means covariance (autocorrelation-robust, referred to
//!    `F(q, m − q)`, see [`super::stats`]). Because the shape was chosen as the best of `G`
//!    grid points, the p-value is Bonferroni-corrected by `G` (conservative: the selected
//!    shape's p-value is never below the grid minimum).
//! 3. **Family-wise control.** Holm's step-down over all candidates; a candidate is
//!    significant when its Holm p < α **and** it explains at least `min_err` of the residual
//!    variance **and** the RMS it explains is at least `min_rho` × the noise floor (practical
//!    significance: on 10⁵ samples a 0.01 % improvement is "significant" but not worth a
//!    model term).
//!
//! Where physics fixes the sign of an amplitude (`EffectKind::admissible_sign`: friction
//! consumes force, compliance and backlash reduce the apparent inertia, …) the test is
//! one-sided: an estimate of the wrong sign counts as no evidence. This is what keeps
//! errors-in-variables bias out: derivative-based fingerprints (compliance's a⁗) correlate
//! with the acceleration noise in the residual with a fixed, unphysical sign.
//! 4. **Rank** by ERR (how much of the residual the effect explains); verdict = the best
//!    significant candidate. A compliance mode the record does not resolve (never a verdict)
//!    that would rank above the verdict is ranked by its *motion form's* ERR instead, net of
//!    the encoder noise (`motion_form_err`): its command-form column carries the recorded
//!    input's own noise and can outrank a real friction effect by fitting it. Occam: if a
//!    significant candidate with fewer fingerprint columns leaves the same trace
//!    (contributions correlated ≥ `ambiguity_corr`) and the top one explains less than
//!    `min_err` more of the residual, the simpler one goes first.
//! 5. **Ambiguity.** If another significant candidate's best-fit contribution (its partial
//!    projection of the residual) correlates ≥ `ambiguity_corr` with the winner's and
//!    explains nearly as much, both are named with an experiment that would separate them.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use sim_plant::effects::{compliance, resolved, shape_search, EffectKind, Shape, Trajectory};

use super::fit::{self, cross_sums, gram, gram_inverse};
use super::metrics::Score;
use super::model::Model;
use super::residual::{self, ColumnMemo, Prepared};
use super::stats;
use super::units::eng;

/// Tuning of the diagnosis.
#[derive(Debug, Clone)]
pub struct Options {
    /// Family-wise error rate.
    pub alpha: f64,
    /// Minimum fraction of residual variance a candidate must explain.
    pub min_err: f64,
    /// Minimum RMS a candidate must explain, in units of the noise floor (ρ of the effect):
    /// once the residual is at the noise floor, a "significant" 1 % is a fit to noise-like
    /// artefacts of the record, not a physical effect worth a model term.
    pub min_rho: f64,
    /// Correlation of contributions above which two candidates are called ambiguous.
    pub ambiguity_corr: f64,
    /// ERR ratio (runner-up / winner) above which a correlated runner-up is ambiguous.
    pub ambiguity_err_ratio: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            alpha: 0.05,
            min_err: 0.01,
            min_rho: 0.25,
            ambiguity_corr: 0.9,
            ambiguity_err_ratio: 0.8,
        }
    }
}

/// One candidate effect.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// The effect (serialised as its lowercase name).
    pub effect: EffectKind,
    /// 1 = most likely missing.
    pub rank: usize,
    /// Wald F statistic at the best shape.
    pub statistic: f64,
    /// Holm-adjusted p-value (after the shape-search correction).
    pub p_value: f64,
    /// Raw p-value at the best shape.
    pub p_raw: f64,
    /// Fraction of the residual sum of squares the effect removes.
    pub err: f64,
    /// Numerator degrees of freedom (fingerprint columns).
    pub df: usize,
    /// Shape grid size (multiplicity of the shape search).
    pub grid: usize,
    /// Significant after Holm and the practical threshold.
    pub significant: bool,
    /// Best shape.
    #[serde(skip)]
    pub shape: Shape,
}

/// Baseline numbers.
#[derive(Debug, Clone, Serialize)]
pub struct Baseline {
    /// Fit %.
    pub fit_percent: f64,
    /// RMS residual.
    pub rms: f64,
    /// Noise floor of the equation-error residual: the input's noise and the encoder's noise
    /// through the fitted inertia, added in power ([`Prepared::equation_floor`]).
    pub noise_floor_rms: f64,
    /// The input's share of the floor ([`Prepared::noise_floor`]).
    pub input_noise_rms: f64,
    /// The position encoder's share: J·σ_a after the differentiator
    /// ([`Prepared::encoder_floor`]).
    pub encoder_noise_rms: f64,
    /// Ljung–Box p.
    pub ljung_box_p: f64,
    /// Model description.
    pub model: String,
}

/// The verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// Effect to add, or null.
    pub add: Option<EffectKind>,
    /// Candidates that are hard to tell apart from it.
    pub ambiguous_with: Vec<EffectKind>,
    /// Experiment that would separate them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub experiment: Option<String>,
    /// Plain text.
    pub text: String,
}

/// Result of `diagnose`.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Residual used.
    pub residual_mode: String,
    /// The input's intersample behaviour the residual assumed (`zoh`, `foh`, `mid`, `bl`).
    pub intersample: String,
    /// The differentiator's cut-off the residual was formed in (Hz): `--cutoff`, or the
    /// default the record's encoder noise sets.
    pub cutoff_hz: f64,
    /// Current-model numbers.
    pub baseline: Baseline,
    /// Ranked candidates.
    pub candidates: Vec<Candidate>,
    /// Verdict.
    pub verdict: Verdict,
    /// Effects that could not be tested on this record, with why.
    pub untestable: Vec<String>,
    /// Tested and ranked, but held back from the verdict, with why.
    pub notes: Vec<String>,
}

struct Scan {
    kind: EffectKind,
    shape: Shape,
    err: f64,
    grid: usize,
}

/// Records longer than this are shape-searched on a central window of this many samples (the
/// chosen shape is then scored on the whole record): filtered fingerprints (compliance,
/// quantisation) cost a filter pass per shape, and the shape is a property of the joint, not of
/// the record's length. A spatial period is searched on the whole record: its columns cost a
/// sine per sample, and the period a record resolves grows with its travel, which a central
/// window (the quiet middle of a chirp) can cut to a third.
pub const SEARCH_WINDOW: usize = 40_000;

/// Best shape of one effect by ERR against residual `e` of regressors with Gram inverse `g0i`
/// (the candidate columns from `memo` when it holds them).
#[allow(clippy::too_many_arguments)]
fn scan(
    kind: EffectKind,
    p: &Prepared,
    path: Option<&InputPath>,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    rss: f64,
    memo: Option<&ColumnMemo>,
) -> Option<Scan> {
    let t = p.trajectory();
    let whole = kind.fit_traits().search == sim_plant::effects::ShapeSearch::Period;
    let (shape, dr, grid) = if t.len() <= SEARCH_WINDOW || whole {
        search(kind, &t, x0, g0i, e, path, p.input_noise_var, memo)?
    } else {
        search_windowed(kind, p, path, &t, x0, g0i, e, memo)?
    };
    Some(Scan {
        kind,
        shape,
        err: dr / rss,
        grid,
    })
}

/// [`search`] on the central [`SEARCH_WINDOW`] samples of a long record; the chosen shape is
/// then scored (ΔRSS) on the whole record.
#[allow(clippy::too_many_arguments)]
fn search_windowed(
    kind: EffectKind,
    p: &Prepared,
    path: Option<&InputPath>,
    t: &Trajectory,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    memo: Option<&ColumnMemo>,
) -> Option<(Shape, f64, usize)> {
    let n = t.len();
    let w = (n - SEARCH_WINDOW) / 2..(n + SEARCH_WINDOW) / 2;
    let tw = Trajectory {
        input: &t.input[w.clone()],
        position: &t.position[w.clone()],
        velocity: &t.velocity[w.clone()],
        acceleration: &t.acceleration[w.clone()],
        load_position: t.load().map_or(&[], |l| &l[w.clone()]),
        raw_offset: t.raw_offset + w.start,
        ..*t
    };
    let xw: Vec<Vec<f64>> = x0.iter().map(|c| c[w.clone()].to_vec()).collect();
    let gw = gram_inverse(&gram(&xw));
    // The window's residual, made orthogonal to the window's regressors.
    let ew = fit::least_squares(&xw, &e[w.clone()]).ok()?.residual;
    let (shape, _, grid) = search(kind, &tw, &xw, &gw, &ew, path, p.input_noise_var, memo)?;
    let z = residual::candidate_columns_on(kind, t, &shape);
    let rss: f64 = e.iter().map(|v| v * v).sum();
    let bias = input_noise_bias(kind, &shape, path, p.input_noise_var, e.len(), rss);
    let (dr, first) = delta_rss_net(&z, x0, g0i, e, bias.as_slice());
    let dr = match kind.admissible_sign() {
        Some(sg) if first * sg <= 0.0 => 0.0,
        _ => dr,
    };
    Some((shape, dr, grid))
}

/// Shape search of one effect on trajectory `t`: best shape, its ΔRSS, shapes tried.
#[allow(clippy::too_many_arguments)]
fn search(
    kind: EffectKind,
    t: &Trajectory,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    path: Option<&InputPath>,
    input_noise_var: f64,
    memo: Option<&ColumnMemo>,
) -> Option<(Shape, f64, usize)> {
    // Where physics fixes the sign of the first amplitude, a shape whose fit has the wrong
    // sign explains nothing (the same rule as the test below), so the search does not settle
    // on it and hide an admissible shape.
    use rayon::prelude::*;
    let sign = kind.admissible_sign();
    let rss: f64 = e.iter().map(|v| v * v).sum();
    let score = |s: &Shape| {
        let z = match memo {
            Some(m) => m.candidate(kind, t, s),
            None => std::sync::Arc::new(residual::candidate_columns_on(kind, t, s)),
        };
        if z.is_empty() {
            return None;
        }
        let bias = input_noise_bias(kind, s, path, input_noise_var, e.len(), rss);
        let (dr, first) = delta_rss_net(&z, x0, g0i, e, bias.as_slice());
        Some(match sign {
            Some(sg) if first * sg <= 0.0 => 0.0,
            _ => dr,
        })
    };
    shape_search(kind, t, e, |batch| batch.par_iter().map(score).collect())
}

/// What the recorded input's own noise puts into a candidate column built linearly from that
/// input (compliance's command form `L·H·u`) and into the residual alike (`L·u`, or the
/// input τ late when the model holds a delay: [`InputPath`]): their products' expectation,
/// σ²·n·⟨h_z, h_e⟩, from the input probe's impulse responses (`Prepared::input_probe`).
/// Without it such a column
/// "explains" the residual's share of white noise in its band — on a record at its noise
/// floor a mode near the band's edge took 20 % of the residual at Holm p 3·10⁻⁸. σ² is the
/// input's second-difference estimate, capped at what the residual could hold if it were all
/// input noise (a dithered command reads high: the dither moves the joint and is no noise).
/// Empty for every other column.
fn input_noise_bias(
    kind: EffectKind,
    shape: &Shape,
    path: Option<&InputPath>,
    input_noise_var: f64,
    n: usize,
    rss: f64,
) -> Vec<NoiseBias> {
    let command_form = kind == EffectKind::Compliance && shape.compliance_near_inertia <= 0.0;
    let Some(path) = path.filter(|_| command_form) else {
        return Vec::new();
    };
    let hz = residual::candidate_columns_on(kind, &path.probe.trajectory(), shape);
    let Some(h) = hz.first() else {
        return Vec::new();
    };
    let he = &path.residual;
    let ee: f64 = he.iter().map(|x| x * x).sum();
    if ee.is_nan() || ee <= 0.0 {
        return Vec::new();
    }
    let n = n as f64;
    let s2 = input_noise_var.min(rss / (n * ee));
    // Only the shared term: the column's own noise energy (an attenuation, not a false
    // explanation) is left in, as an over-estimated σ² would otherwise inflate the fit.
    vec![NoiseBias {
        cross: s2 * n * h.iter().zip(he).map(|(a, b)| a * b).sum::<f64>(),
        energy: 0.0,
    }]
}

/// The input probe (`Prepared::input_probe`) and the residual's response to it under the
/// model: the recorded input low-passed, or applied τ late when the model holds a delay (its
/// prediction is the recorded input delayed, so the input's noise reaches the residual τ
/// late), and a command-form column shares it through its own response at lag τ.
struct InputPath<'a> {
    probe: &'a Prepared,
    residual: Vec<f64>,
}

impl<'a> InputPath<'a> {
    /// The path of `p`'s input probe under `model` (none without a probe): the probe's
    /// input less the input-delaying effects' columns at their fitted amplitudes.
    fn of(model: &Model, p: &'a Prepared) -> Option<Self> {
        let probe = p.input_probe.as_deref()?;
        let mut residual = probe.input.clone();
        for e in model
            .effects
            .iter()
            .filter(|e| e.kind.fit_traits().amplitude_by_search)
        {
            let amp = e.params.first().map_or(0.0, |q| q.value);
            for c in residual::model_columns(e.kind, probe, &e.shape) {
                for (h, x) in residual.iter_mut().zip(&c) {
                    *h -= amp * x;
                }
            }
        }
        Some(InputPath { probe, residual })
    }
}

/// Expected noise terms of one candidate column (see [`motion_form_err`]): its product with
/// the residual and its own energy that a sensor's noise puts there by construction.
#[derive(Debug, Clone, Copy)]
struct NoiseBias {
    cross: f64,
    energy: f64,
}

/// ΔRSS from adding columns `z` to regressors `x0` (residual `e` ⟂ `x0`), and the fitted
/// amplitude of the first column of `z`. `bias` (per column; may be shorter or empty) is
/// taken off the columns' cross-products with `e` and off their energies: what noise shared
/// by a column and the residual puts there by construction.
fn delta_rss_signed(
    z: &[Vec<f64>],
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    bias: &[NoiseBias],
) -> (f64, f64) {
    let q = z.len();
    let p = x0.len();
    // Row i: z[i]·x0[0], …, z[i]·x0[p−1], z[i]·e.
    let with: Vec<&[f64]> = x0.iter().map(Vec::as_slice).chain([e]).collect();
    let cross: Vec<Vec<f64>> = z.iter().map(|c| cross_sums(c, &with)).collect();
    let zx = DMatrix::from_fn(q, p, |i, j| cross[i][j]);
    let zz = gram(z);
    let ze = DVector::from_iterator(
        q,
        (0..q).map(|i| cross[i][p] - bias.get(i).map_or(0.0, |b| b.cross)),
    );
    let mut zt = &zz - &zx * g0i * zx.transpose();
    // The column's own noise energy, off its diagonal (capped at half: the refit's rule).
    for (i, b) in bias.iter().enumerate().take(q) {
        zt[(i, i)] -= b.energy.clamp(0.0, 0.5 * zt[(i, i)].max(0.0));
    }
    // Columns the current model already spans carry no new information.
    for i in 0..q {
        if zt[(i, i)] <= 1e-9 * zz[(i, i)].max(1e-300) {
            return (0.0, 0.0);
        }
    }
    let zti = gram_inverse(&zt);
    let theta = &zti * &ze;
    // A corrected fit cannot explain more than the residual holds.
    let rss: f64 = e.iter().map(|v| v * v).sum();
    let dr = (ze.transpose() * theta.clone())[(0, 0)];
    (dr.clamp(0.0, rss), theta[0])
}

/// [`delta_rss_signed`] net of the noise `bias` shares with the residual, and never above the
/// plain ΔRSS: the correction takes off what the noise explains by construction, and a σ² read
/// high (a dithered command's second difference holds the dither) must not turn its excess into
/// an explanation. The test scales its statistic by the same share, capped at 1 (`diagnose_with`).
fn delta_rss_net(
    z: &[Vec<f64>],
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    bias: &[NoiseBias],
) -> (f64, f64) {
    let (dr, first) = delta_rss_signed(z, x0, g0i, e, bias);
    if bias.is_empty() {
        return (dr, first);
    }
    let (raw, _) = delta_rss_signed(z, x0, g0i, e, &[]);
    (dr.min(raw), first)
}

/// Partial projection of `e` on `z` after removing `x0`: the candidate's best-fit contribution.
fn contribution(z: &[Vec<f64>], x0: &[Vec<f64>], g0i: &DMatrix<f64>, e: &[f64]) -> Vec<f64> {
    let n = e.len();
    let q = z.len();
    let p = x0.len();
    let with: Vec<&[f64]> = x0.iter().map(Vec::as_slice).collect();
    let cross: Vec<Vec<f64>> = z.iter().map(|c| cross_sums(c, &with)).collect();
    let zx = DMatrix::from_fn(q, p, |i, j| cross[i][j]);
    let b = g0i * zx.transpose(); // p×q
    let zt: Vec<Vec<f64>> = (0..q)
        .map(|i| {
            let mut c = z[i].clone();
            for j in 0..p {
                let k = b[(j, i)];
                for (cc, x) in c.iter_mut().zip(&x0[j]) {
                    *cc -= k * x;
                }
            }
            c
        })
        .collect();
    let gi = gram_inverse(&gram(&zt));
    let ze = DVector::from_iterator(
        q,
        zt.iter()
            .map(|c| c.iter().zip(e).map(|(a, b)| a * b).sum::<f64>()),
    );
    let g = gi * ze;
    let mut out = vec![0.0; n];
    for i in 0..q {
        for (o, c) in out.iter_mut().zip(&zt[i]) {
            *o += g[i] * c;
        }
    }
    out
}

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let ab: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let aa: f64 = a.iter().map(|x| x * x).sum();
    let bb: f64 = b.iter().map(|x| x * x).sum();
    if aa * bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// An experiment that separates two effects with similar fingerprints on this record.
pub fn separating_experiment(a: EffectKind, b: EffectKind) -> String {
    use EffectKind::*;
    let pair = |x, y| (a == x && b == y) || (a == y && b == x);
    if pair(Coulomb, Stribeck) || pair(Stribeck, Viscous) {
        "constant-velocity sweeps at several speeds from ~1 % to 100 % of the maximum in both directions (friction–velocity map)".into()
    } else if pair(Coulomb, Offset) || pair(Offset, Asymmetry) || pair(Coulomb, Asymmetry) {
        "slow triangle moves at two or more speeds in both directions: offset shifts both directions equally, Coulomb flips with direction, asymmetry grows with speed".into()
    } else if pair(Ripple, Gravity) || pair(Ripple, Cogging) {
        "constant-velocity moves over several periods at two speeds: a position-periodic effect keeps its period in position, not in time".into()
    } else if pair(Gravity, Offset) {
        "hold the axis at several positions over a large travel: gravity varies with angle, an offset does not".into()
    } else if pair(Delay, Compliance) || pair(Compliance, Backlash) || pair(Delay, Backlash) {
        "torque steps or a chirp with a load-side sensor: compliance shows a resonance and load/motor difference, delay a pure phase lag, backlash a dead zone at reversals".into()
    } else if pair(Deadband, Coulomb) || pair(Deadband, Quantization) {
        "open-loop slow input ramps through zero with the axis free: a dead zone shows no motion below a command threshold".into()
    } else {
        "a richer excitation: broadband chirp over the full travel, at several speeds and load levels, in both directions".into()
    }
}

/// Best shape of one effect and its ERR against residual `e` of regressors `x0`.
pub fn scan_shape(
    kind: EffectKind,
    model: &Model,
    p: &Prepared,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    rss: f64,
) -> Option<(Shape, f64)> {
    let path = InputPath::of(model, p);
    scan(kind, p, path.as_ref(), x0, g0i, e, rss, None).map(|s| (s.shape, s.err))
}

/// ERR of compliance in its *motion form* (`H₂·a`: the acceleration high-passed at the
/// locked-motor mode, unit J1, no ratio — `sim_plant::effects::compliance`'s motion column
/// as `refine` starts it), best over the compliance grid, net of the encoder noise the column
/// shares with the residual. Used to rank a mode the record does not resolve in the command
/// form against a significant resolved candidate: the command form's column carries the
/// recorded input's own noise, as the residual does, and at a mode near the band edge it
/// "explains" that noise (8 of 10 % ERR on a Stribeck trial at ρ = 2, where it outranked
/// the significant Stribeck friction). The motion form has none of the input's noise; the
/// encoder's noise it does carry is known well (the position's fourth difference, see
/// [`Prepared::position_noise_var`]) and is taken off through the noise probe's impulse
/// responses. A transmission mode leaves its residual in both forms.
fn motion_form_err(
    p: &Prepared,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    rss: f64,
    inertia: f64,
) -> f64 {
    let t = p.trajectory();
    let n = e.len() as f64;
    let probe = p.noise_probe.as_deref();
    let mut best = 0.0f64;
    // The locked-motor mode lies below the coupled one (f₂ = f/√(1 + J2/J1)): the grid's
    // frequencies and half of them, at more dampings than the command form's grid (the
    // searched ζ₂ also carries the load's viscous friction).
    let grid = sim_plant::effects::shape_grid(EffectKind::Compliance, &t);
    let mut freqs: Vec<f64> = grid.iter().map(|s| s.compliance_frequency).collect();
    freqs.extend(grid.iter().map(|s| 0.5 * s.compliance_frequency));
    freqs.sort_by(f64::total_cmp);
    freqs.dedup_by(|a, b| (*a / *b - 1.0).abs() < 1e-9);
    let shapes = freqs.iter().flat_map(|&f| {
        [0.01, 0.02, 0.05, 0.1, 0.2, 0.35, 0.6].map(|zeta| {
            let mut sh = Shape {
                compliance_frequency: f,
                compliance_damping: zeta,
                ..Shape::default()
            };
            compliance::set_unit_motion_form(&mut sh);
            sh
        })
    });
    for sh in shapes {
        let z = residual::candidate_columns_on(EffectKind::Compliance, &t, &sh);
        // The residual's encoder noise is −J·(the acceleration's); the column's is its own
        // impulse response to the position's noise.
        let bias = probe.map(|pr| {
            let hz = residual::candidate_columns_on(EffectKind::Compliance, &pr.trajectory(), &sh);
            let h = &hz[0];
            let cross: f64 = h.iter().zip(&pr.acceleration).map(|(a, b)| a * b).sum();
            let energy: f64 = h.iter().map(|a| a * a).sum();
            let s2 = n * p.position_noise_var;
            NoiseBias {
                cross: -s2 * inertia * cross,
                energy: s2 * energy,
            }
        });
        let (dr, first) = delta_rss_signed(&z, x0, g0i, e, bias.as_slice());
        if first < 0.0 {
            best = best.max(dr / rss);
        }
    }
    best
}

/// Occam between indistinguishable candidates (step 4 of the module docs).
///
/// Effects of the library differ in their number of fingerprint columns (asymmetry has a
/// Coulomb-extra and a viscous-extra column, deadband a width and a nonlinearity column), and
/// more columns always explain at least as much. When the top candidate by ERR and a
/// significant candidate with *fewer* columns leave the same trace on this record (their
/// contributions correlate ≥ `ambiguity_corr`), the richer one is kept on top only if it
/// explains at least `min_err` more of the residual than the simpler one; otherwise the
/// simpler one is moved to rank 1. Both stay in the list, and the verdict names them as
/// ambiguous. (Both already passed the noise-floor test, so the comparison is relative.)
fn prefer_parsimonious(
    cands: &mut [Candidate],
    p: &Prepared,
    x0: &[Vec<f64>],
    g0i: &DMatrix<f64>,
    e: &[f64],
    opts: &Options,
) {
    let Some(top) = cands.first().filter(|c| c.significant).cloned() else {
        return;
    };
    let zt = residual::candidate_columns(top.effect, p, &top.shape);
    let ct = contribution(&zt, x0, g0i, e);
    let mut best: Option<usize> = None;
    for (i, c) in cands.iter().enumerate().skip(1) {
        if !c.significant || c.df >= top.df || best.is_some_and(|b| cands[b].df <= c.df) {
            continue;
        }
        // Both are already above the noise floor (significant); between two explanations of
        // the same residual what matters is how much more of it the richer one explains.
        if top.err - c.err >= opts.min_err {
            continue;
        }
        let zc = residual::candidate_columns(c.effect, p, &c.shape);
        let cc = contribution(&zc, x0, g0i, e);
        if corr(&ct, &cc).abs() >= opts.ambiguity_corr {
            best = Some(i);
        }
    }
    if let Some(i) = best {
        cands[..=i].rotate_right(1);
    }
}

/// Diagnose the (already fitted) model on prepared data.
pub fn diagnose(model: &Model, p: &Prepared, opts: &Options) -> Diagnosis {
    diagnose_with(model, p, opts, None)
}

/// [`diagnose`], the candidates' columns from `memo` when it holds them: `--auto` diagnoses
/// one record after every step, over the same grid of candidate shapes.
pub fn diagnose_with(
    model: &Model,
    p: &Prepared,
    opts: &Options,
    memo: Option<&ColumnMemo>,
) -> Diagnosis {
    let d = residual::design(model, p);
    let x0 = &d.cols;
    let g0i = gram_inverse(&gram(x0));
    let base = fit::least_squares(x0, &d.y).expect("enough samples for the current model");
    let e = &base.residual;
    let rss = base.rss.max(1e-300);
    // The inertia this fit gives (the model's own when it is held fixed).
    let inertia = d
        .free
        .iter()
        .position(|&i| i == 0)
        .and_then(|k| base.theta.get(k).copied())
        .unwrap_or(model.inertia.value);
    // The tests below need the plain least-squares residual (orthogonal to the model's
    // columns); the baseline the user reads is the model as fitted — the bias-compensated
    // inertia — so that it is the score `compare`, `fit` and `--auto` print for it.
    let own = residual::equation_error(model, p);
    let own_j = model.inertia.value;
    let score = Score::of(&own, p.equation_floor(own_j));
    let baseline = Baseline {
        fit_percent: score.fit_percent,
        rms: score.rms,
        noise_floor_rms: score.noise_floor_rms,
        input_noise_rms: p.noise_floor,
        encoder_noise_rms: p.encoder_floor(own_j),
        ljung_box_p: stats::ljung_box(&own.residual, 20).1,
        model: model.name.clone(),
    };

    let mut untestable = Vec::new();
    let mut notes = Vec::new();
    let mut scans = Vec::new();
    // Tested, and explain nothing: fitted with the unphysical sign at every shape (Coulomb
    // friction that would push the motion), or spanned by the model already.
    let mut nothing: Vec<Scan> = Vec::new();
    // The shape scans are independent: run them on the worker pool.
    let traj = p.trajectory();
    let kinds: Vec<EffectKind> = EffectKind::ALL
        .into_iter()
        .filter(|&k| !model.has(k))
        .filter(|&k| match sim_plant::effects::ruled_out(k, &traj) {
            Some(why) => {
                untestable.push(format!("{}: {why}", k.name()));
                false
            }
            None => true,
        })
        .collect();
    let input_path = InputPath::of(model, p);
    let path = input_path.as_ref();
    let scanned: Vec<(usize, Option<Scan>)> = {
        use rayon::prelude::*;
        kinds
            .par_iter()
            .enumerate()
            .map(|(i, &k)| (i, scan(k, p, path, x0, &g0i, e, rss, memo)))
            .collect()
    };
    for (i, sc) in scanned {
        let kind = kinds[i];
        match sc {
            Some(s) if s.err > 0.0 => scans.push(s),
            Some(s) => nothing.push(s),
            None => untestable.push(format!(
                "{}: no shape to test on this record (e.g. unknown period)",
                kind.name()
            )),
        }
    }

    // Wald test at each best shape.
    let t = p.trajectory();
    let mut cands: Vec<Candidate> = scans
        .iter()
        .map(|s| {
            let z = residual::candidate_columns_on(s.kind, &t, &s.shape);
            let q = z.len();
            let mut cols = x0.clone();
            cols.extend(z);
            let f = fit::least_squares(&cols, &d.y).expect("fit");
            let idx: Vec<usize> = (x0.len()..x0.len() + q).collect();
            // The share of the explained energy that survives the input-noise correction
            // (`input_noise_bias`; 1 for columns without it) scales the statistic too.
            let z = &cols[x0.len()..];
            let bias = input_noise_bias(s.kind, &s.shape, path, p.input_noise_var, e.len(), rss);
            let survives = if bias.is_empty() {
                1.0
            } else {
                let (raw, _) = delta_rss_signed(z, x0, &g0i, e, &[]);
                (s.err * rss / raw.max(1e-300)).clamp(0.0, 1.0)
            };
            let (stat, mut p_raw) = f.wald_scaled(&idx, survives);
            let mut err = s.err;
            // One-sided where physics fixes the sign of the (first) amplitude: half the
            // two-sided p when the estimate has the admissible sign, otherwise no evidence.
            if let Some(sign) = s.kind.admissible_sign() {
                if f.theta[x0.len()] * sign > 0.0 {
                    if q == 1 {
                        p_raw *= 0.5;
                    }
                } else {
                    p_raw = 1.0;
                    err = 0.0;
                }
            }
            Candidate {
                effect: s.kind,
                rank: 0,
                statistic: stat,
                p_value: (p_raw * s.grid as f64).min(1.0),
                p_raw,
                err,
                df: q,
                grid: s.grid,
                significant: false,
                shape: s.shape.clone(),
            }
        })
        .collect();
    let adj = stats::holm(&cands.iter().map(|c| c.p_value).collect::<Vec<_>>());
    let n = e.len() as f64;
    let floor = p.practical_floor(rss);
    for (c, a) in cands.iter_mut().zip(adj) {
        c.p_value = a;
        let explained_rms = (c.err * rss / n).sqrt();
        // A shape at the edge of what the record resolves (a transmission mode above its
        // bandwidth) is ranked, but not a verdict: the record does not identify it.
        let resolved = resolved(c.effect, &t, &c.shape);
        c.significant = a < opts.alpha
            && c.err >= opts.min_err
            && explained_rms >= opts.min_rho * floor
            && resolved;
        if !resolved && c.err > 0.0 {
            // Modes are searched up to twice the cut-off: name the band that reaches higher.
            let wider = crate::diff::default_cutoff(p.dt, None);
            let how = if wider > 1.01 * p.cutoff_hz {
                format!(
                    "--cutoff {wider:.0} tests modes up to {:.0} Hz",
                    2.0 * wider
                )
            } else {
                "a higher --cutoff tests higher modes".to_string()
            };
            notes.push(format!(
                "{}: best shape at the edge of what this record resolves (a transmission mode \
                 above its bandwidth); ranked, never a verdict — {how}",
                c.effect
            ));
        }
    }
    // Ranked last with no evidence (every effect not in the model is ranked). They stay out of
    // Holm's family: a test that cannot reject does not spend any of the error rate.
    cands.extend(nothing.iter().map(|s| Candidate {
        effect: s.kind,
        rank: 0,
        statistic: 0.0,
        p_value: 1.0,
        p_raw: 1.0,
        err: 0.0,
        df: residual::candidate_columns_on(s.kind, &t, &s.shape).len(),
        grid: s.grid,
        significant: false,
        shape: s.shape.clone(),
    }));
    // Ranked by ERR (the no-evidence candidates last). A compliance mode at a shape the record
    // does not resolve (never a verdict) that would outrank the verdict keeps that place only
    // if its motion form explains as much (see [`motion_form_err`]): otherwise it is ranked by
    // the motion form's ERR.
    let verdict_err = cands
        .iter()
        .filter(|c| c.significant && resolved(c.effect, &t, &c.shape))
        .map(|c| c.err)
        .reduce(f64::max);
    let mut rank_err: Vec<f64> = cands.iter().map(|c| c.err).collect();
    if let Some(v) = verdict_err {
        for (c, r) in cands.iter().zip(rank_err.iter_mut()) {
            let unresolved_mode = c.effect == EffectKind::Compliance
                && !resolved(EffectKind::Compliance, &t, &c.shape);
            if unresolved_mode && c.err >= v {
                *r = motion_form_err(p, x0, &g0i, e, rss, inertia);
            }
        }
    }
    let mut keyed: Vec<(f64, Candidate)> = rank_err.into_iter().zip(cands).collect();
    keyed.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut cands: Vec<Candidate> = keyed.into_iter().map(|(_, c)| c).collect();
    prefer_parsimonious(&mut cands, p, x0, &g0i, e, opts);
    for (i, c) in cands.iter_mut().enumerate() {
        c.rank = i + 1;
    }

    // A residual within [`AT_ENCODER_FLOOR`] of the encoder's noise through the inertia —
    // which no effect can explain, and which is estimated reliably (the position's fourth
    // difference; the input's own floor reads high on a dithered command) — has nothing left
    // to explain: what a candidate fits there is that noise's structure.
    // (A model with a transmission mode passes the encoder's noise through J1 + J2·G(s), not
    // J·s²: its floor is not the rigid one, and the rule does not apply.)
    let quiet = !model.has(EffectKind::Compliance)
        && baseline.rms <= AT_ENCODER_FLOOR * baseline.encoder_noise_rms;
    if quiet {
        let mut held = false;
        for c in cands.iter_mut().filter(|c| c.significant) {
            c.significant = false;
            held = true;
            notes.push(format!(
                "{}: significant, but the residual is within {:.0} % of the encoder's noise \
                 floor alone (RMS {:.2}× it): nothing is left to explain in this band",
                c.effect,
                100.0 * (AT_ENCODER_FLOOR - 1.0),
                baseline.rms / baseline.encoder_noise_rms
            ));
        }
        if let Some(f) = lower_cutoff(p, own_j, baseline.rms).filter(|_| held) {
            notes.push(format!(
                "the encoder's floor falls with the band: at --cutoff {f:.0} it would be half \
                 this residual, and what was held back here can be tested there"
            ));
        }
    }
    let winner = cands.iter().find(|c| c.significant).cloned();
    let verdict = match winner {
        None => Verdict {
            add: None,
            ambiguous_with: Vec::new(),
            experiment: None,
            text: "no significant missing effect".into(),
        },
        Some(w) => {
            let wk = w.effect;
            let zw = residual::candidate_columns(wk, p, &w.shape);
            let cw = contribution(&zw, x0, &g0i, e);
            let mut amb = Vec::new();
            for c in cands
                .iter()
                .filter(|c| c.significant && c.effect != w.effect)
                .take(6)
            {
                if c.err < opts.ambiguity_err_ratio * w.err {
                    continue;
                }
                let zc = residual::candidate_columns(c.effect, p, &c.shape);
                let cc = contribution(&zc, x0, &g0i, e);
                if corr(&cw, &cc).abs() >= opts.ambiguity_corr {
                    amb.push(c.effect);
                }
            }
            let experiment = amb.first().map(|&b| separating_experiment(wk, b));
            let text = if amb.is_empty() {
                format!(
                    "add {} (explains {:.1} % of the residual, Holm p = {:.2e})",
                    w.effect,
                    100.0 * w.err,
                    w.p_value
                )
            } else {
                format!(
                    "add {} — but hard to tell apart from {} on this record; to separate them: {}",
                    w.effect,
                    amb.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "),
                    experiment.clone().unwrap_or_default()
                )
            };
            Verdict {
                add: Some(w.effect),
                ambiguous_with: amb,
                experiment,
                text,
            }
        }
    };
    if let Some(note) = encoder_limited(&baseline, verdict.add) {
        notes.push(note);
    }
    if let Some(note) = unexplained(&baseline, verdict.add) {
        notes.push(note);
    }
    if let Some(note) = input_floor_reads_high(&baseline) {
        notes.push(note);
    }
    if let Some(note) = intersample_note(model, p, opts, rss) {
        notes.push(note);
    }
    if let Some(k) = verdict.add {
        if let Some(why) = sim_plant::effects::identifiability(k, &t) {
            notes.push(format!("{}: {why}", k.name()));
        }
    }
    Diagnosis {
        residual_mode: residual::Mode::Equation.name().into(),
        intersample: p.intersample.name().into(),
        cutoff_hz: p.cutoff_hz,
        baseline,
        candidates: cands,
        verdict,
        untestable,
        notes,
    }
}

/// A note when the record fits another intersample behaviour clearly better than the one
/// assumed — by the practical thresholds a candidate effect must pass (`min_err` of the
/// residual and `min_rho` × the noise floor): the two differ by half a sample of lag, which
/// a wrong convention leaves in the residual as a delay of either sign.
fn intersample_note(model: &Model, p: &Prepared, opts: &Options, rss: f64) -> Option<String> {
    use sim_plant::effects::Intersample;
    let mut others: Vec<(Intersample, f64)> =
        [Intersample::Zoh, Intersample::Foh, Intersample::Mid]
            .into_iter()
            .filter(|&i| i != p.intersample)
            .filter_map(|is| {
                let q = p.with_intersample(is);
                let d = residual::design(model, &q);
                fit::least_squares(&d.cols, &d.y).ok().map(|f| (is, f.rss))
            })
            .collect();
    others.sort_by(|a, b| a.1.total_cmp(&b.1));
    let &(best, best_rss) = others.first()?;
    let gain = 1.0 - best_rss / rss;
    let explained_rms = ((rss - best_rss).max(0.0) / p.len() as f64).sqrt();
    // Another that fits as well, to within the practical threshold, is named too: `mid` and
    // `foh` differ by a sinc in the band, far less than the half sample either is from `zoh`.
    let also: Vec<String> = others[1..]
        .iter()
        .filter(|(_, r)| (r - best_rss) < opts.min_err * rss)
        .map(|(i, _)| format!(" (or `{i}`, nearly as well)"))
        .collect();
    (gain >= opts.min_err && explained_rms >= opts.min_rho * p.practical_floor(rss)).then(|| {
        format!(
            "the input fits {:.1} % better read as `{best}`{} ({}) than as `{}`: if that is how \
             the record was logged, pass --intersample {best}",
            100.0 * gain,
            also.concat(),
            best.describe(),
            p.intersample
        )
    })
}

/// The highest cut-off, down to an eighth of the record's, at which the encoder's floor
/// through inertia `j` would be half of a residual of RMS `rms`: the floor scales with the
/// differentiator's acceleration gain (about f_c^2.5), while a joint's effects sit at the
/// motion's frequencies, well inside the band. `None` when no such band is that low.
fn lower_cutoff(p: &Prepared, j: f64, rms: f64) -> Option<f64> {
    let (fc, dt) = (p.cutoff_hz, p.dt);
    let g0 = crate::diff::acceleration_noise_gain(fc, dt);
    let enc = p.encoder_floor(j);
    if !(g0 > 0.0 && enc > 0.0 && rms > 0.0) {
        return None;
    }
    (1..=20)
        .map(|k| fc * 0.9f64.powi(k))
        .find(|&f| enc * crate::diff::acceleration_noise_gain(f, dt) / g0 <= 0.5 * rms)
}

/// RMS of a residual, in units of the encoder's share of its noise floor, up to which no
/// verdict is given (see `diagnose`).
pub const AT_ENCODER_FLOOR: f64 = 1.1;

/// RMS of a residual, in units of its noise floor, up to which it counts as "at the floor":
/// for `encoder_limited`, and for `fit`'s hint to look for another effect.
pub const AT_FLOOR: f64 = 1.2;

/// A warning when a verdict rests on a residual that is at its noise floor and that floor is
/// mostly the encoder's noise through the differentiator: that noise is a function of the
/// motion (between counts the position is flat, each count a step), and on a smooth,
/// undithered excitation it is structured enough for a filtered-motion or filtered-command
/// fingerprint to fit it consistently across the record — on a rigid joint with a 2¹⁶-count
/// encoder, two slow sines and a 40 Hz cut-off the diagnosis names compliance.
fn encoder_limited(b: &Baseline, verdict: Option<EffectKind>) -> Option<String> {
    let effect = verdict?;
    let at_floor = b.rms <= AT_FLOOR * b.noise_floor_rms;
    (at_floor && b.encoder_noise_rms > b.input_noise_rms).then(|| {
        format!(
            "{effect}: the residual is at its noise floor (RMS {:.2}× it) and {:.0} % of that \
             floor's power is the encoder's noise through the differentiator; the verdict may \
             fit the differentiated quantisation, not a physical effect — confirm with a finer \
             encoder, a lower --cutoff or a dithered excitation",
            b.rms / b.noise_floor_rms,
            100.0 * (b.encoder_noise_rms / b.noise_floor_rms).powi(2)
        )
    })
}

/// RMS of a residual, in units of its noise floor, above which "no significant missing
/// effect" is not the end of the story (`unexplained` then adds a note).
pub const UNEXPLAINED: f64 = 1.5;

/// A note when no candidate is significant but the residual is well above its noise floor:
/// the verdict then means "nothing in the library", not "nothing left". On the XL330 servo
/// logs in ../shared/data/real, after gravity and Coulomb, no candidate is significant while
/// the residual is 3.2× its floor and not white: what is left has no fingerprint in the
/// library (docs/design/workbench-notebook.md, *On a second real machine*).
fn unexplained(b: &Baseline, verdict: Option<EffectKind>) -> Option<String> {
    let left = b.rms / b.noise_floor_rms;
    (verdict.is_none() && left > UNEXPLAINED).then(|| {
        format!(
            "no effect in the library explains a significant share of what is left, yet the \
             residual is {left:.2}× its noise floor{}: the model misses something the library \
             has no fingerprint for (load-dependent friction, a drive's current limit or \
             saturation, a further mode, …) — `compare` shows where it lives (by time, \
             velocity, position phase and load level)",
            if b.ljung_box_p < 1e-16 {
                " and not white (Ljung–Box p < 1e-16)".to_string()
            } else if b.ljung_box_p < 0.01 {
                format!(" and not white (Ljung–Box p {:.1e})", b.ljung_box_p)
            } else {
                String::new()
            }
        )
    })
}

/// A note when the input's share of the noise floor is above the whole residual. The residual
/// holds at least the noise the recorded input carries, so an input floor above it is not that
/// noise: the command's fast content moved the joint (a dither, steps, a controller acting on
/// the encoder's counts), and the second difference the floor is estimated from read it as
/// noise. The floor then reads high and every "× floor" figure low; `unexplained` stays quiet.
fn input_floor_reads_high(b: &Baseline) -> Option<String> {
    (b.input_noise_rms > b.rms).then(|| {
        format!(
            "noise floor: its input share ({}) is above the whole residual ({}), so it is not \
             the recorded input's noise but fast content of the command that moves the joint (a \
             dither, steps, a controller acting on the encoder's counts): the floor reads high \
             and \"× floor\" figures low; the encoder's share ({}) is the reliable part",
            eng(b.input_noise_rms),
            eng(b.rms),
            eng(b.encoder_noise_rms)
        )
    })
}

impl Diagnosis {
    /// The JSON object of the interface (plus extra fields).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "residual_mode": self.residual_mode,
            "intersample": self.intersample,
            "cutoff_hz": self.cutoff_hz,
            "baseline": self.baseline,
            "candidates": self.candidates,
            "verdict": self.verdict,
            "untestable": self.untestable,
            "notes": self.notes,
        })
    }

    /// Human-readable table.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let b = &self.baseline;
        let _ = writeln!(s, "model: {}", b.model);
        let _ = writeln!(
            s,
            "input between samples: {}   differentiator cut-off: {:.1} Hz",
            self.intersample, self.cutoff_hz
        );
        let _ = writeln!(
            s,
            "residual: {}   fit {:.2} %   RMS {}   noise floor {} (input {}, encoder {})   \
             Ljung–Box p {:.2e}",
            self.residual_mode,
            b.fit_percent,
            eng(b.rms),
            eng(b.noise_floor_rms),
            eng(b.input_noise_rms),
            eng(b.encoder_noise_rms),
            b.ljung_box_p
        );
        let _ = writeln!(
            s,
            "{:>4}  {:<13} {:>9} {:>12} {:>10} {:>4} {:>5}  sig",
            "rank", "effect", "ERR %", "F", "Holm p", "df", "grid"
        );
        for c in &self.candidates {
            let _ = writeln!(
                s,
                "{:>4}  {:<13} {:>9.3} {:>12} {:>10.2e} {:>4} {:>5}  {}",
                c.rank,
                c.effect,
                100.0 * c.err,
                eng(c.statistic),
                c.p_value,
                c.df,
                c.grid,
                if c.significant { "yes" } else { "no" }
            );
        }
        for u in &self.untestable {
            let _ = writeln!(s, "not tested: {u}");
        }
        for u in &self.notes {
            let _ = writeln!(s, "note: {u}");
        }
        let _ = writeln!(s, "verdict: {}", self.verdict.text);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn baseline(rms: f64, ljung_box_p: f64) -> Baseline {
        Baseline {
            fit_percent: 80.0,
            rms,
            noise_floor_rms: 1.0,
            input_noise_rms: 0.6,
            encoder_noise_rms: 0.8,
            ljung_box_p,
            model: "test".into(),
        }
    }

    /// The cut-off the held-back note names does put the encoder's floor at half the
    /// residual: a record prepared afresh at that cut-off, its encoder noise estimated again,
    /// shows it (a joint on a 2¹² encoder whose residual is at its encoder floor at 100 Hz).
    #[test]
    fn the_named_cutoff_halves_the_encoder_floor() {
        let (n, dt) = (12_000, 1e-3);
        let step = std::f64::consts::TAU / 4096.0;
        let q: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                let x = 0.8 * (0.7 * t).sin() + 0.1 * (5.3 * t).sin() + 0.02 * (31.0 * t).sin();
                (x / step).round() * step
            })
            .collect();
        let rec = |q: &[f64]| crate::data::Recording {
            path: "synthetic".into(),
            time: (0..n).map(|k| k as f64 * dt).collect(),
            input: (0..n).map(|k| (k as f64 * 1.3e-3).cos()).collect(),
            output: q.to_vec(),
            load_output: None,
            dt,
            units: ("N·m".into(), "rad".into()),
            columns: crate::data::Columns::new("u", "q"),
            resampled: None,
            recorded: None,
        };
        let j = 0.01;
        let p = Prepared::new(&rec(&q), Some(100.0));
        let floor = p.encoder_floor(j);
        assert!(floor > 0.0);
        let f = lower_cutoff(&p, j, floor).expect("a lower band halves it");
        assert!(f < 100.0 && f > 40.0, "{f}");
        let lower = Prepared::new(&rec(&q), Some(f)).encoder_floor(j);
        assert!(lower <= 0.55 * floor, "{lower} vs {floor} at {f} Hz");
        // A residual far above the floor needs no lower band than the first step.
        assert_eq!(lower_cutoff(&p, j, 100.0 * floor), Some(90.0));
    }

    /// The noise correction takes off what a column's noise explains by construction and
    /// nothing more: a shared-noise estimate far above what the column and the residual hold
    /// (σ² read from a dithered command's second difference) would, subtracted as it stands,
    /// turn a column unrelated to the residual into an explanation of all of it.
    #[test]
    fn the_noise_correction_never_adds_explanation() {
        let n = 4000;
        let x0 = vec![vec![1.0; n]];
        let g0i = gram_inverse(&gram(&x0));
        let mut e: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).sin()).collect();
        let mean = e.iter().sum::<f64>() / n as f64;
        e.iter_mut().for_each(|v| *v -= mean);
        let z = vec![e
            .iter()
            .enumerate()
            .map(|(k, v)| (k as f64 * 1.3).cos() + 0.01 * v)
            .collect::<Vec<f64>>()];
        let rss: f64 = e.iter().map(|v| v * v).sum();
        let zz: f64 = z[0].iter().map(|v| v * v).sum();
        let (plain, _) = delta_rss_signed(&z, &x0, &g0i, &e, &[]);
        let high = [NoiseBias {
            cross: -(zz * rss).sqrt(),
            energy: 0.0,
        }];
        let (subtracted, _) = delta_rss_signed(&z, &x0, &g0i, &e, &high);
        assert!(
            subtracted > 0.9 * rss && plain < 1e-3 * rss,
            "{subtracted} {plain} {rss}"
        );
        let (net, _) = delta_rss_net(&z, &x0, &g0i, &e, &high);
        assert!(net <= plain, "{net} vs plain {plain}");
        // A shared term of the product's own sign is taken off as it stands.
        let ze: f64 = z[0].iter().zip(&e).map(|(a, b)| a * b).sum();
        let part = [NoiseBias {
            cross: 0.5 * ze,
            energy: 0.0,
        }];
        let (net, _) = delta_rss_net(&z, &x0, &g0i, &e, &part);
        assert!((net / plain - 0.25).abs() < 0.01, "{net} vs {plain}");
    }

    /// An input floor above the whole residual cannot be the input's noise, and the report
    /// says so; one below it is left alone.
    #[test]
    fn an_input_floor_above_the_residual_is_named() {
        let note = input_floor_reads_high(&baseline(0.5, 0.0)).expect("0.6 above 0.5");
        assert!(
            note.contains("input share (0.6) is above the whole residual (0.5)")
                && note.contains("encoder's share (0.8)"),
            "{note}"
        );
        assert_eq!(input_floor_reads_high(&baseline(0.7, 0.0)), None);
    }

    /// "No significant missing effect" on a residual well above its floor says that the
    /// library ran out, not that nothing is left; at the floor, or with a verdict, it is quiet.
    #[test]
    fn a_residual_above_its_floor_with_no_verdict_gets_a_note() {
        let note = unexplained(&baseline(3.24, 0.0), None).expect("3.24× the floor, no verdict");
        assert!(
            note.contains("3.24× its noise floor")
                && note.contains("not white (Ljung–Box p < 1e-16)"),
            "{note}"
        );
        let some = unexplained(&baseline(3.0, 1e-4), None).expect("3× the floor");
        assert!(some.contains("not white (Ljung–Box p 1.0e-4)"), "{some}");
        let white = unexplained(&baseline(2.0, 0.5), None).expect("2× the floor");
        assert!(!white.contains("not white"), "{white}");
        assert_eq!(unexplained(&baseline(1.1, 0.0), None), None);
        assert_eq!(
            unexplained(&baseline(3.24, 0.0), Some(EffectKind::Coulomb)),
            None
        );
    }
}
