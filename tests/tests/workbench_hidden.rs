//! Hidden-effect trials, reduced for CI (the full ≥ 200-per-family run with the confusion
//! matrix is `cargo run --release -p jointlab-tests --bin hidden-trials`).
//!
//! Trial counts here: 3 per family at target ρ = 2 for the nine families whose rank-1 rate
//! meets the bar (offset, coulomb, asymmetry, ripple, gravity, delay, quantization:
//! rank 1 and verdict; compliance and stribeck: rank 1), the refit to the noise floor where
//! it is asserted (all of those but gravity and stribeck), 10 null trials, 3 pair
//! trials for `--auto` (coulomb + offset, gravity + asymmetry, offset + delay), and the
//! bench's former misses of the motion-form rank rule (picked seeds, said so there). Other
//! seeds are fixed and consecutive (not picked); each group allows at most the misses stated
//! in its assertion. What does NOT yet meet the bar (the refit of stribeck; backlash refit
//! from the motor encoder alone) is measured by the bench binary and listed in
//! docs/workbench.md — it is not asserted here. Backlash *with a load-side encoder* meets
//! it (`hidden-trials 40 --family backlash --load-encoder`) and is asserted on 3 trials,
//! with 3 compliance and 5 null trials recorded the same way (a spring's or a rigid joint's measured deflection is not a gap).
//!
//! Run in release (about 30–60 s on 2 cores):
//! `cargo test --release -p jointlab-tests --test workbench_hidden`

use jointlab_tests::hidden::{run, run_with, Family, Outcome, TrialOptions};

fn trials(families: &[Family], seeds: std::ops::Range<u64>, rho: f64) -> Vec<Outcome> {
    seeds.filter_map(|s| run(s, families, rho)).collect()
}

#[test]
fn single_effects_rank_first_and_refit_to_the_noise_floor() {
    let fams = [
        Family::Offset,
        Family::Coulomb,
        Family::Asymmetry,
        Family::Ripple,
        Family::Gravity,
        Family::Delay,
        Family::Compliance,
        Family::Quantization,
        Family::Stribeck,
    ];
    for (i, f) in fams.iter().enumerate() {
        let base = 50_000 + 100 * i as u64;
        let out = trials(&[*f], base..base + 3, 2.0);
        assert!(out.len() >= 2, "{}: too many unstable draws", f.name());
        for o in &out {
            println!(
                "{:<10} ρ = {:.2}  top = {:?}  verdict = {:?}  val/floor = {:.3}",
                f.name(),
                o.rho,
                o.top,
                o.verdict,
                o.val_ratio
            );
            assert!(
                o.rho >= 1.0,
                "{}: generator missed the strength target (ρ = {})",
                f.name(),
                o.rho
            );
        }
        // Compliance: rank 1 only. A transmission mode above the record's bandwidth (2× the
        // differentiator's cut-off) is ranked but not a verdict — the record does not identify
        // the mode — and this group's compliance draws put it there in two of three trials.
        // Stribeck: rank 1 only too (its verdict rate, 92.4 % in the bench, is below the
        // rank-1 bar; two of these three draws rank it first without significance).
        let verdict_needed = !matches!(f, Family::Compliance | Family::Stribeck);
        let hits = out
            .iter()
            .filter(|o| o.rank1_ok() && (!verdict_needed || o.verdict.as_deref() == Some(f.name())))
            .count();
        assert!(
            hits == out.len(),
            "{}: rank-1 verdict in {hits}/{}",
            f.name(),
            out.len()
        );
        if !matches!(f, Family::Gravity | Family::Stribeck) {
            // Refit-to-noise-floor, asserted for the families where the 200-per-family bench
            // meets it (docs/workbench.md, *Status on main*; compliance at 96.5 % since its
            // noise-aware mode search). One miss allowed per family. Not Stribeck (86.4 %: a
            // static friction form against the referee's LuGre bristles). Not gravity: its
            // estimation refit reaches the floor, but on these seeds the validation record
            // covers angles the estimation record did not, and a short-travel sin/cos fit
            // extrapolates (2 of 3 above 1.1·floor here; 99.2 % over the bench's draws).
            let fit_ok = out.iter().filter(|o| o.val_ratio <= 1.1).count();
            assert!(
                fit_ok + 1 >= out.len(),
                "{}: validation RMS ≤ 1.1·floor in {fit_ok}/{}",
                f.name(),
                out.len()
            );
        }
    }
}

/// With a load-side encoder (`TrialOptions::load_encoder`) backlash is measured, not
/// inferred: rank 1, the verdict and the refit to the noise floor on every backlash trial;
/// on compliance trials the measured deflection is no gap and backlash is not a candidate
/// (rank 1 stays compliance); null trials stay quiet. Bench: 31/31 backlash rank 1 and refit
/// (median val/floor 0.86), compliance rank 1 22/24 as without the load encoder, nulls 2/117.
#[test]
fn load_encoder_resolves_backlash() {
    let opts = TrialOptions { load_encoder: true };
    let runs = |f: &[Family], seeds: std::ops::Range<u64>, rho: f64| -> Vec<Outcome> {
        seeds.filter_map(|s| run_with(s, f, rho, opts)).collect()
    };
    let out = runs(&[Family::Backlash], 50_800..50_803, 2.0);
    assert!(out.len() >= 2, "backlash: too many unstable draws");
    for o in &out {
        println!(
            "backlash + load encoder: ρ = {:.2}  top = {:?}  verdict = {:?}  val/floor = {:.3}",
            o.rho, o.top, o.verdict, o.val_ratio
        );
        assert!(
            o.rho >= 1.0,
            "generator missed the strength target (ρ = {})",
            o.rho
        );
        assert!(
            o.rank1_ok() && o.verdict.as_deref() == Some("backlash"),
            "{o:?}"
        );
        assert!(o.val_ratio <= 1.1, "refit: val/floor {}", o.val_ratio);
    }
    let out = runs(&[Family::Compliance], 50_900..50_903, 2.0);
    assert!(out.len() >= 2, "compliance: too many unstable draws");
    for o in &out {
        println!(
            "compliance + load encoder: ρ = {:.2}  top = {:?}",
            o.rho, o.top
        );
        assert_ne!(o.top.as_deref(), Some("backlash"), "{o:?}");
    }
    let out = runs(&[], 70_100..70_105, 1.0);
    let alarms: Vec<_> = out
        .iter()
        .filter(|o| !o.null_ok())
        .map(|o| o.verdict.clone())
        .collect();
    println!(
        "nulls + load encoder: {} run, false alarms {alarms:?}",
        out.len()
    );
    assert!(
        out.len() >= 4 && alarms.len() <= 1,
        "false alarms: {alarms:?}"
    );
}

#[test]
fn null_trials_stay_quiet() {
    let out = trials(&[], 70_000..70_010, 1.0);
    assert!(out.len() >= 8);
    let alarms: Vec<_> = out
        .iter()
        .filter(|o| !o.null_ok())
        .map(|o| o.verdict.clone())
        .collect();
    println!("null trials: {} run, false alarms {:?}", out.len(), alarms);
    assert!(alarms.len() <= 1, "false alarms: {alarms:?}");
}

#[test]
fn auto_finds_two_hidden_effects() {
    let mut out = trials(&[Family::Coulomb, Family::Offset], 90_000..90_001, 2.0);
    out.extend(trials(
        &[Family::Gravity, Family::Asymmetry],
        90_001..90_002,
        2.0,
    ));
    out.extend(trials(
        &[Family::Offset, Family::Delay],
        90_002..90_003,
        2.0,
    ));
    assert_eq!(out.len(), 3);
    for o in &out {
        println!(
            "hidden {:?} → --auto added {:?}",
            o.families.iter().map(|f| f.name()).collect::<Vec<_>>(),
            o.auto_added
        );
        assert!(
            o.pair_ok(),
            "hidden {:?}, added {:?}",
            o.families,
            o.auto_added
        );
    }
}

#[test]
fn auto_adds_nothing_to_null_records() {
    use hil_host::workbench::diagnose::Options;
    use hil_host::workbench::refine;
    use hil_host::workbench::residual::Prepared;
    use jointlab_tests::hidden::{cutoff, generate, start_model};
    // `--auto` goes beyond the diagnosis (BIC choice, delay probe, swap pass): on records
    // with no hidden effect it must still add nothing. Fixed consecutive seeds; one miss allowed.
    let mut added = Vec::new();
    let mut runs = 0;
    for seed in 71_000..71_006 {
        let Some(t) = generate(seed, &[], 1.0) else {
            continue;
        };
        runs += 1;
        let p = Prepared::new(&t.est, cutoff());
        let mut m = start_model(&[]);
        let run = refine::auto(&mut m, &p, None, &Options::default(), 6).expect("auto");
        let names: Vec<String> = run.steps.iter().filter_map(|s| s.added.clone()).collect();
        println!("null seed {seed}: --auto added {names:?}");
        if !names.is_empty() {
            added.push(names);
        }
    }
    assert!(runs >= 5, "too many unstable draws");
    assert!(
        added.len() <= 1,
        "--auto added effects to null records: {added:?}"
    );
}

#[test]
fn speed_record_is_one_continuous_joint() {
    use hil_host::workbench::diagnose::{diagnose, Options};
    use hil_host::workbench::model::Model;
    use hil_host::workbench::refine;
    use hil_host::workbench::residual::Prepared;
    use jointlab_tests::hidden::{cutoff, long_record, N};
    // `diagnose-speed` times the workbench on this record; the time only means something if
    // the diagnosis is the one a user would get. Joins must not jump in position (an earlier
    // version offset each segment from the *first* one's end), all clocks and columns line up,
    // and the diagnosis finds the hidden Coulomb friction.
    let rec = long_record(42, 3);
    assert_eq!(rec.input.len(), 3 * N);
    assert_eq!(rec.output.len(), 3 * N);
    assert_eq!(rec.time.len(), 3 * N);
    let step = |k: usize| (rec.output[k] - rec.output[k - 1]).abs();
    let inside = (1..N).map(step).fold(0.0, f64::max);
    for j in [N, 2 * N] {
        assert!(
            step(j) <= 2.0 * inside,
            "join at {j} jumps {:.3e} rad (largest step inside a segment {inside:.3e})",
            step(j)
        );
    }
    let p = Prepared::new(&rec, cutoff());
    let mut m = Model::baseline();
    refine::refit_all(&mut m, &p).expect("fit");
    let d = diagnose(&m, &p, &Options::default());
    assert!(
        d.baseline.fit_percent > 80.0,
        "baseline fit {:.1} %: not one joint",
        d.baseline.fit_percent
    );
    assert_eq!(d.verdict.add.as_deref(), Some("coulomb"), "{}", d.to_text());
}

#[test]
fn an_unresolved_mode_outranks_the_verdict_only_if_its_motion_form_agrees() {
    // Regression seeds, picked: the 200-per-family bench's misses this rule fixed. On these
    // Stribeck trials an edge-of-band compliance mode ranked above the significant Stribeck
    // verdict by fitting the recorded input's own noise (its command-form column carries it,
    // as the residual does); its motion form, which carries none of it, explains ≈ 0 %. On
    // these compliance trials (modes above the band, a spurious significant dead zone) the
    // motion form explains as much as the command form and the mode keeps rank 1. (Compliance
    // 1 500 145 was the second such seed; its effect-free twin diverges, so it is no longer a
    // trial — `hidden::generate` returns `None` for it.)
    assert!(run(1_500_145, &[Family::Compliance], 2.0).is_none());
    for (family, seed, rho) in [
        (Family::Stribeck, 1_300_077, 2.0),
        (Family::Stribeck, 1_300_097, 2.0),
        (Family::Compliance, 1_500_052, 1.0),
    ] {
        let o = run(seed, &[family], rho).expect("a stable draw");
        println!(
            "{} seed {seed}: top {:?}, verdict {:?}",
            family.name(),
            o.top,
            o.verdict
        );
        assert_eq!(
            o.top.as_deref(),
            Some(family.name()),
            "{} seed {seed}: rank 1",
            family.name()
        );
    }
}

/// `fit --add stribeck` refits from four starts of its searches (everything searched; the
/// dry-friction sign lead held at 0; and with δ held at 1, at 2) and keeps the lowest
/// estimation error (`refine::refit_all`). Picked seeds: two of the 200-per-family bench's
/// worst Stribeck refits from one start — seed 1 300 098 stopped at 10.9× the floor in-sample
/// and 22.9× on validation, 1 300 090 at 2.16× on validation; now 1.19× and 1.08×. Fails
/// with the single start.
#[test]
fn stribeck_refit_keeps_the_best_of_several_starts() {
    for (seed, rho, bound) in [(1_300_098, 4.0, 1.3), (1_300_090, 4.0, 1.1)] {
        let o = run(seed, &[Family::Stribeck], rho).expect("stable draw");
        println!(
            "stribeck seed {seed}: ρ {:.2}, val/floor {:.3}",
            o.rho, o.val_ratio
        );
        assert!(
            o.val_ratio <= bound,
            "stribeck seed {seed}: validation RMS {:.3}× the floor (bound {bound})",
            o.val_ratio
        );
    }
}
