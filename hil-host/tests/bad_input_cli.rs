//! Bad input on the command line: a clear error naming what and where, a nonzero exit (1 for
//! a file's contents, 2 for a bad flag), and no half-written output.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{hil, text};

fn dir(name: &str) -> PathBuf {
    common::dir("badcli", name)
}

/// A 3 s PD-driven mass with viscous friction (time_s, force_N, pos_m); `cell(row)` may
/// replace a row's force cell.
fn record(path: &Path, cell: impl Fn(usize) -> Option<&'static str>) {
    let dt = 1e-3;
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let mut s = String::from("time_s,force_N,pos_m\n");
    for k in 0..3000 {
        let t = k as f64 * dt;
        let r = 0.05 * (std::f64::consts::TAU * 0.7 * t).sin();
        let u = 400.0 * (r - x) - 40.0 * v + 0.01 * ((k * 7919 % 101) as f64 - 50.0);
        let shown = cell(k).map_or(u.to_string(), str::to_string);
        s.push_str(&format!("{t},{shown},{x}\n"));
        for _ in 0..10 {
            let a = (u - 3.0 * v) / 2.0;
            v += 1e-4 * a;
            x += 1e-4 * v;
        }
    }
    std::fs::write(path, s).unwrap();
}

fn workbench(cmd: &str, rec: &Path, extra: &[&str]) -> Output {
    hil()
        .arg(cmd)
        .arg(rec)
        .args(["--input", "force_N", "--output", "pos_m"])
        .args(extra)
        .output()
        .unwrap()
}

/// One 1e308 cell: `diagnose` exited 0 with "fit NaN %" and "no significant missing effect";
/// `fit --validate` on it printed NaN and wrote the model. Now both fail with exit 1 naming
/// the file, line and column, and `fit` writes nothing.
#[test]
fn a_cell_out_of_scale_fails_naming_file_line_and_column() {
    let d = dir("huge");
    let (good, huge) = (d.join("good.csv"), d.join("huge.csv"));
    record(&good, |_| None);
    record(&huge, |k| (k == 1000).then_some("1e308"));
    let o = workbench("diagnose", &huge, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("huge.csv:1002: column `force_N`") && !e.contains("NaN"),
        "{e}"
    );
    let model = d.join("m.toml");
    let o = workbench(
        "fit",
        &good,
        &[
            "--validate",
            huge.to_str().unwrap(),
            "--save-model",
            model.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("huge.csv:1002:"));
    assert!(!model.exists(), "no model is written after a failed fit");
    std::fs::remove_dir_all(&d).ok();
}

/// A NaN, infinite or zero gain is a usage error (exit 2) naming the flag; a finite gain whose
/// product overflows is a data error naming the flag and the line.
#[test]
fn a_bad_input_gain_names_the_flag() {
    let d = dir("gain");
    let rec = d.join("rec.csv");
    record(&rec, |_| None);
    for g in ["nan", "inf", "0"] {
        let o = workbench("diagnose", &rec, &["--input-gain", g]);
        assert_eq!(o.status.code(), Some(2), "{g}: {}", text(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("--input-gain"),
            "{g}: {}",
            text(&o)
        );
    }
    let o = workbench("diagnose", &rec, &["--input-gain", "1e308"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("rec.csv:") && e.contains("after --input-gain 1e308"),
        "{e}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// `fit` on a model with nothing free (an empty model file) panicked; now exit 1 and no file.
#[test]
fn fit_with_nothing_free_fails_cleanly() {
    let d = dir("nofree");
    let rec = d.join("rec.csv");
    record(&rec, |_| None);
    let empty = d.join("empty.toml");
    std::fs::write(&empty, "").unwrap();
    let out = d.join("out.toml");
    let o = workbench(
        "fit",
        &rec,
        &[
            "--model",
            empty.to_str().unwrap(),
            "--save-model",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no free parameter"),
        "{}",
        text(&o)
    );
    assert!(!out.exists());
    // `min = nan` is refused where it is written.
    let nan = d.join("nan.toml");
    std::fs::write(
        &nan,
        "[effects.viscous]\ndamping = { value = 1.0, free = true, min = nan }\n",
    )
    .unwrap();
    let o = workbench("fit", &rec, &["--model", nan.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("nan.toml:2:") && e.contains("`damping`") && e.contains("NaN"),
        "{e}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// An empty candump log exited 0 saying nothing; one CAN FD line aborted the whole file. Now
/// the empty log is an error naming the file, and FD and unparseable lines are skipped with
/// a count on stderr.
#[test]
fn replay_refuses_an_empty_log_and_skips_odd_lines() {
    let d = dir("replay");
    let empty = d.join("empty.log");
    std::fs::write(&empty, "").unwrap();
    let o = hil().arg("replay").arg(&empty).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("empty.log") && e.contains("no CAN frame"), "{e}");

    let mixed = d.join("mixed.log");
    std::fs::write(
        &mixed,
        "(1700000000.000100) vcan0 123#DEADBEEF\n\
         (1700000000.000200) vcan0 123##1112233\n\
         garbage\n\
         (1700000000.000300) vcan0 456#01\n",
    )
    .unwrap();
    let o = hil().arg("replay").arg(&mixed).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(out.lines().count(), 2, "{out}");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("skipped 2 line(s): 1 CAN FD (##), 1 unparseable") && e.contains("line 3"),
        "{e}"
    );
    // Only FD lines: no frame at all, an error.
    let fd = d.join("fd.log");
    std::fs::write(&fd, "(1700000000.000200) vcan0 123##1112233\n").unwrap();
    let o = hil().arg("replay").arg(&fd).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("1 CAN FD"),
        "{}",
        text(&o)
    );
    std::fs::remove_dir_all(&d).ok();
}
