//! `replay` as can-utils' candump and a converter: a lab run's candump log, decoded through the
//! protocol's DBC, gives back the lab recorder's own CSV row for row (two independent paths:
//! the recorder saw the nodes' values, the converter only the bytes on the wire); candump
//! filters and timestamp modes; clear errors.

use std::path::{Path, PathBuf};

mod common;
use common::{hil, ok, text};

fn dir(name: &str) -> PathBuf {
    common::dir("replay", name)
}

/// A lab step run on harmonic-drive-60: its recorder's CSV and its candump log.
fn lab_run(d: &Path) -> (PathBuf, PathBuf) {
    ok(hil()
        .args([
            "demo",
            "--scenario",
            "step",
            "--preset",
            "harmonic-drive-60",
            "--out",
        ])
        .arg(d)
        .output()
        .unwrap());
    let stem = d.join("demo-step-harmonic-drive-60");
    (stem.with_extension("csv"), stem.with_extension("log"))
}

fn table(p: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(p).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
    r.records()
        .map(|row| {
            let row = row.unwrap();
            h.iter()
                .cloned()
                .zip(row.iter().map(str::to_string))
                .collect()
        })
        .collect()
}

#[test]
fn a_lab_log_converts_to_the_recorders_csv_row_for_row() {
    let d = dir("convert");
    let (lab_csv, log) = lab_run(&d);
    let out = d.join("from-log.csv");
    let o = hil()
        .arg("replay")
        .arg(&log)
        .arg("--csv")
        .arg(&out)
        .output()
        .unwrap();
    let said = text(&o);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("2304 counts/rev"), "{said}");
    let lab = table(&lab_csv);
    let wire = table(&out);
    assert_eq!(lab.len(), wire.len());
    let f = |r: &std::collections::HashMap<String, String>, k: &str| -> f64 {
        r.get(k)
            .unwrap_or_else(|| panic!("no column {k}"))
            .parse()
            .unwrap()
    };
    let t0 = f(&lab[0], "time_s");
    for (a, b) in lab.iter().zip(&wire) {
        assert_eq!(f(a, "seq") as i64 % 256, f(b, "sensor_seq") as i64);
        assert!((f(a, "time_s") - t0 - f(b, "time_s")).abs() < 1e-9);
        assert!((f(a, "motor_pos_rad") - f(b, "motor_pos_rad")).abs() < 1e-9);
        assert!((f(a, "torque_cmd_Nm") - f(b, "actuator_torque_Nm")).abs() < 1e-9);
        assert!((f(a, "torque_sensor_Nm") - f(b, "sensor_output_torque_Nm")).abs() < 1e-9);
    }
    // The motion is there (not a column of zeros that would match trivially).
    let travel = wire
        .iter()
        .map(|r| f(r, "motor_pos_rad").abs())
        .fold(0.0, f64::max);
    assert!(travel > 0.1, "{travel}");
    // And the workbench loads it as it is.
    ok(hil()
        .arg("diagnose")
        .arg(&out)
        .args(["--input", "actuator_torque_Nm", "--json"])
        .output()
        .unwrap());
}

#[test]
fn filters_and_timestamps_are_candumps() {
    let d = dir("print");
    let (_, log) = lab_run(&d);
    let all = ok(hil().arg("replay").arg(&log).output().unwrap());
    let actuators = ok(hil()
        .arg("replay")
        .arg(&log)
        .args(["--filter", "201:7FF", "--timestamp", "zero"])
        .output()
        .unwrap());
    let lines: Vec<&str> = actuators.lines().collect();
    assert_eq!(
        lines.len(),
        all.lines().filter(|l| l.contains("Actuator[1]")).count()
    );
    assert!(lines.len() >= 2000, "{}", lines.len());
    assert!(lines
        .iter()
        .all(|l| l.contains("Actuator[1] torque=") && l.contains(" N.m")));
    assert!(lines[0].starts_with("(0.000000)"), "{}", lines[0]);
    let rest = ok(hil()
        .arg("replay")
        .arg(&log)
        .args(["--filter", "201~7FF"])
        .output()
        .unwrap());
    assert_eq!(rest.lines().count() + lines.len(), all.lines().count());
    assert!(!rest.contains("Actuator["));
    // Parameter writes name the parameter and its unit.
    assert!(
        all.contains("(motor_counts_per_rev, counts)"),
        "{all:.2000}"
    );
}

#[test]
fn what_replay_cannot_do_it_says() {
    let d = dir("errors");
    let (_, log) = lab_run(&d);
    let cases: [(&[&str], i32, &str); 3] = [
        (&["--filter", "201"], 2, "ID:MASK"),
        (
            &["--csv", "x.csv", "--node", "3"],
            2,
            "node 3 sent no Sensor frame",
        ),
        (
            &["--csv", "x.csv", "--filter", "201:7FF"],
            2,
            "no Sensor frame",
        ),
    ];
    for (args, code, says) in cases {
        let o = hil()
            .current_dir(&d)
            .arg("replay")
            .arg(&log)
            .args(args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", text(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(says),
            "{args:?}: {}",
            text(&o)
        );
    }
}
