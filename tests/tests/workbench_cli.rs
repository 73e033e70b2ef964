//! Workbench interface: CSV errors name file, line and column; the CLI commands run end to
//! end on a recording and write what they promise; `diagnose --json` has the agreed shape.

use std::path::{Path, PathBuf};

use jointlab_tests::synth::PdMass;

use clap::Parser;
use hil_host::cli::{run, Cli};
use jointlab_workbench::data::{self, Columns};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("jointlab-wb-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The PD-tracked mass with its position in mm and a little noise on the logged command,
/// logged with a zero-order hold or (`mid`) in the middle of each hold.
fn synth_logged(path: &Path, mid: bool) {
    PdMass {
        position_in_mm: true,
        log_mid_hold: mid,
        logged_input_noise: 0.005,
        ..PdMass::new(8000)
    }
    .write(path, |_, _| {});
}

fn synth(path: &Path) {
    synth_logged(path, false)
}

#[test]
fn csv_errors_say_file_line_column() {
    let d = tmp("csv");
    let cols = Columns::new("u_N", "y_m");
    let cases = [
        ("missing.csv", "time_s,u_N\n0,1\n", "no column `y_m`", ":1:"),
        (
            "text.csv",
            "time_s,u_N,y_m\n0,1,2\n0.001,abc,2\n",
            "`abc` is not a number",
            ":3:",
        ),
        (
            "nan.csv",
            "time_s,u_N,y_m\n0,1,2\n0.001,1,NaN\n",
            "NaN/inf",
            ":3:",
        ),
        (
            "time.csv",
            "time_s,u_N,y_m\n0,1,2\n0.002,1,2\n0.001,1,2\n",
            "does not increase",
            ":4:",
        ),
    ];
    for (name, body, what, line) in cases {
        let mut body = body.to_string();
        // pad with good rows so only the planted defect can fail
        for k in 0..60 {
            body.push_str(&format!("{},1,2\n", 1.0 + k as f64 * 1e-3));
        }
        let p = d.join(name);
        std::fs::write(&p, body).unwrap();
        let e = data::load(&p, &cols).unwrap_err().to_string();
        assert!(e.contains(name), "{e}");
        assert!(e.contains(what), "{e}");
        assert!(e.contains(line), "{e}");
        if what != "no column `y_m`" {
            assert!(e.contains("column `"), "{e}");
        }
    }
    // Whole-record defects: a gap in time (rows dropped at line 42) and a column that never
    // changes; jitter within 3× the median interval is accepted.
    let row = |k: usize, t: f64, u: f64| format!("{t},{u},{}\n", (k as f64 * 0.1).sin());
    let mut gap = String::from("time_s,u_N,y_m\n");
    let mut flat = gap.clone();
    let mut jitter = gap.clone();
    for k in 0..100 {
        let t = k as f64 * 1e-3 + if k >= 40 { 5e-3 } else { 0.0 };
        gap.push_str(&row(k, t, (k as f64).cos()));
        flat.push_str(&row(k, k as f64 * 1e-3, 0.5));
        jitter.push_str(&row(
            k,
            (k as f64 + 0.4 * (k % 2) as f64) * 1e-3,
            (k as f64).cos(),
        ));
    }
    for (name, body, what) in [
        (
            "gap.csv",
            gap,
            "gap.csv:42: column `time_s`: the sample interval",
        ),
        ("flat.csv", flat, "column `u_N` is 0.5 on every row"),
    ] {
        let p = d.join(name);
        std::fs::write(&p, body).unwrap();
        let e = data::load(&p, &cols).unwrap_err().to_string();
        assert!(e.contains(what), "{e}");
    }
    let p = d.join("jitter.csv");
    std::fs::write(&p, jitter).unwrap();
    assert!(data::load(&p, &cols).is_ok());
}

#[test]
fn units_from_suffix() {
    let d = tmp("units");
    let p = d.join("rec.csv");
    synth(&p);
    let r = data::load(&p, &Columns::new("force_N", "pos_mm")).unwrap();
    assert_eq!(r.units.1, "m");
    assert!(
        r.output.iter().fold(0.0f64, |m, v| m.max(v.abs())) < 0.1,
        "mm were not converted to m"
    );
}

#[test]
fn diagnose_fit_and_compare_end_to_end() {
    let d = tmp("e2e");
    let rec = d.join("rec.csv");
    synth(&rec);
    let rec_s = rec.to_str().unwrap();
    let cols = Columns::new("force_N", "pos_mm");
    let p = Prepared::new(&data::load(&rec, &cols).unwrap(), None);
    let mut model = Model::baseline();
    refine::refit_all(&mut model, &p).unwrap();
    let dg = diagnose(&model, &p, &Options::default());
    let j = dg.to_json();
    assert!(j["residual_mode"].is_string());
    for k in ["fit_percent", "rms", "noise_floor_rms", "ljung_box_p"] {
        assert!(j["baseline"][k].is_f64(), "baseline.{k}");
    }
    // The baseline diagnose reports is the model's own score — what compare, fit and --auto
    // print for it (the same inertia, the same floor).
    let own = refine::score(&model, &p);
    assert_eq!(dg.baseline.rms, own.rms);
    assert_eq!(dg.baseline.fit_percent, own.fit_percent);
    assert_eq!(dg.baseline.noise_floor_rms, own.noise_floor_rms);
    let c0 = &j["candidates"][0];
    assert_eq!(c0["rank"], 1);
    assert!(c0["statistic"].is_f64() && c0["p_value"].is_f64() && c0["effect"].is_string());
    assert!(j["verdict"]["ambiguous_with"].is_array());
    assert_eq!(j["verdict"]["add"], "coulomb", "{}", dg.to_text());

    // fit --add coulomb writes a model whose Coulomb level is the simulated 0.8 N
    let out = d.join("fitted.toml");
    run(Cli::parse_from([
        "hil-host",
        "fit",
        rec_s,
        "--input",
        "force_N",
        "--output",
        "pos_mm",
        "--add",
        "coulomb",
        "--save-model",
        out.to_str().unwrap(),
    ]))
    .unwrap();
    let m = Model::load(&out).unwrap();
    let fc = m
        .effects
        .iter()
        .find(|e| e.kind.name() == "coulomb")
        .unwrap()
        .params[0]
        .clone();
    assert!((fc.value - 0.8).abs() < 0.1, "fc {}", fc.value);
    assert!((m.inertia.value - 2.0).abs() < 0.1, "m {}", m.inertia.value);
    assert!(fc.sigma.unwrap() > 0.0);

    // compare writes the HTML report with its eight plots inlined
    let rep = d.join("report");
    run(Cli::parse_from([
        "hil-host",
        "compare",
        rec_s,
        "--input",
        "force_N",
        "--output",
        "pos_mm",
        "--model",
        out.to_str().unwrap(),
        "--out",
        rep.to_str().unwrap(),
        "--png",
    ]))
    .unwrap();
    let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 8);
    for id in [
        "overlay",
        "residual_time",
        "residual_acf",
        "input_ccf",
        "residual_velocity",
        "residual_position",
        "residual_position_folded",
        "residual_spectrum",
    ] {
        assert!(
            rep.join(format!("{id}.svg")).exists() && rep.join(format!("{id}.png")).exists(),
            "{id}"
        );
    }
    // the fitted model leaves nothing significant
    let p2 = Prepared::new(&data::load(&rec, &cols).unwrap(), None);
    let d2 = diagnose(&m, &p2, &Options::default());
    assert!(d2.verdict.add.is_none(), "{}", d2.to_text());
    assert_eq!(j["intersample"], "zoh");

    // The same joint logged mid-hold and read as the default zoh: once Coulomb is in the
    // model the half sample is most of what is left, and the diagnosis says which convention
    // fits; read as `mid`, the Coulomb model leaves nothing significant.
    let mid = d.join("mid.csv");
    synth_logged(&mid, true);
    let with_coulomb = |c: &Columns| {
        let pm = Prepared::new(&data::load(&mid, c).unwrap(), None);
        let mut bm = Model::baseline();
        bm.add(sim_plant::effects::EffectKind::Coulomb, Default::default());
        refine::refit_all(&mut bm, &pm).unwrap();
        diagnose(&bm, &pm, &Options::default())
    };
    let dm = with_coulomb(&cols);
    assert!(
        dm.notes.iter().any(|n| n.contains("`mid`")),
        "{}",
        dm.to_text()
    );
    let dm = with_coulomb(
        &cols
            .clone()
            .with_intersample(sim_plant::effects::Intersample::Mid),
    );
    assert!(dm.verdict.add.is_none(), "{}", dm.to_text());
    assert!(
        !dm.notes.iter().any(|n| n.contains("better read as")),
        "{}",
        dm.to_text()
    );

    // every subcommand has examples in --help
    for sub in ["compare", "diagnose", "fit"] {
        let e = Cli::try_parse_from(["hil-host", sub, "--help"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("Examples:"), "{sub}");
    }
}

/// Write a hidden-effect record as a CSV with a load-side position column.
fn write_with_load(rec: &jointlab_tests::hidden::TruthRecord, path: &Path) {
    let mut s = String::from("time_s,torque_Nm,q_rad,q_load_rad\n");
    for (i, l) in rec.load_position.iter().enumerate() {
        s.push_str(&format!(
            "{},{},{},{l}\n",
            rec.time[i], rec.input[i], rec.position[i]
        ));
    }
    std::fs::write(path, s).unwrap();
}

/// `fit --load-output COL` feeds the load-side position in: on a backlash record (a hidden
/// trial with its load encoder) the backlash column is then built from the measured
/// deflection — the fitted gap is the truth's and the validation error falls well below the
/// motor-encoder-only fit's.
#[test]
fn fit_uses_a_load_side_position() {
    use jointlab_tests::hidden::{generate_in, rk4::Rk4, speed_conditions, Family};
    let d = tmp("load");
    let cond = speed_conditions(12.0);
    let t = generate_in(&Rk4, 1_400_005, &[Family::Backlash], 2.0, cond).expect("stable draw");
    let gap = t.effects[0].1;
    let (est, val) = (d.join("est.csv"), d.join("val.csv"));
    write_with_load(&t.est, &est);
    write_with_load(&t.val, &val);
    let cutoff = t.cutoff.to_string();
    let fit = |load: bool, out: &Path| {
        let mut args: Vec<String> = [
            "hil-host",
            "fit",
            est.to_str().unwrap(),
            "--input",
            "torque_Nm",
            "--output",
            "q_rad",
            "--cutoff",
            &cutoff,
            "--add",
            "backlash",
            "--validate",
            val.to_str().unwrap(),
            "--save-model",
            out.to_str().unwrap(),
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        if load {
            args.extend(["--load-output".to_string(), "q_load_rad".to_string()]);
        }
        run(Cli::parse_from(args)).map(|()| Model::load(out).unwrap())
    };
    let with =
        fit(true, &d.join("with.toml")).expect("the fit on the measured deflection is saved");
    // From the motor encoder alone a gap behind a 40–60 Hz spring may not fit physically at
    // all (then it is refused, not saved); when it does, it validates far worse.
    let without = fit(false, &d.join("without.toml"));
    let val_rms = |m: &Model, load: bool| {
        let mut cols = Columns::new("torque_Nm", "q_rad");
        if load {
            cols.load_output = Some("q_load_rad".into());
        }
        let p = Prepared::new(&data::load(&val, &cols).unwrap(), Some(t.cutoff));
        let r = jointlab_workbench::residual::equation_error(m, &p).residual;
        (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt()
    };
    let rw = val_rms(&with, true);
    let width = |m: &Model| {
        m.effects
            .iter()
            .find(|e| e.kind.name() == "backlash")
            .expect("backlash added")
            .shape
            .backlash_width
    };
    println!(
        "validation RMS / floor with the load column {:.3}; gap {:.4e} (truth {gap:.4e})",
        rw / t.floor_val_refit,
        width(&with),
    );
    assert!(
        rw <= 1.1 * t.floor_val_refit,
        "with the load column: {}",
        rw / t.floor_val_refit
    );
    match &without {
        Err(e) => println!("motor encoder alone: refused ({e})"),
        Ok(m) => {
            let ro = val_rms(m, false);
            println!(
                "motor encoder alone: validation RMS / floor {:.3}",
                ro / t.floor_val
            );
            assert!(rw < 0.6 * ro, "with {rw:.3e}, without {ro:.3e}");
        }
    }
    // (The measured width is the deflection's spread: the gap and the spring's travel.)
    assert!(width(&with) >= 0.9 * gap, "gap {} vs {gap}", width(&with));
}
