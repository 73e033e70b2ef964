//! The three parts agree about one joint: the HIL lab runs the card against a thesis preset
//! (identification chirp, colocated PD), and the workbench, given only the recording, names
//! the plant's friction and fits the preset's Coulomb level back out of it.
//!
//! The plant is the 3-mass WHOI cable reducer with asymmetric Coulomb friction, stiction and a
//! quantised encoder; the workbench fits a rigid motor-side axis. So the test also shows that
//! the default baseline's rigid view holds well below the transmission mode (20–25 Hz).

use clap::Parser;
use hil_host::cli::{run, Cli};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;
use sim_plant::effects::EffectKind;

#[test]
fn a_hil_recording_names_its_friction_and_the_fit_recovers_the_preset() {
    let dir = std::env::temp_dir().join(format!("jointlab-wb-hil-{}", std::process::id()));
    let preset = "whoi-cable-30";
    // The HIL recording loads as it is: motor torque command in, motor encoder out.
    let p = Prepared::new(&jointlab_tests::hil_identify_record(&dir, preset), None);
    let rec = dir.join(format!("demo-identify-{preset}.csv"));
    let mut model = Model::baseline();
    refine::refit_all(&mut model, &p).unwrap();
    let dg = diagnose(&model, &p, &Options::default());
    assert_eq!(
        dg.verdict.add,
        Some(sim_plant::effects::EffectKind::Coulomb),
        "{}",
        dg.to_text()
    );

    // Truth, referred to the motor: the preset's output-referred Coulomb levels over N.
    let truth = sim_plant::presets::preset(preset).unwrap();
    let n = truth.plant.gear_ratio.value;
    let c = truth.effects.coulomb.as_ref().unwrap().torque.value;
    let extra = truth
        .effects
        .asymmetry
        .as_ref()
        .map_or(0.0, |a| a.coulomb_extra.value);
    // `coulomb` is the negative-direction level, `asymmetry` adds the positive one's excess;
    // a symmetric fit lands between the two.
    let (lo, hi) = (c.min(c + extra) / n, c.max(c + extra) / n);

    let fitted = dir.join("fitted.toml");
    run(Cli::parse_from([
        "hil-host",
        "fit",
        rec.to_str().unwrap(),
        "--input",
        "torque_cmd_Nm",
        "--output",
        "motor_pos_rad",
        "--add",
        "coulomb",
        "--save-model",
        fitted.to_str().unwrap(),
    ]))
    .unwrap();
    let m = Model::load(&fitted).unwrap();
    let coulomb = &m
        .effects
        .iter()
        .find(|e| e.kind == EffectKind::Coulomb)
        .unwrap()
        .params[0];
    let (fc, sigma) = (coulomb.value, coulomb.sigma.unwrap());
    // Within 5 % of the range or its own 2σ, whichever is wider: the plant also has stiction
    // (breakaway 1.8× Coulomb), which lifts a Coulomb-only fit by an amount that depends on
    // how much slow sliding the rest band holds — the fit's uncertainty covers that.
    let tol = |x: f64| (0.05 * x).max(2.0 * sigma);
    assert!(
        fc > lo - tol(lo) && fc < hi + tol(hi),
        "fitted Coulomb {fc} ± {sigma} N·m (motor) outside the preset's [{lo}, {hi}]"
    );
    // The rigid inertia, motor-referred: I1 + (I_mid + I2)/N², within 5 % (the quantised
    // encoder's noise in the acceleration is compensated, see `fit::least_squares_compensated`).
    let j = truth.motor.inertia.value
        + (truth.plant.middle_inertia.value + truth.plant.output_inertia.value) / (n * n);
    let rel = (m.inertia.value - j).abs() / j;
    assert!(rel < 0.05, "inertia {} vs {j} ({rel})", m.inertia.value);

    // The default band follows the card's 2304-count encoder (about 10 Hz, modes searched to
    // twice that): the cable's mode sits at its edge, and the diagnosis says which band
    // reaches it.
    assert!(
        dg.notes
            .iter()
            .any(|n| n.starts_with("compliance: best shape at the edge")
                && n.contains("--cutoff 100")),
        "{:?}",
        dg.notes
    );
    // `--auto` in that band (the card's own observer band): the cable's compliant stages are
    // the largest thing a rigid friction model leaves after Coulomb friction; at the grid
    // shape a backlash explains about as much, but once refitted the transmission mode —
    // with a physical split, J2/J1 > 0 — explains a third of the residual and wins `choose`.
    let band = controller::card::config::OBSERVER_BANDWIDTH_HZ;
    let p = Prepared::new(
        &jointlab_tests::hil_identify_record(&dir, preset),
        Some(band),
    );
    let mut auto_model = Model::baseline();
    let run = refine::auto(&mut auto_model, &p, None, &Options::default(), 6).unwrap();
    let added: Vec<_> = run.steps.iter().filter_map(|s| s.added.clone()).collect();
    let step = run
        .steps
        .iter()
        .position(|s| {
            s.added
                .as_deref()
                .is_some_and(|a| a.starts_with("compliance"))
        })
        .unwrap_or_else(|| panic!("--auto added {added:?}"));
    let gain = run.steps[step].score.fit_percent - run.steps[step - 1].score.fit_percent;
    assert!(gain > 5.0, "compliance step +{gain} % ({added:?})");
    let alpha = auto_model
        .effects
        .iter()
        .find(|e| e.kind == EffectKind::Compliance)
        .map(|e| e.params[0].value);
    assert!(
        alpha.is_some_and(|a| a < 0.0),
        "compliance −J2/J1 = {alpha:?}"
    );
    // Each addition lowers the error it was taken to lower: a full refit from the grid shape
    // that settles in a worse optimum is not the step taken.
    for w in run.steps.windows(2) {
        if w[1].replaced.is_none() {
            assert!(
                w[1].score.rms <= w[0].score.rms,
                "step {} ({:?}) raised the RMS {} → {} ({added:?})",
                w[1].step,
                w[1].added,
                w[0].score.rms,
                w[1].score.rms
            );
        }
    }
    let last = run.steps.last().unwrap().score;
    assert!(
        last.fit_percent > 90.0,
        "--auto ends at {} % ({added:?})",
        last.fit_percent
    );
    // What `--save-model` writes scores what the table printed.
    let saved = dir.join("auto.toml");
    auto_model.save(&saved).unwrap();
    let back = refine::score(&Model::load(&saved).unwrap(), &p);
    assert!(
        (back.rms - last.rms).abs() <= 1e-6 * last.rms,
        "saved model scores {} vs {}",
        back.rms,
        last.rms
    );
    let _ = std::fs::remove_dir_all(&dir);
}
