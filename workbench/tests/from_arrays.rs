//! `Recording::from_arrays` and the CSV loader share one constructor: the same numbers give
//! the same recording (units, gains, window, resampling, the as-recorded columns the noise
//! statistics read) and so the same diagnosis; bad arrays are errors naming the array.

use std::path::PathBuf;

use jointlab_workbench::data::{self, Arrays, Columns, DataError, Recording, ARRAYS};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;

/// A polled clock (intervals 0.9–1.1 ms), a mass with viscous and Coulomb friction driven
/// through a gain, its position logged in mm on a 1 µm encoder, the input with a little
/// deterministic noise; columns (time, input in V, position in mm, supply in V).
fn record(n: usize) -> [Vec<f64>; 4] {
    let (mut t, mut u, mut q, mut volts) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut now = 0.0;
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for k in 0..n {
        let w = [
            2.0 * std::f64::consts::PI * 1.3,
            2.0 * std::f64::consts::PI * 3.1,
        ];
        let x = 0.1 * (w[0] * now).sin() + 0.03 * (w[1] * now).sin();
        let v = 0.1 * w[0] * (w[0] * now).cos() + 0.03 * w[1] * (w[1] * now).cos();
        let a = -0.1 * w[0] * w[0] * (w[0] * now).sin() - 0.03 * w[1] * w[1] * (w[1] * now).sin();
        let force = 2.0 * a + 5.0 * v + 1.5 * v.signum() + 0.02 * noise();
        let supply = 12.0 + 0.1 * (k % 7) as f64;
        t.push(now);
        // Logged as duty × supply through a 10 N/V gain: duty = force / (10 · supply).
        u.push(force / (10.0 * supply));
        q.push((x * 1e6).round() / 1e3);
        volts.push(supply);
        now += 1e-3 * (1.0 + 0.1 * [0.0, 1.0, -1.0, 0.5][k % 4]);
    }
    [t, u, q, volts]
}

fn columns() -> Columns {
    Columns {
        time: "t_s".into(),
        input_gain: 10.0,
        input_times: Some("supply_V".into()),
        window: Some((0.1, 1.9)),
        ..Columns::new("duty", "pos_mm")
    }
}

fn arrays(r: &[Vec<f64>; 4]) -> Arrays<'_> {
    Arrays {
        time: &r[0],
        input: &r[1],
        output: &r[2],
        load_output: None,
        input_times: Some(&r[3]),
    }
}

/// The CSV text of the columns; `{}` prints the shortest text that parses back to the same
/// f64, so the file holds exactly the arrays' numbers.
fn csv_text(r: &[Vec<f64>; 4]) -> String {
    let mut s = String::from("t_s,duty,pos_mm,supply_V\n");
    let [t, u, q, v] = r;
    for (((t, u), q), v) in t.iter().zip(u).zip(q).zip(v) {
        s += &format!("{t},{u},{q},{v}\n");
    }
    s
}

fn same(a: &Recording, b: &Recording) {
    assert_eq!(a.time, b.time);
    assert_eq!(a.input, b.input);
    assert_eq!(a.output, b.output);
    assert_eq!(a.dt, b.dt);
    assert_eq!(a.units, b.units);
    assert_eq!(a.resampled, b.resampled);
    assert_eq!(a.recorded, b.recorded);
}

#[test]
fn arrays_and_the_csv_loader_give_one_recording_and_one_diagnosis() {
    let r = record(2000);
    let dir = std::env::temp_dir().join(format!("jointlab-arrays-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("polled.csv");
    std::fs::write(&path, csv_text(&r)).expect("write csv");
    let cols = columns();
    let from_csv = data::load(&path, &cols);
    std::fs::remove_dir_all(&dir).ok();
    let from_csv = from_csv.expect("csv");
    let from_arrays = Recording::from_arrays(arrays(&r), &cols).expect("arrays");
    // The window, the units (mm → m, duty × V × gain) and the resampling all applied.
    assert!(from_csv.resampled.is_some(), "a polled clock is resampled");
    assert!(from_csv.recorded.is_some());
    assert!(from_csv.time[0] >= 0.1 && *from_csv.time.last().unwrap() <= 1.9);
    assert!(
        from_csv.output.iter().all(|x| x.abs() < 0.2),
        "positions in m"
    );
    same(&from_csv, &from_arrays);
    assert_eq!(from_arrays.path, PathBuf::from(ARRAYS));

    let diagnosis = |rec: &Recording| {
        let p = Prepared::checked(rec, None).expect("default cut-off");
        let mut m = Model::baseline();
        refine::refit_all(&mut m, &p).expect("baseline fit");
        diagnose(&m, &p, &Options::default()).to_json()
    };
    let (a, b) = (diagnosis(&from_csv), diagnosis(&from_arrays));
    assert_eq!(a, b);
    // A diagnosis with something in it: the friction the record holds ranks first.
    assert_eq!(a["candidates"][0]["effect"], "coulomb", "{a}");
}

#[test]
fn bad_arrays_are_errors_naming_the_array_and_the_index() {
    let r = record(200);
    let cols = Columns {
        window: None,
        ..columns()
    };
    let mut nan = r.clone();
    nan[1][17] = f64::NAN;
    let e = Recording::from_arrays(arrays(&nan), &cols).unwrap_err();
    assert!(
        matches!(&e, DataError::NotFinite { line: 17, column, .. } if column == "duty"),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "<arrays>:17: column `duty`: value is NaN (NaN/inf not allowed)"
    );

    let mut short = r.clone();
    short[2].pop();
    let e = Recording::from_arrays(arrays(&short), &cols)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "<arrays>: `pos_mm` holds 199 values, `t_s` 200: every array needs one value per sample"
    );

    let e = Recording::from_arrays(
        Arrays {
            input_times: None,
            ..arrays(&r)
        },
        &cols,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("input_times names `supply_V` but no array"),
        "{e}"
    );

    // The shared checks after the arrays are read: time must increase.
    let mut back = r.clone();
    back[0][50] = back[0][49];
    let e = Recording::from_arrays(arrays(&back), &cols)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("<arrays>:50: column `t_s`: time"), "{e}");
}
