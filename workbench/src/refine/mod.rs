//! `fit --add` and `diagnose --auto`: add an effect, refit everything free, and show the error
//! before and after — on the estimation record and, if given, on a validation record.
//!
//! Amplitudes enter linearly, so they are fitted by linear least squares. A smooth shape
//! parameter (Stribeck velocity, ripple period, dead-zone width) is first placed at the best
//! point of the library's `shape_grid`, then refined together with all free amplitudes by
//! Levenberg–Marquardt on the equation error (log-parameterised so it stays positive); its 1σ
//! comes from the LM Jacobian with the same batch-means covariance. Shapes whose fingerprint
//! is not smooth in the shape (backlash width, quantum) are not refined by LM. Before LM,
//! searches least squares cannot do (see `search_shapes`): a delay's τ on the input actually
//! delayed, Coulomb's sign lead and smoothing, the ripple period on a fine grid, the
//! compliance mode (and the motion form of its column), the quantiser step and the blur of
//! its sawtooth, the backlash width and the load's time constant, Stribeck's stick window (at
//! rest the friction is the applied torque).
//!
//! `--auto` adds the diagnosis's verdict, or a simpler significant candidate that fits as well
//! (BIC); when nothing significant is left it probes for a delay on the measured input, then
//! tries removals and replacements of what it added (BIC), because greedy addition can take
//! one flexible effect for two true ones.
//!
//! The module's parts: this file holds the scores, the refit (least squares, then the shape
//! searches, then LM) and `fit --add`; `search` the shape searches least squares cannot do;
//! [`auto()`] the `--auto` loop (choice by BIC, the delay probe, the swap pass); `coverage`
//! what a validation record asks of a fit beyond the positions it saw.

mod auto;
mod coverage;
mod search;

pub use auto::{auto, auto_observed, AutoRun, AutoStep};
pub use coverage::extrapolation_notes;
pub use search::best_shape;

use serde::Serialize;
use sim_plant::effects::{EffectKind, Shape, ShapeSearch};

use super::fit;
pub use super::metrics::Score;
use super::model::Model;
use super::residual::{self, Prepared};
pub use search::Only;
use search::{search_shapes, On, StickStart};

/// Equation-error score of a model on prepared data (no refit).
pub fn score(model: &Model, p: &Prepared) -> Score {
    Score::of(
        &residual::equation_error(model, p),
        p.equation_floor(model.inertia.value),
    )
}

/// One fitted parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ParamRow {
    /// Owner (`inertia` or an effect name).
    pub owner: String,
    /// Name.
    pub name: String,
    /// Value.
    pub value: f64,
    /// 1σ.
    pub sigma: f64,
    /// Unit, as the model's axis names it (`N·s/m` on a linear axis for `N·m·s/rad`).
    pub unit: String,
}

/// What `fit --add` reports.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Effect added (None = refit only).
    pub added: Option<EffectKind>,
    /// Before, estimation data.
    pub before: Score,
    /// After, estimation data.
    pub after: Score,
    /// Before, validation data.
    pub before_validation: Option<Score>,
    /// After, validation data.
    pub after_validation: Option<Score>,
    /// Parameters ± 1σ.
    pub params: Vec<ParamRow>,
}

/// Shape value that LM may refine, if the effect's fingerprint is smooth in it.
fn smooth_shape(kind: EffectKind, s: &Shape) -> Option<f64> {
    kind.fit_traits().smooth_shape.map(|a| (a.get)(s))
}

fn set_shape(kind: EffectKind, s: &mut Shape, v: f64) {
    if let Some(a) = kind.fit_traits().smooth_shape {
        (a.set)(s, v);
    }
}

/// Refit all free parameters of a model: least squares for the amplitudes, the shape searches
/// (`search::search_shapes`), then Levenberg–Marquardt over the smooth shapes of free
/// effects.
///
/// The LM is a *variable projection*: its unknowns are the shapes alone (log-parameterised),
/// and at each trial shape the amplitudes are the bias-compensated least-squares solution
/// ([`residual::refit`]). A joint LM over amplitudes and shapes minimises the plain sum of
/// squares, i.e. it is ordinary least squares in the amplitudes, and gives back the
/// errors-in-variables shrinkage of the inertia that the compensation takes out (the
/// acceleration column carries the encoder's noise), a few percent of the inertia: enough to
/// keep a refit off the noise floor. The objective is the
/// one the shape searches minimise (`search::ls_rss`), so LM polishes their result instead of
/// pulling it elsewhere. The amplitudes' 1σ are the least-squares ones at the final shape.
///
/// A model with a free Stribeck term is refitted from **several starts** (`StickStart::all`)
/// and keeps the one with the lowest equation error on the estimation record (its [`score`],
/// the stuck rows' clipped balancing torque included): everything searched; the dry-friction
/// sign lead held at 0; and the lead at 0 with the Stribeck exponent δ held at each value of
/// the grid. The stick window, the sign shape and vs × δ are searched one after the other on a
/// multimodal surface, and where the search ends depends on where the first steps took it. A
/// zero lead is the physical prior — the differentiator is zero-phase, so the friction
/// reverses where the measured velocity crosses zero — and the searched lead the data's
/// alternative; holding δ lets the window and vs settle under each curve shape instead of
/// the one the diagnosis's grid happened to prefer. On the 119 hidden-Stribeck trials at
/// ρ ≥ 1 of the 200-per-family bench, validation within 1.1× the floor: one start 93, the
/// first two 97, all four 103 (docs/design/workbench-notebook.md).
pub fn refit_all(model: &mut Model, p: &Prepared) -> Result<(), fit::FitError> {
    refit_searching(model, p, Only::All)
}

/// [`refit_all`], searching only the shapes of the effects from index `first` on (those just
/// added to a fitted model); the others keep theirs. `--auto` weighs its candidates so —
/// re-searching a transmission mode already in the model for every candidate was most of its
/// time — and refits the one it takes in full.
pub fn refit_added(model: &mut Model, p: &Prepared, first: usize) -> Result<(), fit::FitError> {
    refit_searching(model, p, Only::From(first))
}

fn refit_searching(model: &mut Model, p: &Prepared, only: Only) -> Result<(), fit::FitError> {
    // A stick window is searched from several starts (`refit_each_start`).
    let stick = model.effects.iter().any(|e| {
        e.kind.fit_traits().search == ShapeSearch::Stick && e.params.iter().any(|q| q.free)
    });
    if !stick {
        return refit_from(model, p, StickStart::SEARCHED, only);
    }
    let fits = refit_each_start(model, p, only);
    let mut best: Option<(f64, Model)> = None;
    let mut first_err = None;
    for (m, r) in fits {
        match r {
            Ok(()) => {
                let rms = score(&m, p).rms;
                let rms = if rms.is_nan() { f64::INFINITY } else { rms };
                if best.as_ref().is_none_or(|(b, _)| rms < *b) {
                    best = Some((rms, m));
                }
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    match best {
        Some((_, m)) => {
            *model = m;
            Ok(())
        }
        // Every start failed (`StickStart::all` is never empty): the first start's error.
        None => first_err.map_or(Ok(()), Err),
    }
}

/// The Stribeck refit from each of [`StickStart::all`], in start order (on the worker pool;
/// rayon collects in order, so the order, not which finishes first, decides ties in
/// [`refit_all`]).
#[doc(hidden)]
pub fn refit_each_start(
    model: &Model,
    p: &Prepared,
    only: Only,
) -> Vec<(Model, Result<(), fit::FitError>)> {
    use rayon::prelude::*;
    StickStart::all(p)
        .par_iter()
        .map(|&start| {
            let mut m = model.clone();
            let r = refit_from(&mut m, p, start, only);
            (m, r)
        })
        .collect()
}

/// [`refit_all`] from one start of the Stribeck searches.
fn refit_from(
    model: &mut Model,
    p: &Prepared,
    start: StickStart,
    only: Only,
) -> Result<(), fit::FitError> {
    refit_from_searched(model, p, start, only)?;
    if residual::out_of_range(model) {
        residual::refit_in_range(model, p)?;
    }
    Ok(())
}

/// [`refit_from`]'s shape searches and least squares, without the physical range.
fn refit_from_searched(
    model: &mut Model,
    p: &Prepared,
    start: StickStart,
    only: Only,
) -> Result<(), fit::FitError> {
    let on = On::new(p);
    for e in model.effects.iter_mut() {
        e.shape_sigma = None;
    }
    on.refit(model)?;
    search_shapes(model, &on, start, only);
    let before = on.refit(model)?.rss;
    let lm_idx: Vec<usize> = model
        .effects
        .iter()
        .enumerate()
        .filter(|(_, e)| {
            smooth_shape(e.kind, &e.shape).is_some() && e.params.iter().any(|q| q.free)
        })
        .map(|(i, _)| i)
        .collect();
    if lm_idx.is_empty() {
        return Ok(());
    }
    let x0: Vec<f64> = lm_idx
        .iter()
        .map(|&e| {
            smooth_shape(model.effects[e].kind, &model.effects[e].shape)
                .unwrap_or(1.0)
                .ln()
        })
        .collect();
    let template = model.clone();
    let apply = |x: &[f64]| -> Model {
        let mut m = template.clone();
        for (k, &e) in lm_idx.iter().enumerate() {
            let kind = m.effects[e].kind;
            set_shape(kind, &mut m.effects[e].shape, x[k].exp());
        }
        m
    };
    let lm = fit::levenberg_marquardt(
        |x| {
            let mut m = apply(x);
            on.refit(&mut m)
                .map(|f| f.residual)
                .unwrap_or_else(|_| vec![f64::INFINITY; p.len()])
        },
        &x0,
        30,
    );
    let mut m = apply(&lm.x);
    if let Ok(f) = on.refit(&mut m) {
        if f.rss < before && m.physical_split().is_ok() {
            // The batch-means 1σ of ln(shape), with the amplitudes re-solved at each trial
            // shape: its variable-projection Jacobian already carries their trade-off.
            for (k, &e) in lm_idx.iter().enumerate() {
                let entry = &mut m.effects[e];
                let var = lm.cov.get((k, k)).copied().unwrap_or(f64::NAN);
                entry.shape_sigma = smooth_shape(entry.kind, &entry.shape)
                    .map(|v| v * var.sqrt())
                    .filter(|s| s.is_finite());
            }
            *model = m;
        }
    }
    Ok(())
}

/// Parameter table of a model.
pub fn param_rows(model: &Model) -> Vec<ParamRow> {
    let axis = model.axis.unwrap_or_default();
    // A canonical unit as this model's data measure it: N·m → N on a linear axis, and → V
    // (V·s²/rad for an inertia) when the input was a command in V.
    let unit = |canonical: &str| match &model.input_unit {
        None => axis.unit(canonical),
        Some(u) if canonical == "kg·m²" => format!("{u}·s²/{}", axis.unit("rad")),
        Some(u) => axis.unit(canonical).replace(&axis.unit("N·m"), u),
    };
    let mut rows = vec![ParamRow {
        owner: "inertia".into(),
        name: model.inertia.name.clone(),
        value: model.inertia.value,
        sigma: model.inertia.sigma.unwrap_or(0.0),
        unit: unit("kg·m²"),
    }];
    for e in &model.effects {
        let specs = e.kind.params();
        for q in &e.params {
            rows.push(ParamRow {
                owner: e.kind.name().into(),
                name: q.name.clone(),
                value: q.value,
                sigma: q.sigma.unwrap_or(0.0),
                unit: specs
                    .iter()
                    .find(|s| s.name == q.name)
                    .map_or_else(String::new, |s| unit(s.unit)),
            });
        }
        if let Some(a) = e.kind.fit_traits().smooth_shape {
            rows.push(ParamRow {
                owner: e.kind.name().into(),
                name: "shape".into(),
                value: (a.get)(&e.shape),
                sigma: e.shape_sigma.unwrap_or(0.0),
                unit: unit(a.unit),
            });
        }
    }
    rows
}

/// Add `kind` (if given) at its best grid shape, refit everything free, and score before and
/// after on estimation and validation data.
pub fn fit_add(
    model: &mut Model,
    p: &Prepared,
    kind: Option<EffectKind>,
    validation: Option<&Prepared>,
) -> Result<FitReport, fit::FitError> {
    residual::refit(model, p)?;
    let before = score(model, p);
    let before_validation = validation.map(|v| score(model, v));
    if let Some(k) = kind {
        let shape = best_shape(model, p, k).unwrap_or_default();
        model.add(k, shape);
    }
    if !model.params().iter().any(|q| q.free) {
        return Err(fit::FitError::NothingFree);
    }
    refit_all(model, p)?;
    let after = score(model, p);
    let after_validation = validation.map(|v| score(model, v));
    // A fit that overflowed is not a result: no NaN fit % is printed, no model written.
    for (record, s) in [
        ("estimation", Some(after)),
        ("validation", after_validation),
    ] {
        for (what, value) in s.map_or(Vec::new(), |s| {
            vec![("fit %", s.fit_percent), ("RMS", s.rms)]
        }) {
            if !value.is_finite() {
                return Err(fit::FitError::NonFiniteScore {
                    what,
                    record,
                    value,
                });
            }
        }
    }
    Ok(FitReport {
        added: kind,
        before,
        after,
        before_validation,
        after_validation,
        params: param_rows(model),
    })
}

#[cfg(test)]
mod tests {
    use super::auto::{best_validating, bic, choose, swap_pass};
    use super::*;
    use crate::data::{Columns, Recording};
    use crate::diagnose::{self, Diagnosis};
    use crate::stats::tests_support::unit_uniform;

    /// A rigid joint (inertia [`J`], viscous 0.03 N·m·s/rad) on two sines, plus `extra`
    /// (position, velocity) → torque, with white torque noise of 3 mN·m rms, recorded through
    /// an encoder of `counts` per revolution (with 0.2 count of jitter).
    fn synthetic(extra: impl Fn(f64, f64) -> f64, counts: f64) -> Prepared {
        synthetic_around(0.0, extra, counts)
    }

    /// [`synthetic`] with the motion about `x0` (rad).
    fn synthetic_around(x0: f64, extra: impl Fn(f64, f64) -> f64, counts: f64) -> Prepared {
        synthetic_with(x0, extra, counts, 3e-3)
    }

    /// [`synthetic_around`] with torque noise of RMS `noise` (N·m).
    fn synthetic_with(
        x0: f64,
        extra: impl Fn(f64, f64) -> f64,
        counts: f64,
        noise: f64,
    ) -> Prepared {
        let (n, dt) = (20_000, 1e-3);
        let (j, b) = (J, 0.03);
        let step = std::f64::consts::TAU / counts;
        let w1 = std::f64::consts::TAU * 0.4;
        let w2 = std::f64::consts::TAU * 1.1;
        let mut time = Vec::with_capacity(n);
        let mut input = Vec::with_capacity(n);
        let mut output = Vec::with_capacity(n);
        for i in 0..n {
            let t = i as f64 * dt;
            let x = x0 + 0.08 * (w1 * t).sin() + 0.03 * (w2 * t + 1.0).sin();
            let v = 0.08 * w1 * (w1 * t).cos() + 0.03 * w2 * (w2 * t + 1.0).cos();
            let a = -0.08 * w1 * w1 * (w1 * t).sin() - 0.03 * w2 * w2 * (w2 * t + 1.0).sin();
            let tau = j * a + b * v + extra(x, v);
            let noise = (unit_uniform(2 * i as u64) - 0.5) * 12f64.sqrt() * noise;
            let jitter = (unit_uniform(2 * i as u64 + 1) - 0.5) * 12f64.sqrt() * 0.2 * step;
            time.push(t);
            input.push(tau + noise);
            output.push(step * ((x + jitter) / step).round());
        }
        // Torque and position sampled at the same instants.
        let columns = Columns::new("torque_Nm", "q_rad")
            .with_intersample(sim_plant::effects::Intersample::Bl);
        prepared("synthetic", columns, time, input, output, dt)
    }

    /// A torque → position recording at `dt`, prepared at a 40 Hz cut-off.
    fn prepared(
        path: &str,
        columns: Columns,
        time: Vec<f64>,
        input: Vec<f64>,
        output: Vec<f64>,
        dt: f64,
    ) -> Prepared {
        let rec = Recording {
            path: path.into(),
            time,
            input,
            output,
            load_output: None,
            dt,
            units: ("N·m".into(), "rad".into()),
            columns,
            resampled: None,
            recorded: None,
        };
        Prepared::new(&rec, Some(40.0))
    }

    const J: f64 = 0.02;
    const FINE: f64 = 1_048_576.0;

    /// Gravity's estimation record about 1 rad and its validation record about `x_val`, the
    /// baseline fitted on the first and its diagnosis there.
    fn gravity_about_1_rad_validated_at(
        x_val: f64,
    ) -> (Prepared, Prepared, Model, diagnose::Diagnosis) {
        let gravity = |x: f64, _: f64| 0.02 * x.sin();
        let est = synthetic_around(1.0, gravity, FINE);
        let val = synthetic_around(x_val, gravity, FINE);
        let mut m0 = Model::baseline();
        refit_all(&mut m0, &est).expect("fit");
        let d = diagnose::diagnose(&m0, &est, &diagnose::Options::default());
        (est, val, m0, d)
    }

    /// Gravity on a joint that moves a tenth of a radian about 1 rad: there it is a constant
    /// plus a slope below the noise, which an offset explains almost as well with one
    /// parameter fewer, and the verdict is the offset. A validation record about 3 rad refuses
    /// it (gravity there is a sixth of it), and `--auto` then takes the gravity behind it.
    #[test]
    fn a_simpler_step_that_does_not_validate_leaves_the_verdict_its_turn() {
        let (est, val, m0, d) = gravity_about_1_rad_validated_at(3.0);
        // The premise: the offset is the verdict, and the one candidate offered.
        assert_eq!(d.verdict.add, Some(EffectKind::Offset), "{}", d.to_text());
        let offered = choose(&m0, &est, &d, EffectKind::Offset).expect("choose");
        assert!(offered.iter().all(|(c, _)| c.effect == EffectKind::Offset));
        let mut m = m0.clone();
        let run = auto(&mut m, &est, Some(&val), &diagnose::Options::default(), 3).expect("auto");
        let added: Vec<_> = run.steps.iter().filter_map(|s| s.added.clone()).collect();
        assert_eq!(
            added.first().map(String::as_str),
            Some("gravity"),
            "{}",
            run.stop
        );
    }

    /// Two candidates that both lower the validation error: an offset (first in BIC order on
    /// an estimation record about 1 rad, where gravity is a constant plus a slope) and gravity.
    /// Validated about 2.6 rad, where gravity has fallen to half, the offset removes a third of
    /// the error and gravity nearly all of it, more than the offset per parameter: gravity.
    #[test]
    fn the_step_that_validates_best_per_parameter_is_taken() {
        let (est, val, m0, d) = gravity_about_1_rad_validated_at(2.6);
        let fitted = |k: EffectKind| {
            let c = d
                .candidates
                .iter()
                .find(|c| c.effect == k)
                .expect("candidate")
                .clone();
            let mut m = m0.clone();
            m.add(k, c.shape.clone());
            refit_all(&mut m, &est).expect("fit");
            (c, m)
        };
        let ranked = vec![fitted(EffectKind::Offset), fitted(EffectKind::Gravity)];
        let before = score(&m0, &val);
        // The premise: both lower the validation error, the offset by less.
        let after: Vec<f64> = ranked.iter().map(|(_, m)| score(m, &val).rms).collect();
        assert!(
            after[1] < after[0] && after[0] < 0.9 * before.rms,
            "{} → {after:?}",
            before.rms
        );
        let mut refused = None;
        let (c, _, _) = best_validating(&m0, &est, ranked, Some(&val), Some(before), &mut refused)
            .expect("refit")
            .expect("a step");
        assert_eq!(c.effect, EffectKind::Gravity);
        assert!(refused.is_none());
    }

    /// Coulomb friction and an offset, read by `--auto` as asymmetry and an offset (the
    /// step column spans half an offset and Coulomb at once, so it can go first): the closing
    /// swap pass puts Coulomb, one parameter fewer for the same sliding torque, in
    /// asymmetry's place.
    #[test]
    fn the_swap_pass_trades_asymmetry_for_coulomb_beside_an_offset() {
        let truth = |_: f64, v: f64| 0.02 * v.signum() + 0.015;
        let est = synthetic(truth, FINE);
        let val = synthetic_around(0.7, truth, FINE);
        let mut m0 = Model::baseline();
        refit_all(&mut m0, &est).expect("fit");
        let d = diagnose::diagnose(&m0, &est, &diagnose::Options::default());
        let start_len = m0.effects.len();
        let mut m = m0.clone();
        for k in [EffectKind::Asymmetry, EffectKind::Offset] {
            let shape = best_shape(&m, &est, k).expect("a grid shape");
            m.add(k, shape);
            refit_all(&mut m, &est).expect("fit");
        }
        let before = score(&m, &val);
        let moves = swap_pass(
            &mut m,
            &est,
            start_len,
            &d.candidates,
            Some(&val),
            Some(before),
        )
        .expect("swap pass");
        let names: Vec<_> = m.effects.iter().map(|e| e.kind).collect();
        assert!(
            m.has(EffectKind::Coulomb) && m.has(EffectKind::Offset),
            "{names:?} after {moves:?}"
        );
        assert!(!m.has(EffectKind::Asymmetry), "{names:?} after {moves:?}");
    }

    /// The baseline with a ripple of spatial period `period` (its amplitudes free at 0).
    pub(super) fn with_ripple(period: f64) -> Model {
        let mut m = Model::baseline();
        m.add(
            EffectKind::Ripple,
            Shape {
                ripple_period: period,
                ..Shape::default()
            },
        );
        m
    }

    /// A rigid joint with a position ripple, recorded through a 2¹⁶-count encoder: the
    /// differentiated acceleration carries enough encoder noise that ordinary least squares
    /// shrinks the inertia by more than 1 %. The refit with LM over the ripple period must keep
    /// the bias-compensated inertia (LM as variable projection), and find the period.
    #[test]
    fn lm_shape_refit_keeps_the_compensated_inertia() {
        let (j, amp, period) = (J, 0.01, 0.05);
        let p = synthetic(
            |x, _| amp * (std::f64::consts::TAU * x / period).sin(),
            65_536.0,
        );
        // The test is only meaningful where plain least squares would be visibly biased.
        let a2 = p.acceleration.iter().map(|a| a * a).sum::<f64>() / p.len() as f64;
        let acc_noise =
            p.position_noise_var * super::super::diff::acceleration_noise_gain(40.0, p.dt).powi(2);
        assert!(acc_noise / a2 > 0.02, "{}", acc_noise / a2);
        let mut m = with_ripple(0.051);
        refit_all(&mut m, &p).expect("fit");
        let period_fit = m.effects[1].shape.ripple_period;
        assert!(
            (period_fit / period - 1.0).abs() < 1e-2,
            "period {period_fit}"
        );
        assert!(
            (m.inertia.value / j - 1.0).abs() < 5e-3,
            "inertia {} vs {j}",
            m.inertia.value
        );
        let row = param_rows(&m).into_iter().find(|r| r.name == "shape");
        assert_eq!(row.map(|r| r.sigma), m.effects[1].shape_sigma);
    }

    /// The ripple period's 1σ is a statistical one: on the same motion with four times the
    /// torque noise it grows about fourfold (the sine's own harmonics and the encoder's
    /// counts are the same in both records).
    #[test]
    fn the_periods_sigma_grows_with_the_noise() {
        let sigma = |noise: f64| {
            let p = synthetic_with(
                0.0,
                |x, _| 0.01 * (std::f64::consts::TAU * x / 0.05).sin(),
                65_536.0,
                noise,
            );
            let mut m = with_ripple(0.051);
            refit_all(&mut m, &p).expect("fit");
            m.effects[1].shape_sigma.expect("the period's 1σ")
        };
        let (low, high) = (sigma(3e-3), sigma(12e-3));
        assert!(
            low > 0.0 && (2.5..6.0).contains(&(high / low)),
            "{low} → {high}"
        );
    }

    /// A Gaussian Stribeck curve (δ = 2) whose vs lies midway between two points of the
    /// shape grid (×1.9 apart): the fully searched start of the refit compares δ = 1 and 2
    /// each at its own best vs, and so finds the curve's shape, vs and excess (compared at
    /// the grid's points it took δ = 1).
    #[test]
    fn the_stribeck_refit_finds_the_curve_shape_between_grid_points() {
        let probe = synthetic(|_, _| 0.0, FINE);
        let grid: Vec<f64> =
            sim_plant::effects::shape_grid(EffectKind::Stribeck, &probe.trajectory())
                .iter()
                .filter(|s| s.stribeck_exponent == 2.0)
                .map(|s| s.stribeck_velocity)
                .collect();
        let vs = (grid[4] * grid[5]).sqrt();
        let (coulomb, excess) = (0.01, 0.02);
        let p = synthetic(
            |_, v| {
                let x = v / vs;
                v.signum() * (coulomb + excess * (-x * x).exp())
            },
            FINE,
        );
        let mut m = Model::baseline();
        m.add(EffectKind::Coulomb, Shape::default());
        m.add(EffectKind::Stribeck, Shape::default());
        // The fully searched start alone: `refit_all`'s other starts hold δ at each value.
        refit_from(&mut m, &p, StickStart::SEARCHED, Only::All).expect("fit");
        let e = &m.effects[2];
        assert_eq!(e.kind, EffectKind::Stribeck);
        let (d, v) = (e.shape.stribeck_exponent, e.shape.stribeck_velocity);
        let got = e.params[0].value;
        assert!(
            d == 2.0 && (v / vs - 1.0).abs() < 0.1 && (got / excess - 1.0).abs() < 0.1,
            "δ {d}, vs {v} (true {vs}), excess {got} (true {excess})"
        );
    }

    /// A two-mass joint (motor J1, load J2, shaft k and c; drag `b_motor` on the motor and
    /// `b_load` on the load) driven open loop by a torque multisine through the coupled mode
    /// (8 Hz), 12 s at 1 kHz, RK4 at 0.1 ms, 2²⁰ counts with 0.2 count of jitter and 1 mN·m
    /// of torque noise.
    /// [`two_mass`]'s inertias (kg·m²).
    const TWO_MASS_INERTIA: (f64, f64) = (0.5e-3, 0.75e-3);

    /// [`two_mass`]'s spring: stiffness and damping of an 8 Hz, ζ = 0.05 coupled mode.
    fn two_mass_spring() -> (f64, f64) {
        let (j1, j2) = TWO_MASS_INERTIA;
        let jr = j1 * j2 / (j1 + j2);
        let w = std::f64::consts::TAU * 8.0;
        (w * w * jr, 2.0 * 0.05 * w * jr)
    }

    fn two_mass(b_motor: f64, b_load: f64) -> Prepared {
        let (j1, j2) = TWO_MASS_INERTIA;
        let (k, c) = two_mass_spring();
        let (n, sub, dt) = (12_000, 10, 1e-3);
        let h = dt / sub as f64;
        let step = std::f64::consts::TAU / FINE;
        let freqs = [0.3, 0.7, 1.3, 2.9, 5.3, 7.1, 9.7, 13.0, 19.0];
        let torque = |t: f64| {
            freqs
                .iter()
                .enumerate()
                .map(|(i, f)| 0.004 * (std::f64::consts::TAU * f * t + i as f64).sin())
                .sum::<f64>()
        };
        let deriv = |s: [f64; 4], u: f64| {
            let spring = k * (s[0] - s[2]) + c * (s[1] - s[3]);
            [
                s[1],
                (u - b_motor * s[1] - spring) / j1,
                s[3],
                (spring - b_load * s[3]) / j2,
            ]
        };
        let (mut time, mut input, mut output) = (Vec::new(), Vec::new(), Vec::new());
        let mut s = [0.0; 4];
        for i in 0..n {
            let t = i as f64 * dt;
            let u = torque(t);
            let jitter = (unit_uniform(2 * i as u64 + 1) - 0.5) * 12f64.sqrt() * 0.2 * step;
            let noise = (unit_uniform(2 * i as u64) - 0.5) * 12f64.sqrt() * 1e-3;
            time.push(t);
            input.push(u + noise);
            output.push(step * ((s[0] + jitter) / step).round());
            // The command held over the sample (zero-order hold).
            for _ in 0..sub {
                let add = |s: [f64; 4], d: [f64; 4], f: f64| {
                    [
                        s[0] + f * d[0],
                        s[1] + f * d[1],
                        s[2] + f * d[2],
                        s[3] + f * d[3],
                    ]
                };
                let k1 = deriv(s, u);
                let k2 = deriv(add(s, k1, h / 2.0), u);
                let k3 = deriv(add(s, k2, h / 2.0), u);
                let k4 = deriv(add(s, k3, h), u);
                for q in 0..4 {
                    s[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q]);
                }
            }
        }
        let columns = Columns::new("torque_Nm", "q_rad");
        prepared("two-mass", columns, time, input, output, dt)
    }

    /// A joint driven open loop through a D/A of step `quantum` (the command, a two-tone
    /// multisine peaking near 0.1 N·m, logged exactly; a disturbance after the D/A), and the
    /// refit of the baseline plus quantization handed the step `start`: the found step, the
    /// gain and whether it is free, the RMS before and after, and the model.
    fn refit_da(quantum: f64, start: f64) -> (f64, crate::model::Param, f64, f64, Model) {
        let (n, dt, j, b) = (12_000, 1e-3, J, 0.03);
        let (w1, w2) = (std::f64::consts::TAU * 0.7, std::f64::consts::TAU * 2.3);
        let step = std::f64::consts::TAU / FINE;
        let (mut time, mut input, mut output) = (Vec::new(), Vec::new(), Vec::new());
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let decay = (-b * dt / j).exp();
        for i in 0..n {
            let t = i as f64 * dt;
            let u = 0.06 * (w1 * t).sin() + 0.04 * (w2 * t + 1.0).sin();
            let noise = (unit_uniform(2 * i as u64) - 0.5) * 12f64.sqrt() * 2e-3;
            let applied = quantum * (u / quantum).round() + noise;
            let jitter = (unit_uniform(2 * i as u64 + 1) - 0.5) * 12f64.sqrt() * 0.2 * step;
            time.push(t);
            input.push(u);
            output.push(step * ((x + jitter) / step).round());
            // Exact over the sample with the torque held: v → τ/b with time constant J/b.
            let v_end = applied / b + (v - applied / b) * decay;
            x += applied / b * dt + (v - applied / b) * (j / b) * (1.0 - decay);
            v = v_end;
        }
        let p = prepared(
            "da",
            Columns::new("torque_Nm", "q_rad"),
            time,
            input,
            output,
            dt,
        );
        let mut m = Model::baseline();
        refit_all(&mut m, &p).expect("fit");
        let before = residual::equation_error(&m, &p).rms();
        m.add(
            EffectKind::Quantization,
            Shape {
                quantum: start,
                ..Shape::default()
            },
        );
        refit_all(&mut m, &p).expect("fit");
        let e = m
            .effects
            .iter()
            .find(|e| e.kind == EffectKind::Quantization)
            .expect("quantization");
        let (found, gain) = (e.shape.quantum, e.params.first().expect("gain").clone());
        let after = residual::equation_error(&m, &p).rms();
        (found, gain, before, after, m)
    }

    /// A D/A coarser than the diagnosis's grid: its step is 1.1× the command's peak, so the
    /// applied torque takes three levels (−Δ, 0, Δ). Handed the grid's coarsest step (⅔ of
    /// the peak), the refit finds the step with the gain held at 1 and a physical model.
    /// With the gain free such a step was fitted as a tenfold negative gain (a model no file
    /// can hold) that explained little.
    #[test]
    fn a_quantiser_coarser_than_the_grid_is_found_with_its_gain_held_at_one() {
        let (found, gain, before, after, m) = refit_da(0.11, 0.1 / 1.5);
        assert!(
            (found / 0.11 - 1.0).abs() < 0.01 && gain.value == 1.0 && !gain.free,
            "step {found} (truth 0.11), gain {} (free: {})",
            gain.value,
            gain.free
        );
        assert!(
            after < 0.3 * before && m.physical().is_ok(),
            "RMS {before} → {after}; {:?}",
            m.physical()
        );
    }

    /// The coarse steps do not take a fine quantiser's place: at a step of a tenth of the
    /// peak the refit keeps that step with its gain free.
    #[test]
    fn a_fine_quantiser_keeps_its_step_and_free_gain() {
        let (found, gain, before, after, _) = refit_da(0.01, 0.0103);
        assert!(
            (found / 0.01 - 1.0).abs() < 0.01 && gain.free && (0.0..=1.0).contains(&gain.value),
            "step {found} (truth 0.01), gain {} (free: {})",
            gain.value,
            gain.free
        );
        assert!(after < 0.5 * before, "RMS {before} → {after}");
    }

    /// The compliance column holds the load's own drag, (J2·s + b₂)², and none of the
    /// motor's, while the rigid fit gives only their sum: the refit finds where the drag
    /// sits, a bearing's at the motor or a seal's at the load.
    #[test]
    fn the_compliance_refit_finds_how_the_drag_splits_between_motor_and_load() {
        for (b_motor, b_load) in [(1e-3, 3e-3), (3e-3, 1e-3)] {
            let p = two_mass(b_motor, b_load);
            let mut m = Model::baseline();
            m.add(EffectKind::Compliance, Shape::default());
            refit_all(&mut m, &p).expect("fit");
            let e = m
                .effects
                .iter()
                .find(|e| e.kind == EffectKind::Compliance)
                .expect("compliance");
            let got = e.shape.compliance_load_damping;
            assert!(
                e.shape.compliance_near_inertia > 0.0 && (got / b_load - 1.0).abs() < 0.15,
                "drag {b_motor} at the motor, {b_load} at the load: the load's found {got} \
                 (motion form: {})",
                e.shape.compliance_near_inertia > 0.0
            );
            // The model file holds the same joint: the motor's drag at the motor, the
            // load's at the load, and the spring's own damping (not the mode's, which
            // carries the load's drag too).
            let sim = m.to_sim();
            let motor = sim.motor.damping.value;
            let load = sim.plant.output_damping.value
                + sim
                    .effects
                    .viscous
                    .as_ref()
                    .map_or(0.0, |v| v.damping.value);
            let spring = sim
                .effects
                .compliance
                .as_ref()
                .map_or(0.0, |c| c.damping.value);
            let (_, c) = two_mass_spring();
            let b = b_motor + b_load;
            assert!(
                (motor - b_motor).abs() < 0.1 * b
                    && (load - b_load).abs() < 0.1 * b
                    && (spring / c - 1.0).abs() < 0.15,
                "file: motor drag {motor} (truth {b_motor}), load {load} ({b_load}), spring \
                 damping {spring} ({c})"
            );
        }
    }

    /// The diagnosis of `p` against the baseline, with `effect` forced to be the verdict (as
    /// if its grid-shape test had come out significant).
    fn forced_verdict(p: &Prepared, effect: EffectKind) -> Diagnosis {
        let mut d = diagnose::diagnose(&Model::baseline(), p, &diagnose::Options::default());
        for c in &mut d.candidates {
            if c.effect == effect {
                c.significant = true;
            }
        }
        d.verdict.add = Some(effect);
        d
    }

    /// `--auto` adds a candidate only if its refitted model lowers the BIC: on a joint with
    /// nothing but inertia and viscous friction, an offset column handed in as the verdict
    /// buys a χ²(1)-sized drop in RSS and does not pay for its parameter; with a real offset
    /// in the data the same call takes it. On the rigid record compliance explains over a
    /// third of the residual at a mode above the record's band (its command-form column fits
    /// the input's own noise, and refitted it lowers the BIC) — it must not compete as a
    /// "close" alternative, being unresolved. A 2²⁰-count encoder keeps the baseline at the
    /// input's noise floor.
    #[test]
    fn choose_takes_a_candidate_only_if_its_refit_lowers_bic() {
        let baseline = Model::baseline();
        let mut m0 = baseline.clone();
        let rigid = synthetic(|_, _| 0.0, FINE);
        refit_all(&mut m0, &rigid).expect("fit");
        let d = forced_verdict(&rigid, EffectKind::Offset);
        let picked = choose(&m0, &rigid, &d, EffectKind::Offset).expect("choose");
        assert!(
            picked.is_empty(),
            "took {:?} on a joint without an offset",
            picked.first().map(|(c, _)| c.effect)
        );

        let mut m1 = baseline;
        let offset = synthetic(|_, _| 0.01, FINE);
        refit_all(&mut m1, &offset).expect("fit");
        let d = forced_verdict(&offset, EffectKind::Offset);
        let (c, fitted) = choose(&m1, &offset, &d, EffectKind::Offset)
            .expect("choose")
            .into_iter()
            .next()
            .expect("the offset in the data was not taken");
        assert_eq!(c.effect, EffectKind::Offset);
        assert!(bic(&fitted, &offset) < bic(&m1, &offset));
    }

    /// A fit stays in the parameters' physical range: on a joint that a friction *assists*
    /// (a negative Coulomb level, which no plant file can hold) the Coulomb term is held at 0
    /// with no 1σ and the rest refits to the best model that exists; a drag the data do
    /// support is fitted as before.
    #[test]
    fn a_fit_holds_a_parameter_at_its_physical_bound() {
        let assisted = synthetic(|_, v| -0.005 * v.signum(), FINE);
        let mut m = Model::baseline();
        m.add(EffectKind::Coulomb, Shape::default());
        refit_all(&mut m, &assisted).expect("fit");
        let c = &m.effect(EffectKind::Coulomb).expect("coulomb").params[0];
        assert_eq!(c.value, 0.0);
        assert!(c.free && c.sigma.is_none(), "{c:?}");
        assert!(m.physical().is_ok());
        // The viscous drag (0.03) takes what it can of the assist, which lowers it, and stays a
        // drag.
        let b = m.effect(EffectKind::Viscous).expect("viscous").params[0].value;
        assert!(b > 0.0 && b < 0.03, "{b}");
        // The bound is physical, not a clamp of every fit: a real drag comes out as itself.
        let dragged = synthetic(|_, v| 0.005 * v.signum(), FINE);
        refit_all(&mut m, &dragged).expect("fit");
        let c = &m.effect(EffectKind::Coulomb).expect("coulomb").params[0];
        assert!(
            (c.value / 0.005 - 1.0).abs() < 0.1 && c.sigma.is_some(),
            "{c:?}"
        );
    }

    /// On a rigid joint whose residual is mostly the encoder's quantisation through the
    /// differentiator, the diagnosis's floor must hold that noise (so the baseline reads as
    /// being at its floor, not 6× above it), and a verdict drawn there must carry the warning
    /// that it may be fitting the quantisation. With a fine encoder the input's noise is the
    /// floor and no warning is given.
    #[test]
    fn diagnosis_floor_holds_the_encoder_noise_through_the_inertia() {
        let coarse = synthetic(|_, _| 0.0, 65_536.0);
        let mut m = Model::baseline();
        refit_all(&mut m, &coarse).expect("fit");
        let d = diagnose::diagnose(&m, &coarse, &diagnose::Options::default());
        let b = &d.baseline;
        assert!(b.encoder_noise_rms > 3.0 * b.input_noise_rms, "{b:?}");
        let ratio = b.rms / b.noise_floor_rms;
        assert!((0.8..1.2).contains(&ratio), "RMS / floor {ratio}: {b:?}");
        if let Some(add) = &d.verdict.add {
            assert!(
                d.notes
                    .iter()
                    .any(|n| n.starts_with(add.name()) && n.contains("quantisation")),
                "verdict {add} without the encoder warning: {:?}",
                d.notes
            );
        }

        let fine = synthetic(|_, _| 0.0, FINE);
        let mut m = Model::baseline();
        refit_all(&mut m, &fine).expect("fit");
        let d = diagnose::diagnose(&m, &fine, &diagnose::Options::default());
        let b = &d.baseline;
        assert!(b.encoder_noise_rms < 0.5 * b.input_noise_rms, "{b:?}");
        assert!(!d.notes.iter().any(|n| n.contains("quantisation")));
    }
}
