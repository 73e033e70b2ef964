//! `diagnose --auto`: rank → add → refit until nothing significant is left, choosing among
//! close candidates by BIC per parameter (with a validation record, by the validation error
//! each removes per parameter), then a delay probe and a swap pass over what it added. With a
//! validation record every effect must earn its place there: a step must lower the
//! validation error (when no significant candidate does, `--auto` stops), and the swap pass
//! drops an effect whose removal the validation record does not pay for.

use serde::Serialize;
use sim_plant::effects::{EffectKind, Shape};

use super::super::diagnose::{self, Diagnosis, Options};
use super::super::fit;
use super::super::model::{EffectEntry, Model};
use super::super::residual::{self, ColumnMemo, Prepared};
use rayon::prelude::*;

use super::{refit_added, refit_all, score, Score};

/// One step of `diagnose --auto`.
#[derive(Debug, Clone, Serialize)]
pub struct AutoStep {
    /// Step number (0 = starting model).
    pub step: usize,
    /// Effect added at this step.
    pub added: Option<String>,
    /// Effect this step removed or replaced (the closing swap pass of `--auto`), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub replaced: Option<String>,
    /// Score after the step (estimation data).
    pub score: Score,
    /// Score on validation data.
    pub validation: Option<Score>,
    /// The verdict this step's effect displaced: `choose` took another candidate because its
    /// full refit had the lower BIC.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chosen_over: Option<String>,
    /// Holm p of the added effect at its grid shape (none when it was not significant there
    /// and won on its refitted BIC, see [`AutoStep::chosen_over`]).
    pub p_value: Option<f64>,
    /// Diagnosis text at this step.
    pub verdict: String,
}

/// Result of `diagnose --auto`.
#[derive(Debug, Clone, Serialize)]
pub struct AutoRun {
    /// Steps.
    pub steps: Vec<AutoStep>,
    /// Final diagnosis.
    pub last: Diagnosis,
    /// Why `--auto` stopped (its final diagnosis may still name a candidate: one it could not
    /// add, or the step limit).
    pub stop: String,
}

/// Rank → add → refit until nothing significant is left (at most `max_steps` additions).
pub fn auto(
    model: &mut Model,
    p: &Prepared,
    validation: Option<&Prepared>,
    opts: &Options,
    max_steps: usize,
) -> Result<AutoRun, fit::FitError> {
    auto_observed(model, p, validation, opts, max_steps, &mut |_| {})
}

/// [`auto`], calling `on_step` with each step as it is taken: a step refits its leading
/// candidates in full, which takes seconds to minutes on a long record, so a front end can
/// show progress.
pub fn auto_observed(
    model: &mut Model,
    p: &Prepared,
    validation: Option<&Prepared>,
    opts: &Options,
    max_steps: usize,
    on_step: &mut dyn FnMut(&AutoStep),
) -> Result<AutoRun, fit::FitError> {
    let mut steps = Steps {
        list: Vec::new(),
        on_step,
    };
    refit_all(model, p)?;
    steps.push(AutoStep {
        step: 0,
        added: None,
        replaced: None,
        score: score(model, p),
        validation: validation.map(|v| score(model, v)),
        chosen_over: None,
        p_value: None,
        verdict: "start".into(),
    });
    let start_len = model.effects.len();
    let mut seen: Vec<diagnose::Candidate> = Vec::new();
    // Every step diagnoses `p` again, over the same grid of candidate shapes.
    let memo = ColumnMemo::with_budget(residual::DIAGNOSIS_BUDGET);
    loop {
        let d = diagnose::diagnose_with(model, p, opts, Some(&memo));
        for c in &d.candidates {
            // Significant candidates, and the best of an effect nesting one in the model even
            // when not significant: a ripple period between grid points explains little at the
            // grid, and gravity (a ripple of period 2π) takes its place; the swap pass then
            // tries ripple for gravity.
            let keep = c.significant || c.effect.fit_traits().nests.iter().any(|&k| model.has(k));
            if keep && !seen.iter().any(|s| s.effect == c.effect) {
                seen.push(c.clone());
            }
        }
        let Some(name) = d.verdict.add else {
            if steps.list.len() <= max_steps {
                let probe = delay_probe(model, p, opts)?;
                let val_before = steps.list.last().and_then(|s| s.validation);
                if let Some((m, text)) = probe.filter(|(m, _)| validates(m, validation, val_before))
                {
                    *model = m;
                    steps.push(AutoStep {
                        step: steps.list.len(),
                        added: Some(EffectKind::Delay.name().into()),
                        replaced: None,
                        score: score(model, p),
                        validation: validation.map(|v| score(model, v)),
                        chosen_over: None,
                        p_value: None,
                        verdict: text,
                    });
                    continue;
                }
            }
            let val_before = steps.list.last().and_then(|s| s.validation);
            let moves = swap_pass(model, p, start_len, &seen, validation, val_before)?;
            if moves.is_empty() {
                return Ok(AutoRun {
                    steps: steps.list,
                    last: d,
                    stop: "nothing significant is left".into(),
                });
            }
            let sc = score(model, p);
            let val = validation.map(|v| score(model, v));
            for (added, replaced) in moves {
                let verdict = match &added {
                    Some(a) => format!("{a} replaces {replaced} (lower BIC)"),
                    None => format!("remove {replaced} (it no longer earns its place)"),
                };
                steps.push(AutoStep {
                    step: steps.list.len(),
                    added,
                    replaced: Some(replaced),
                    score: sc,
                    validation: val,
                    chosen_over: None,
                    p_value: None,
                    verdict,
                });
            }
            let last = diagnose::diagnose_with(model, p, opts, Some(&memo));
            return Ok(AutoRun {
                steps: steps.list,
                last,
                stop: "nothing significant was left before the closing swap pass (a swap \
                       changes the rest of the fit, so the final diagnosis may differ)"
                    .into(),
            });
        };
        if steps.list.len() > max_steps {
            return Ok(AutoRun {
                steps: steps.list,
                last: d,
                stop: format!("reached --max-steps {max_steps}"),
            });
        }
        // With a validation record a step must earn its place there: of the candidates that
        // lower the validation error, the one that lowers it most per parameter; when none
        // does (or none refits within its physical range), the other significant candidates
        // get the same test.
        let ranked = choose(model, p, &d, name)?;
        let val_before = steps.list.last().and_then(|s| s.validation);
        let mut refused: Option<(EffectKind, Score)> = None;
        let mut taken = best_validating(model, p, ranked, validation, val_before, &mut refused)?;
        if taken.is_none() && validation.is_some() {
            let more = the_rest(model, p, &d, name)?;
            taken = best_validating(model, p, more, validation, val_before, &mut refused)?;
        }
        let Some((c, fitted, val)) = taken else {
            // Every candidate was refused on the validation record, or none refitted within
            // its physical range with a lower BIC (the last diagnosis says which was next):
            // stop with the model as it is.
            let stop = match (refused, val_before) {
                (Some((effect, after)), Some(before)) => format!(
                    "adding {effect} (or any other candidate) would not improve the validation \
                     record (RMS {} → {}): the model as it is validates best",
                    crate::units::eng(before.rms),
                    crate::units::eng(after.rms)
                ),
                _ => format!(
                    "{name} (and every close candidate) fits only with a parameter outside its \
                     physical range, or raises BIC once refitted"
                ),
            };
            return Ok(AutoRun {
                steps: steps.list,
                last: d,
                stop,
            });
        };
        *model = fitted;
        steps.push(AutoStep {
            step: steps.list.len(),
            added: Some(c.effect.name().into()),
            replaced: None,
            score: score(model, p),
            validation: val,
            chosen_over: (c.effect != name).then(|| name.name().into()),
            p_value: c.significant.then_some(c.p_value),
            verdict: d.verdict.text.clone(),
        });
    }
}

/// A step of `--auto` as it would be taken, with its validation score.
type Step = (diagnose::Candidate, Model, Option<Score>);

/// Of `ranked` (in BIC order), the step that buys the most validation per parameter it
/// spends: each refitted in full from its grid shape and scored on the validation record,
/// the largest ln(RMS before / RMS after) ÷ [`spent`] taken (the earlier on a tie). A
/// candidate that does not lower the validation error is refused (the first such is kept in
/// `refused` for the stop message). Without a validation record, the first of `ranked`.
///
/// Why validation decides between the ranked, not only whether the first may go: two
/// effects that the estimation record cannot tell apart (gravity and Coulomb friction over a
/// short travel) both lower the validation error, by very different amounts where the joint
/// moves differently; BIC order alone takes the one-parameter effect.
pub(super) fn best_validating(
    model: &Model,
    p: &Prepared,
    ranked: Vec<(diagnose::Candidate, Model)>,
    validation: Option<&Prepared>,
    before: Option<Score>,
    refused: &mut Option<(EffectKind, Score)>,
) -> Result<Option<Step>, fit::FitError> {
    let (Some(v), Some(before)) = (validation, before) else {
        return ranked
            .into_iter()
            .next()
            .map(|(c, fitted)| full_refit(model, p, &c, fitted).map(|m| (c, m, None)))
            .transpose();
    };
    // The refits and scores are independent and deterministic: on the worker pool, then
    // taken in BIC order.
    let steps: Vec<Result<(diagnose::Candidate, Model, Score), fit::FitError>> = ranked
        .into_par_iter()
        .map(|(c, fitted)| {
            let m = full_refit(model, p, &c, fitted)?;
            let val = score(&m, v);
            Ok((c, m, val))
        })
        .collect();
    let mut best: Option<(f64, Step)> = None;
    for step in steps {
        let (c, m, after) = step?;
        let gain = (before.rms / after.rms).ln() / spent(&c).max(1) as f64;
        if gain.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            refused.get_or_insert((c.effect, after));
            continue;
        }
        if best.as_ref().is_none_or(|b| gain > b.0) {
            best = Some((gain, (c, m, Some(after))));
        }
    }
    Ok(best.map(|(_, step)| step))
}

/// The step as taken: `c` added to `model` at its grid shape and refitted in full (the
/// ranking weighed it with the model's other shapes as they were), or `fitted` when that
/// leaves the physical range or fits worse than `model` did without the effect: a full
/// refit from the grid can settle in a worse optimum than the other shapes held where they
/// were, and a step never raises the error it is taken to lower.
fn full_refit(
    model: &Model,
    p: &Prepared,
    c: &diagnose::Candidate,
    fitted: Model,
) -> Result<Model, fit::FitError> {
    let mut m = model.clone();
    m.add(c.effect, c.shape.clone());
    refit_all(&mut m, p)?;
    let better = m.physical().is_ok() && score(&m, p).rms <= score(model, p).rms;
    Ok(if better { m } else { fitted })
}

/// Whether `m` does at least as well as `before` on the validation record (true without one).
fn validates(m: &Model, validation: Option<&Prepared>, before: Option<Score>) -> bool {
    validates_within(m, validation, before, 0)
}

/// [`validates`], allowing the validation error to rise by what the information criterion
/// charges for `slack` parameters: n_v·ln(RSS′/RSS) ≤ [`PENALTY`]·slack·ln n_v. A move that
/// frees parameters (a removal, or a swap for a simpler effect) passes where the validation
/// record does not pay for them. Removing a redundant effect raises the validation error by
/// a hair (1.5·10⁻⁶ for an offset beside asymmetry at the floor), and "no worse at all" kept
/// it.
fn validates_within(
    m: &Model,
    validation: Option<&Prepared>,
    before: Option<Score>,
    slack: usize,
) -> bool {
    match (validation, before) {
        (Some(v), Some(b)) => {
            let n = v.len() as f64;
            let price = PENALTY * slack as f64 * n.ln() / n;
            2.0 * (score(m, v).rms / b.rms).ln() <= price
        }
        _ => true,
    }
}

/// The steps taken so far, each reported to the observer as it is taken.
struct Steps<'a> {
    list: Vec<AutoStep>,
    on_step: &'a mut dyn FnMut(&AutoStep),
}

impl Steps<'_> {
    fn push(&mut self, s: AutoStep) {
        (self.on_step)(&s);
        self.list.push(s);
    }
}

/// Weight of the per-parameter penalty ln n in `--auto`'s model comparisons: twice BIC's.
/// The residual of a closed-loop record is not white (Ljung–Box rejects even at the noise
/// floor), so n overstates the independent samples and plain BIC lets an extra column buy a
/// few units of RSS with structure that is not a physical effect (asymmetry's second column
/// where offset + Coulomb is the truth).
const PENALTY: f64 = 2.0;

/// Parameters a fitted effect spends: its amplitudes plus a searched shape (ripple period,
/// Stribeck velocity, dead-zone width, backlash width, quantum).
fn spent_params(kind: EffectKind, df: usize) -> usize {
    df + usize::from(kind.fit_traits().searched_shape)
}

/// Parameters a candidate would spend ([`spent_params`]).
fn spent(c: &diagnose::Candidate) -> usize {
    spent_params(c.effect, c.df)
}

/// The diagnosis's candidate for its verdict `verdict`.
fn verdict_candidate(
    d: &Diagnosis,
    verdict: EffectKind,
) -> Result<&diagnose::Candidate, fit::FitError> {
    d.candidates
        .iter()
        .find(|c| c.effect == verdict)
        .ok_or(fit::FitError::NonFinite)
}

/// Fraction of the verdict's error reduction at which a candidate that is not significant at
/// its grid shape still competes in [`choose`].
const CLOSE_ERR: f64 = 0.5;

/// Which significant candidates `--auto` may add, best first: the diagnosis ranks by the
/// error reduction at a grid shape, without shape refinement and without charging for
/// parameters. Between the leading significant candidates (at most three), each is added and
/// fully refitted, and they are ordered by the BIC, n·ln(RSS/n) + k·ln n, they buy per
/// parameter — the one-column effect first when two explain the residual comparably
/// (gravity vs ripple, Coulomb vs asymmetry). With a validation record `--auto` takes the one
/// that lowers the validation error most per parameter ([`best_validating`]).
///
/// A candidate is taken only if its refitted model also has a lower BIC than the current one
/// ([`bic`]): significance is judged at the candidate's grid shape against a plain
/// least-squares projection, but the step adds a fully refitted effect, and refitting (new
/// shapes, errors-in-variables compensation of the motion columns) can leave the model worse
/// than before (a backlash significant at its grid shape can raise the RMS once refitted).
/// Empty when none of them fits within its physical range with a lower BIC than the model's.
pub(super) fn choose(
    model: &Model,
    p: &Prepared,
    d: &Diagnosis,
    verdict: EffectKind,
) -> Result<Vec<(diagnose::Candidate, Model)>, fit::FitError> {
    rank(model, p, &offered(p, d, verdict)?)
}

/// The candidates [`choose`] weighs: the verdict and at most two alternatives.
fn offered<'a>(
    p: &Prepared,
    d: &'a Diagnosis,
    verdict: EffectKind,
) -> Result<Vec<&'a diagnose::Candidate>, fit::FitError> {
    let top = verdict_candidate(d, verdict)?;
    // Only simpler (or equally simple) alternatives may displace the verdict: BIC's penalty
    // is too light to stop a flexible, input-based fingerprint from fitting what two true
    // effects leave together.
    // A candidate that missed significance only at its grid shape competes too when it came
    // close to the verdict's error reduction: the grid is coarse for a dynamic fingerprint
    // (a transmission mode between grid frequencies and ratios explains a few percent there,
    // and half the residual once refined), so the refitted comparison is the fair one.
    // A shape the record does not resolve (a transmission mode above its bandwidth, whose
    // command-form column is ≈ u⁽²⁾/ω² and fits the input's own noise) is never a verdict,
    // and does not compete here either.
    let traj = p.trajectory();
    let close = |c: &diagnose::Candidate| {
        c.err >= CLOSE_ERR * top.err && sim_plant::effects::resolved(c.effect, &traj, &c.shape)
    };
    let mut pool: Vec<&diagnose::Candidate> = vec![top];
    pool.extend(
        d.candidates
            .iter()
            .filter(|c| {
                (c.significant || close(c)) && c.effect != verdict && spent(c) <= spent(top)
            })
            .take(2),
    );
    Ok(pool)
}

/// The significant candidates [`choose`] did not offer (at most three, in the diagnosis's
/// order), ranked as [`choose`] ranks: what `--auto` tries when the validation record has
/// refused every candidate [`choose`] offered, or none of them refitted within its physical
/// range. An offset that stands in for gravity over a short travel is the verdict there, and
/// refused where the joint stands elsewhere; the gravity behind it then gets its turn, under
/// the same validation test. A dead band that spans Coulomb friction and an offset at once
/// can be the verdict, with the offset and gravity offered beside it, while Coulomb, further
/// down, is the step that validates.
pub(super) fn the_rest(
    model: &Model,
    p: &Prepared,
    d: &Diagnosis,
    verdict: EffectKind,
) -> Result<Vec<(diagnose::Candidate, Model)>, fit::FitError> {
    let offered: Vec<EffectKind> = offered(p, d, verdict)?.iter().map(|c| c.effect).collect();
    let traj = p.trajectory();
    let pool: Vec<&diagnose::Candidate> = d
        .candidates
        .iter()
        .filter(|c| {
            c.significant
                && !offered.contains(&c.effect)
                && sim_plant::effects::resolved(c.effect, &traj, &c.shape)
        })
        .take(3)
        .collect();
    rank(model, p, &pool)
}

/// `pool`'s candidates added one at a time and refitted, those within their physical range
/// that lower the BIC, best BIC gain per parameter first.
fn rank(
    model: &Model,
    p: &Prepared,
    pool: &[&diagnose::Candidate],
) -> Result<Vec<(diagnose::Candidate, Model)>, fit::FitError> {
    let current = bic(model, p);
    // Each candidate's full refit is independent of the others' (and deterministic), so they
    // run on the worker pool; the results are then taken in pool order, exactly as one
    // after the other.
    let first_new = model.effects.len();
    let refits: Vec<_> = pool
        .par_iter()
        .map(|c| {
            let mut m = model.clone();
            m.add(c.effect, c.shape.clone());
            if !coherent(&m) {
                return None;
            }
            Some(refit_added(&mut m, p, first_new).map(|()| m))
        })
        .collect();
    // The candidate that buys the most BIC per parameter it spends: greedy selection under
    // a parameter budget. A one-parameter offset that explains nearly what a two-parameter
    // asymmetry does goes first; the richer effect must then earn its second parameter at
    // the next step.
    let mut ranked: Vec<(f64, diagnose::Candidate, Model)> = Vec::new();
    for (&c, refit) in pool.iter().zip(refits) {
        let Some(refit) = refit else {
            continue;
        };
        let m = refit?;
        if m.physical().is_err() {
            // e.g. a quantiser gain fitted above 1: not an explanation the simulator can hold
            continue;
        }
        let gain = (current - bic(&m, p)) / spent(c).max(1) as f64;
        // (NaN: not an improvement)
        if gain.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        ranked.push((gain, c.clone(), m));
    }
    // Best gain first; a tie keeps pool order (the verdict first).
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    Ok(ranked.into_iter().map(|(_, c, m)| (c, m)).collect())
}

/// Whether `m` is a model `--auto` may hold: stribeck is the excess of stiction *above* a
/// Coulomb level, so it needs the Coulomb term. Alone, its stick hold and a slow decay stand
/// in for Coulomb friction on the estimation record (a joint with plain Coulomb friction
/// sticks too) and beat it on BIC, while the decaying curve mispredicts faster motion.
fn coherent(m: &Model) -> bool {
    m.effects
        .iter()
        .all(|e| e.kind.fit_traits().requires.iter().all(|&r| m.has(r)))
}

/// BIC decrease a closing swap must achieve (2: "positive evidence" on Kass & Raftery's scale).
const SWAP_MARGIN: f64 = 2.0;

/// BIC of a fitted model on `p`: n·ln(RSS/n) + k·ln n, k = inertia + every effect's
/// [`spent_params`].
pub(super) fn bic(m: &Model, p: &Prepared) -> f64 {
    let n = p.len() as f64;
    let rss: f64 = residual::equation_error(m, p)
        .residual
        .iter()
        .map(|v| v * v)
        .sum();
    n * (rss / n).max(1e-300).ln() + PENALTY * model_params(m) as f64 * n.ln()
}

/// Parameters a model spends: the inertia and every effect's [`spent_params`].
fn model_params(m: &Model) -> usize {
    1 + m
        .effects
        .iter()
        .map(|e| spent_params(e.kind, e.params.len()))
        .sum::<usize>()
}

/// Whether a fitted `new` effect contains `old` as a special case (a ripple of period 2π is
/// gravity), so that replacing `old` by `new` is a nested comparison BIC can judge.
fn nests(new: EffectKind, old: EffectKind) -> bool {
    new.fit_traits().nests.contains(&old)
}

/// The closing swap pass of `--auto`: greedy addition can take an effect whose columns span
/// two true ones at once (asymmetry's positive-direction friction = offset + Coulomb; an
/// input-based dead zone), and the true ones then add nothing new. With a validation record a
/// move must not cost it more than the parameters the move frees are worth
/// ([`validates_within`]), and a removal that passes that test is a candidate whatever the
/// estimation criterion says. Moves, each judged by BIC against the current model, the best
/// one taken, repeated while one improves (at most three):
/// remove an added effect; replace it by another candidate that was significant at some step
/// and spends no more parameters (or nests it); replace it by two such candidates spending no
/// more parameters together. Returns the (added, removed) names of each move (added `None`:
/// a removal).
pub(super) fn swap_pass(
    model: &mut Model,
    p: &Prepared,
    start_len: usize,
    seen: &[diagnose::Candidate],
    validation: Option<&Prepared>,
    val_before: Option<Score>,
) -> Result<Vec<(Option<String>, String)>, fit::FitError> {
    let mut moves = Vec::new();
    // Effects a move took out may not come back in a later move: refitting re-searches shapes,
    // so "undo" can look better than the model it came from and the pass would oscillate.
    let mut taken_out: Vec<EffectKind> = Vec::new();
    // What the model held when `val_before` was scored.
    let held = model_params(model);
    for _ in 0..3 {
        // A move must lower BIC by a margin: two models that span the same columns (Coulomb +
        // asymmetry vs offset + asymmetry) tie up to rounding, and trading a physical effect
        // for its equivalent on a rounding difference only confuses the reader.
        let current = bic(model, p) - SWAP_MARGIN;
        let mut best: Option<(f64, Model, Option<String>, String)> = None;
        let mut consider = |m: Model, added: Option<String>, replaced: String| {
            // A move may cost the validation record what the parameters it frees were worth
            // there (a removal, or a swap for a simpler effect); one that frees none must not
            // worsen it.
            let slack = held.saturating_sub(model_params(&m));
            if m.physical().is_err()
                || !coherent(&m)
                || !validates_within(&m, validation, val_before, slack)
            {
                return;
            }
            // With a validation record an effect stays only while it earns its place there:
            // a removal that the validation record does not pay for is taken even where the
            // estimation record's criterion keeps the effect (it fitted the estimation
            // record's own detail, a Coulomb term beside asymmetry through a stick).
            let earned_on_validation = added.is_none() && validation.is_some();
            let b = bic(&m, p);
            if (b < current || earned_on_validation) && best.as_ref().is_none_or(|x| b < x.0) {
                best = Some((b, m, added, replaced));
            }
        };
        // The moves to try, in order: each added effect removed, or replaced by one or two
        // fresh candidates that spend no more parameters.
        // (Each trial searches only the shapes of what it adds, after the model's others.)
        let first_new = model.effects.len() - 1;
        let mut trials: Vec<(Model, usize, Option<String>, String)> = Vec::new();
        for i in start_len..model.effects.len() {
            let old = &model.effects[i];
            let (old_kind, old_spent) = (old.kind, spent_params(old.kind, old.params.len()));
            let mut base = model.clone();
            base.remove(i);
            trials.push((base.clone(), first_new, None, old_kind.name().into()));
            let fresh: Vec<(&diagnose::Candidate, EffectKind)> = seen
                .iter()
                .map(|c| (c, c.effect))
                .filter(|(_, k)| !model.has(*k) && !taken_out.contains(k))
                .collect();
            for (a, ka) in &fresh {
                let sa = spent_params(*ka, a.df);
                if (sa > old_spent || !a.significant) && !nests(*ka, old_kind) {
                    continue;
                }
                let mut m = base.clone();
                m.add(*ka, a.shape.clone());
                trials.push((
                    m.clone(),
                    first_new,
                    Some(a.effect.name().into()),
                    old_kind.name().into(),
                ));
                // Dry friction for dry friction (asymmetry's step for Coulomb's sign): also at
                // the sign shape the model had, unsearched. The two span the same sliding
                // torque with an offset beside them, and a search of the newcomer's
                // reversal on the estimation record alone can validate worse than the shape
                // the model already earned there.
                if let Some(kept) = sign_shape_of(old, a) {
                    if let Some(e) = m.effects.last_mut() {
                        e.shape = kept;
                    }
                    let searched_none = m.effects.len();
                    trials.push((
                        m,
                        searched_none,
                        Some(a.effect.name().into()),
                        old_kind.name().into(),
                    ));
                }
                for (b, kb) in &fresh {
                    if kb <= ka || !b.significant || sa + spent_params(*kb, b.df) > old_spent {
                        continue;
                    }
                    let mut m = base.clone();
                    m.add(*ka, a.shape.clone());
                    m.add(*kb, b.shape.clone());
                    trials.push((
                        m,
                        first_new,
                        Some(format!("{} + {}", a.effect, b.effect)),
                        old_kind.name().into(),
                    ));
                }
            }
        }
        // Their full refits are independent and deterministic: on the worker pool, the
        // results collected in the order above (the same choice as one after the other).
        let refits: Vec<_> = trials
            .par_iter()
            .map(|(m, from, _, _)| {
                let mut m = m.clone();
                refit_added(&mut m, p, *from).map(|()| m)
            })
            .collect();
        for (refit, (_, _, added, replaced)) in refits.into_iter().zip(trials) {
            consider(refit?, added, replaced);
        }
        match best {
            Some((_, m, added, replaced)) => {
                taken_out.extend(
                    EffectKind::ALL
                        .into_iter()
                        .filter(|&k| model.has(k) && !m.has(k)),
                );
                *model = m;
                moves.push((added, replaced));
            }
            None => break,
        }
    }
    Ok(moves)
}

/// `old`'s shape for a `new` effect in its place, where both are dry friction whose columns
/// switch with the sign of the velocity (Coulomb, asymmetry): the reversal shape (ε, lead,
/// stick window) carries over.
fn sign_shape_of(old: &EffectEntry, new: &diagnose::Candidate) -> Option<Shape> {
    let signed = |k: EffectKind| k.fit_traits().sign_shaped;
    (signed(old.kind) && signed(new.effect) && old.kind != new.effect).then(|| Shape {
        sign_epsilon: old.shape.sign_epsilon,
        sign_time: old.shape.sign_time,
        sign_lead: old.shape.sign_lead,
        stick_velocity: old.shape.stick_velocity,
        ..new.shape.clone()
    })
}

/// The delay probe of `--auto`, once the diagnosis finds nothing more. The diagnosis tests a
/// delay with a column built from the motion-based instrument (its only safe choice against
/// the input's own noise), which has little power for a delay of a few samples behind a
/// stronger effect. The refit's τ search on the measured input (see `search_shapes`) has
/// no such bias — shifting white noise does not change its sum of squares — so the delay is
/// added if that search removes at least `min_err` of the residual and `min_rho` × the noise
/// floor of RMS, and lowers the (doubled-penalty) BIC.
fn delay_probe(
    model: &Model,
    p: &Prepared,
    opts: &Options,
) -> Result<Option<(Model, String)>, fit::FitError> {
    if model.has(EffectKind::Delay) {
        return Ok(None);
    }
    let rss = |m: &Model| -> f64 {
        residual::equation_error(m, p)
            .residual
            .iter()
            .map(|v| v * v)
            .sum()
    };
    let r0 = rss(model);
    let mut m = model.clone();
    m.add(
        EffectKind::Delay,
        Shape {
            smoothing: 1,
            ..Shape::default()
        },
    );
    refit_all(&mut m, p)?;
    let r1 = rss(&m);
    let n = p.len() as f64;
    let err = (r0 - r1) / r0.max(1e-300);
    let explained = ((r0 - r1).max(0.0) / n).sqrt();
    let tau = m.effects.last().map_or(0.0, |e| e.shape.delay);
    // Like every step of `--auto`, only a model the simulator accepts (the refit with the
    // delay can push another amplitude out of its range).
    if tau > 0.0
        && m.physical().is_ok()
        && err >= opts.min_err
        && explained >= opts.min_rho * p.practical_floor(r0)
        && bic(&m, p) < bic(model, p)
    {
        let text = format!(
            "add delay (τ = {:.2} ms by search on the measured input; explains {:.1} % of the residual)",
            1e3 * tau,
            100.0 * err
        );
        return Ok(Some((m, text)));
    }
    Ok(None)
}
