//! Compensation on the card, measured by the lab: the plant's own friction (its preset, not a
//! workbench fit) compensated halves the work a stiffness emulation loses; a gains file sets
//! the laws the scenario does not; `demo --scenario compensate` runs the whole loop and meets
//! the figures of the thesis's compensation on three transmissions. The truth each figure is
//! held against is the preset's own table.

mod common;

use common::{dir, hil, ok, text};
use controller::proto::params as p;
use hil_host::lab::compensate::Compensation;
use hil_host::lab::gains::GainsFile;
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};

fn loop_area(preset: &str, compensate: bool, under: f64) -> (f64, f64) {
    let m = sim_plant::presets::preset(preset).unwrap();
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &m).unwrap();
    if compensate {
        let mut c = Compensation::from_model(&m, &sc.scale, under).unwrap();
        c.within_damping(&sc.gains);
        sc.gains.friction = c.friction;
        sc.gains.feedforward = c.feedforward;
    }
    let mut lab = Lab::new(&m, sc, &LabOptions::default()).unwrap();
    let csv = dir("compensate", &format!("{preset}-{compensate}-{under}")).join("run.csv");
    lab.recorder.write_csv(&csv).unwrap();
    lab.run(|_, _| {}).unwrap();
    let s = lab.summary().unwrap();
    (
        s.get("loop area (work lost)").unwrap(),
        s.get("achieved / desired").unwrap(),
    )
}

/// The harmonic drive's friction (Coulomb 5–5.5 N·m and 12 N·m·s/rad at the output, thesis
/// Table 4.1) compensated with the preset's own numbers at u = 0.8: the stiffness loop's area
/// falls to 60 % or less (measured: 7.64 → 3.80 J), and the emulated spring stays within
/// 20 % of the one asked for.
#[test]
fn the_plants_own_friction_compensated_shrinks_the_stiffness_loop() {
    let (before, _) = loop_area("harmonic-drive-60", false, 0.8);
    let (after, k) = loop_area("harmonic-drive-60", true, 0.8);
    assert!(after <= 0.6 * before, "loop area {before} → {after} J");
    assert!((0.8..1.2).contains(&k), "achieved / desired stiffness {k}");
}

#[test]
fn a_gains_file_sets_the_laws_and_refuses_a_misspelt_key() {
    let d = dir("compensate", "gains");
    let f = d.join("g.toml");
    std::fs::write(
        &f,
        "force_kp = 0.01\nforce_ki = 0.1\ninput_damping = 2.0\nkm = 0.3\n\
         [friction]\ncoulomb_pos = 5.0\ncoulomb_neg = 5.5\nramp_velocity = 0.05\n\
         [feedforward]\noffset = 1.0\n[feedforward.ripple]\nperiod_counts = 1152\n\
         table = [0.0, 1.0, 0.0, -1.0]\n",
    )
    .unwrap();
    let m = sim_plant::presets::preset("harmonic-drive-60").unwrap();
    let mut sc = Scenario::new(ScenarioKind::Step, &m).unwrap();
    GainsFile::load(&f).unwrap().apply(&mut sc.gains);
    let e = sc.gains.entries(&sc.scale, sc.mode).unwrap();
    let get = |id: u16| e.iter().find(|(i, _)| *i == id).map(|(_, v)| *v);
    // 5 N·m at the output is 5/60 N·m = 833 τLSB at the motor; 1 N·m offset 167 τLSB.
    assert_eq!(get(p::COULOMB_POS), Some(833));
    assert_eq!(get(p::TORQUE_OFFSET), Some(167));
    assert_eq!(get(p::RIPPLE_LENGTH), Some(4));
    assert_eq!(get(p::RIPPLE_TABLE + 1), Some(167));
    assert!(get(p::FORCE_KP).unwrap() > 0 && get(p::KM).unwrap() > 0);
    assert!(get(p::B1E).unwrap() > 0 && get(p::FORCE_KI).unwrap() > 0);
    assert!(e.len() <= p::STAGING_CAPACITY, "{} entries", e.len());

    std::fs::write(&f, "stifness = 3.0\n").unwrap();
    let err = GainsFile::load(&f).unwrap_err().to_string();
    assert!(err.contains("stifness") && err.contains("g.toml"), "{err}");
    std::fs::write(
        &f,
        "[feedforward.ripple]\nperiod_counts = 100\ntable = [1.0]\n",
    )
    .unwrap();
    let err = GainsFile::load(&f).unwrap_err().to_string();
    assert!(err.contains("2 to 64"), "{err}");
}

/// `demo --scenario compensate` on `preset`: its JSON and the directory it wrote.
fn compensate(preset: &str, extra: &[&str]) -> (std::process::Output, std::path::PathBuf) {
    let d = dir("compensate", &format!("demo-{preset}-{}", extra.len()));
    let o = hil()
        .args(["demo", "--scenario", "compensate", "--preset", preset])
        .args(["--json", "--out"])
        .arg(&d)
        .args(extra)
        .output()
        .unwrap();
    (o, d)
}

/// The Coulomb level of `preset`, mean of the two directions, at the motor (N·m): from the
/// preset's own table, not from anything the workbench fitted.
fn true_coulomb(preset: &str) -> f64 {
    let m = sim_plant::presets::preset(preset).unwrap();
    let c = m.effects.coulomb.as_ref().map_or(0.0, |c| c.torque.value);
    let extra = m
        .effects
        .asymmetry
        .as_ref()
        .map_or(0.0, |a| a.coulomb_extra.value);
    (c + 0.5 * extra) / m.plant.gear_ratio.value
}

/// The figures for a friction- and ripple-dominated transmission, from one run of the
/// whole loop (identify, diagnose --auto, compensate at under 0.8, the tasks twice): tracking
/// RMS and the stiffness loop's area halved or better, no limit cycle above 2 counts at the
/// hold, and the fitted Coulomb level within 10 % of the preset's.
fn the_loop_halves_the_error(preset: &str) {
    let (o, d) = compensate(preset, &[]);
    let j: serde_json::Value = serde_json::from_str(&ok(o)).unwrap();
    let fig = |when: &str, what: &str| j[when][what].as_f64().unwrap();
    let change = |what: &str| fig("after", what) / fig("before", what) - 1.0;
    assert!(change("tracking_rms_rad") <= -0.5, "{preset}: {j}");
    assert!(change("loop_area_J") <= -0.5, "{preset}: {j}");
    assert!(fig("after", "limit_cycle_counts") <= 2.0, "{preset}: {j}");
    let fitted = j["coulomb_model_Nm"].as_f64().unwrap();
    let truth = true_coulomb(preset);
    assert!(
        (fitted / truth - 1.0).abs() <= 0.1,
        "{preset}: fitted Coulomb {fitted} N·m, the preset's {truth} N·m"
    );
    for f in j["files"].as_array().unwrap() {
        assert!(std::path::Path::new(f.as_str().unwrap()).exists(), "{f}");
    }
    assert!(d.join(format!("model-{preset}.toml")).exists());
    assert!(d.join(format!("compensate-{preset}.png")).exists());
}

#[test]
fn compensate_harmonic_drive_60() {
    the_loop_halves_the_error("harmonic-drive-60");
}

#[test]
fn compensate_kamo_ball_30() {
    the_loop_halves_the_error("kamo-ball-30");
}

#[test]
fn compensate_sumitomo_59() {
    the_loop_halves_the_error("sumitomo-59");
}

/// The cycloid with backlash: friction compensated on the measured velocity at a high-gain
/// hold limit-cycles when it is compensated in full, and stays within 2 counts at 0.8 (thesis
/// §5: "slightly below").
#[test]
fn cyclo_29_limit_cycle_full_versus_under_compensated() {
    let (o, _) = compensate("cyclo-29", &[]);
    let j: serde_json::Value = serde_json::from_str(&ok(o)).unwrap();
    let hold = j["hold_limit_cycle_counts"].as_array().unwrap();
    let at = |u: f64| {
        hold.iter()
            .find(|h| h["under"].as_f64() == Some(u))
            .and_then(|h| h["counts"].as_f64())
            .unwrap()
    };
    assert!(at(0.8) <= 2.0, "{j}");
    assert!(at(1.0) > 2.0 * at(0.8).max(1.0), "{j}");
}

/// A model with twice the friction the joint has (the preset's own Coulomb level, doubled)
/// is not kept: it tracks better, but it takes more of the emulated spring's loss away than
/// friction compensated at 0.8 can, so the run says so and exits 1.
#[test]
fn a_model_with_twice_the_friction_is_refused() {
    let d = dir("compensate", "twice");
    let f = d.join("twice.toml");
    let c = 2.0 * true_coulomb("harmonic-drive-60");
    std::fs::write(
        &f,
        format!("name = \"twice\"\n[effects.coulomb]\ntorque = {c}\n"),
    )
    .unwrap();
    let (o, _) = compensate("harmonic-drive-60", &["--compensate", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let why = j["refused"].as_str().unwrap_or_default();
    assert!(why.contains("over-compensation"), "{j}");
}

/// A model the card cannot take is refused with its reason, before anything runs.
#[test]
fn compensate_refuses_an_unusable_model_and_a_bad_under() {
    let d = dir("compensate", "refuse");
    let f = d.join("m.toml");
    std::fs::write(&f, "name = \"x\"\n[effects.coulomb]\ntorque = 500.0\n").unwrap();
    let step = |extra: &[&str]| {
        hil()
            .args([
                "demo",
                "--scenario",
                "step",
                "--preset",
                "harmonic-drive-60",
            ])
            .arg("--quiet")
            .arg("--out")
            .arg(&d)
            .arg("--compensate")
            .arg(&f)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = step(&[]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("more than the motor's"), "{}", text(&o));
    let o = step(&["--under", "1.5"]);
    assert!(
        !o.status.success() && text(&o).contains("--under"),
        "{}",
        text(&o)
    );
}

/// The ripple the loop fits and compensates, against the preset's: on the harmonic drive with
/// its transmission made stiff and its ripple independent of load, the fitted amplitude is
/// within 20 % of the table's 2 N·m (at the output, 2/60 at the motor) and its phase within
/// 10°. (Through the drive's own compliance the motor sees the output's ripple amplified by
/// the transmission's dynamics, and a fit from the motor encoder measures that: about 1.45×.)
#[test]
fn the_fitted_ripple_is_the_presets_on_a_stiff_drive() {
    let mut m = sim_plant::presets::preset("harmonic-drive-60").unwrap();
    m.effects.compliance = None;
    m.effects.ripple.as_mut().unwrap().load_gain.value = 0.0;
    let truth = m.effects.ripple.clone().unwrap();
    let n = m.plant.gear_ratio.value;
    let d = dir("compensate", "ripple");
    let o = hil_host::lab::close_loop::run_all(&m, "hd-stiff", 1, 0.8, None, &d, |_| {}).unwrap();
    let fitted = jointlab_workbench::model::Model::load(&o.model_file)
        .unwrap()
        .to_sim();
    let r = fitted.effects.ripple.expect("the fit names the ripple");
    let (a_fit, a_true) = (
        r.sin.value.hypot(r.cos.value),
        truth.sin.value.hypot(truth.cos.value) / n,
    );
    assert!(
        (a_fit / a_true - 1.0).abs() <= 0.2,
        "amplitude {a_fit} vs {a_true}"
    );
    let phase = |s: f64, c: f64| c.atan2(s).to_degrees();
    let dphi = phase(r.sin.value, r.cos.value) - phase(truth.sin.value, truth.cos.value);
    assert!(dphi.abs() <= 10.0, "phase off by {dphi}°");
    // and the period is the tooth period seen at the motor: 120 per output turn at 60:1
    assert!(
        (r.period.value / (std::f64::consts::TAU / 2.0) - 1.0).abs() < 0.02,
        "{}",
        r.period.value
    );
}
