//! Dataset files and column detection: a recording described once in TOML gives the same
//! results as the flags it replaces; a header with unit suffixes needs no column flags; a
//! misspelled column or effect gets a "did you mean"; what cannot be settled is an error that
//! lists the candidates.

use std::path::{Path, PathBuf};

mod common;
use common::{hil, ok, text};

fn dir(name: &str) -> PathBuf {
    common::dir("dataset", name)
}

/// A 3 s PD-driven mass with viscous and Coulomb friction, logged under `names` (time,
/// command in volts, position in mm) plus an unrelated `temp_C` column; the force is
/// 12.5 N per logged volt.
fn record(path: &Path, names: [&str; 3], seed: usize) {
    let dt = 1e-3;
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let mut s = format!("{},{},temp_C,{}\n", names[0], names[1], names[2]);
    for k in 0..3000 {
        let t = k as f64 * dt;
        let r = 0.05 * (std::f64::consts::TAU * 0.7 * t).sin()
            + 0.01 * (std::f64::consts::TAU * (2.3 + seed as f64) * t).sin();
        let u = 400.0 * (r - x) - 40.0 * v + 0.01 * (((k + seed) * 7919 % 101) as f64 - 50.0);
        s.push_str(&format!("{t},{},{},{}\n", u / 12.5, 20.0 + t, x * 1e3));
        for _ in 0..10 {
            let a = (u - 3.0 * v - 0.8 * v.signum()) / 2.0;
            v += 1e-4 * a;
            x += 1e-4 * v;
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_dataset_file_gives_what_its_flags_give() {
    let d = dir("same");
    std::fs::create_dir_all(d.join("data")).unwrap();
    record(&d.join("data/run.csv"), ["clock_s", "cmd_V", "pos_mm"], 0);
    record(&d.join("data/val.csv"), ["clock_s", "cmd_V", "pos_mm"], 1);
    // The file's paths are relative to the dataset file, not to the working directory.
    std::fs::write(
        d.join("data/run.toml"),
        "description = \"a test rig\"\nfile = \"run.csv\"\ntime = \"clock_s\"\ninput = \"cmd_V\"\n\
         input_gain = 12.5\ninput_unit = \"N\"\noutput = \"pos_mm\"\nintersample = \"zoh\"\n\
         validate = \"val.csv\"\n",
    )
    .unwrap();
    let flags = [
        "--time",
        "clock_s",
        "--input",
        "cmd_V",
        "--input-gain",
        "12.5",
        "--input-unit",
        "N",
        "--output",
        "pos_mm",
    ];
    let by_flags = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "data/run.csv", "--json"])
        .args(flags)
        .output()
        .unwrap());
    let by_file = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "data/run.toml", "--json"])
        .output()
        .unwrap());
    assert_eq!(by_file, by_flags);
    let j: serde_json::Value = serde_json::from_str(&by_file).unwrap();
    assert_eq!(j["verdict"]["add"], "coulomb", "{by_file}");

    // `fit` validates on the dataset's `validate`; `--validate` overrides it.
    let fit = |args: &[&str], out: &str| {
        let s = ok(hil()
            .current_dir(&d)
            .arg("fit")
            .args(args)
            .args(["--add", "coulomb", "--json", "--save-model", out])
            .output()
            .unwrap());
        serde_json::from_str::<serde_json::Value>(&s).unwrap()
    };
    let a = fit(&["data/run.toml"], "a.toml");
    let mut with_flags = vec!["data/run.csv", "--validate", "data/val.csv"];
    with_flags.extend(flags);
    let b = fit(&with_flags, "b.toml");
    assert_eq!(a["report"], b["report"]);
    assert!(a["report"]["after_validation"].is_object(), "{a}");
    let c = fit(&["data/run.toml", "--validate", "data/run.csv"], "c.toml");
    assert_ne!(
        a["report"]["after_validation"],
        c["report"]["after_validation"]
    );
    assert_eq!(
        std::fs::read_to_string(d.join("a.toml")).unwrap(),
        std::fs::read_to_string(d.join("b.toml")).unwrap()
    );
    // A flag wins over the file's value.
    let e = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "data/run.toml", "--json", "--input-gain", "1"])
        .output()
        .unwrap());
    assert_ne!(e, by_file);
}

#[test]
fn a_header_with_unit_suffixes_needs_no_column_flags() {
    let d = dir("detect");
    record(&d.join("run.csv"), ["t_s", "force_N", "q_mm"], 0);
    let named = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "run.csv", "--json"])
        .args(["--time", "t_s", "--input", "force_N", "--output", "q_mm"])
        .output()
        .unwrap());
    let found = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "run.csv", "--json"])
        .output()
        .unwrap());
    assert_eq!(found, named);
    // A dataset file that names only the file.
    std::fs::write(d.join("min.toml"), "file = \"run.csv\"\n").unwrap();
    let min = ok(hil()
        .current_dir(&d)
        .args(["diagnose", "min.toml", "--json"])
        .output()
        .unwrap());
    assert_eq!(min, named);
}

#[test]
fn what_cannot_be_settled_is_an_error_that_helps() {
    let d = dir("errors");
    record(&d.join("two.csv"), ["time_s", "force_N", "q_mm"], 0);
    let s = std::fs::read_to_string(d.join("two.csv")).unwrap();
    // a second position column
    let two: String = s
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k == 0 {
                format!("{l},q2_deg\n")
            } else {
                format!("{l},0\n")
            }
        })
        .collect();
    std::fs::write(d.join("two.csv"), two).unwrap();
    let notime = s.replacen("time_s", "stamp", 1);
    std::fs::write(d.join("notime.csv"), notime).unwrap();
    std::fs::write(d.join("typo.toml"), "file = \"two.csv\"\n\ninptu = \"x\"\n").unwrap();
    std::fs::write(
        d.join("gain.toml"),
        "file = \"two.csv\"\noutput = \"q_mm\"\ninput_gain = 0\n",
    )
    .unwrap();
    let cases: [(&[&str], i32, &[&str]); 6] = [
        (
            &["diagnose", "two.csv"],
            1,
            &["no output column named", "q_mm, q2_deg", "--output"],
        ),
        (
            &["diagnose", "notime.csv"],
            1,
            &["no time column named", "time_s, t_s"],
        ),
        (
            &["diagnose", "two.csv", "--output", "q_mn"],
            1,
            &["two.csv:1:", "no column `q_mn`", "did you mean `q_mm`?"],
        ),
        (
            &["fit", "two.csv", "--output", "q_mm", "--add", "coulmb"],
            2,
            &["unknown effect `coulmb`", "did you mean `coulomb`?"],
        ),
        (
            &["diagnose", "typo.toml"],
            1,
            &["typo.toml", "line 3", "inptu"],
        ),
        (
            &["diagnose", "gain.toml"],
            1,
            &["gain.toml", "input_gain", "other than 0"],
        ),
    ];
    for (args, code, says) in cases {
        let o = hil().current_dir(&d).args(args).output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        for s in says {
            assert!(err.contains(s), "{args:?} should say {s:?}: {}", text(&o));
        }
    }
    assert!(!d.join("fitted-model.toml").exists());
}

/// `fit` and `diagnose --auto` keep their model by default and never replace an earlier one
/// they were not told to: the second run writes beside the first. A named file is replaced.
/// The report directory is `--report` (`--out` still works).
#[test]
fn models_are_kept_and_never_silently_replaced() {
    let d = dir("keep");
    record(&d.join("run.csv"), ["time_s", "force_N", "q_mm"], 0);
    let fit = |extra: &[&str]| {
        ok(hil()
            .current_dir(&d)
            .args(["fit", "run.csv", "--add", "coulomb"])
            .args(extra)
            .output()
            .unwrap())
    };
    let first = fit(&[]);
    assert!(
        first.contains("model written to fitted-model.toml"),
        "{first}"
    );
    let kept = std::fs::read_to_string(d.join("fitted-model.toml")).unwrap();
    std::fs::write(d.join("fitted-model.toml"), format!("# mine\n{kept}")).unwrap();
    let second = fit(&[]);
    assert!(
        second.contains("model written to fitted-model-2.toml"),
        "{second}"
    );
    assert!(std::fs::read_to_string(d.join("fitted-model.toml"))
        .unwrap()
        .starts_with("# mine"));
    fit(&["--save-model", "fitted-model.toml"]);
    assert!(!std::fs::read_to_string(d.join("fitted-model.toml"))
        .unwrap()
        .starts_with("# mine"));

    let auto = ok(hil()
        .current_dir(&d)
        .args([
            "diagnose",
            "run.csv",
            "--auto",
            "--max-steps",
            "1",
            "--report",
            "rep",
        ])
        .output()
        .unwrap());
    assert!(auto.contains("model written to auto-model.toml"), "{auto}");
    assert!(d.join("rep/report.html").exists());
    assert!(
        !d.join("rep/auto_error.png").exists(),
        "PNGs only with --png"
    );
    ok(hil()
        .current_dir(&d)
        .args([
            "compare",
            "run.csv",
            "--model",
            "auto-model.toml",
            "--out",
            "old",
        ])
        .output()
        .unwrap());
    assert!(d.join("old/report.html").exists());
}

/// Units reach every output: `--json` names them (with a schema version), a record in
/// millimetres is a linear axis whose model file and parameters speak kg, N and N·s/m, the
/// text prints engineering numbers, and a linear model given a joint's record is refused.
#[test]
fn units_reach_the_json_the_model_file_and_the_text() {
    let d = dir("units");
    record(&d.join("lin.csv"), ["time_s", "cmd_V", "pos_mm"], 0);
    let fit = |extra: &[&str]| {
        hil()
            .current_dir(&d)
            .args(["fit", "lin.csv", "--input", "cmd_V", "--input-gain", "12.5"])
            .args(["--input-unit", "N"])
            .args(["--add", "coulomb", "--save-model", "lin.toml"])
            .args(extra)
            .output()
            .unwrap()
    };
    let j: serde_json::Value = serde_json::from_str(&ok(fit(&["--json"]))).unwrap();
    assert_eq!(j["schema_version"], 1);
    assert_eq!(j["units"]["input"], "N");
    assert_eq!(j["units"]["position"], "m");
    assert_eq!(j["units"]["velocity"], "m/s");
    assert_eq!(j["units"]["residual"], "N");
    let units: Vec<(String, String)> = j["report"]["params"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                format!(
                    "{}.{}",
                    p["owner"].as_str().unwrap(),
                    p["name"].as_str().unwrap()
                ),
                p["unit"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    for (param, unit) in [
        ("inertia.inertia", "kg"),
        ("viscous.damping", "N·s/m"),
        ("coulomb.torque", "N"),
    ] {
        assert!(
            units.contains(&(param.to_string(), unit.to_string())),
            "{param} in {unit}: {units:?}"
        );
    }
    let model = std::fs::read_to_string(d.join("lin.toml")).unwrap();
    assert!(model.contains("axis = \"linear\""), "{model}");
    assert!(
        model.contains("# kg") && !model.contains("kg·m²"),
        "{model}"
    );

    // Text: 4 significant digits, no `9.7351e0`.
    let shown = ok(fit(&[]));
    let exp = shown
        .split_whitespace()
        .find(|w| w.contains("e0") || w.contains("e-1") || w.contains("e1"));
    assert_eq!(exp, None, "{shown}");
    assert!(
        shown.contains(" kg\n") && shown.contains(" N·s/m\n"),
        "{shown}"
    );

    // Fitted to the command in volts, the parameters are in volts: V·s²/m, not kg.
    let v = ok(hil()
        .current_dir(&d)
        .args([
            "fit",
            "lin.csv",
            "--input",
            "cmd_V",
            "--save-model",
            "volts.toml",
            "--json",
        ])
        .output()
        .unwrap());
    let v: serde_json::Value = serde_json::from_str(&v).unwrap();
    let units: Vec<&str> = v["report"]["params"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["unit"].as_str().unwrap())
        .collect();
    assert_eq!(units, ["V·s²/m", "V·s/m"], "{v}");

    // The same motion logged in radians is a joint's record: the linear model is refused.
    record(&d.join("rot.csv"), ["time_s", "cmd_V", "pos_rad"], 0);
    let o = hil()
        .current_dir(&d)
        .args([
            "compare",
            "rot.csv",
            "--input",
            "cmd_V",
            "--input-gain",
            "12.5",
        ])
        .args(["--model", "lin.toml"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("for a linear axis") && err.contains("rot.csv"),
        "{err}"
    );
}

/// `compare` gives its series as data: `residual.csv` in the report directory, with unit
/// suffixes in the header (a record in mm and N: m, m/s, N), measured − predicted = residual
/// on every row, and each model's RMS the one the JSON reports (two models: `m1_`, `m2_`).
#[test]
fn compare_writes_its_residual_as_data() {
    let d = dir("resid");
    record(&d.join("run.csv"), ["time_s", "force_N", "q_mm"], 0);
    ok(hil()
        .current_dir(&d)
        .args([
            "fit",
            "run.csv",
            "--add",
            "coulomb",
            "--save-model",
            "c.toml",
        ])
        .output()
        .unwrap());
    let j: serde_json::Value = serde_json::from_str(&ok(hil()
        .current_dir(&d)
        .args(["compare", "run.csv", "--json", "--report", "rep"])
        .args(["--model", "c.toml", "--refit", "--model", "c.toml"])
        .output()
        .unwrap()))
    .unwrap();
    let path = d.join("rep/residual.csv");
    assert_eq!(j["residual_csv"], "rep/residual.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        header,
        [
            "time_s",
            "position_m",
            "velocity_m_per_s",
            "measured_N",
            "m1_predicted_N",
            "m1_residual_N",
            "m2_predicted_N",
            "m2_residual_N"
        ]
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() > 2500, "{} rows", rows.len());
    for (k, model) in j["models"].as_array().unwrap().iter().enumerate() {
        let (p, r) = (4 + 2 * k, 5 + 2 * k);
        let mut ss = 0.0;
        for row in &rows {
            assert!((row[3] - row[p] - row[r]).abs() <= 1e-9 * row[3].abs().max(1.0));
            ss += row[r] * row[r];
        }
        let rms = (ss / rows.len() as f64).sqrt();
        let want = model["metrics"]["rms"].as_f64().unwrap();
        assert!(
            (rms / want - 1.0).abs() < 1e-9,
            "model {k}: {rms} vs {want}"
        );
    }
}
