//! `Recording::from_arrays` and the CSV loader share one constructor: the same numbers give
//! the same recording (units, gains, window, resampling, the as-recorded columns the noise
//! statistics read) and so the same diagnosis; bad arrays are errors naming the array; and no
//! arrays at all make it (or the preparation for a fit) panic.

use std::path::PathBuf;

use proptest::prelude::*;
use sim_plant::effects::Intersample;

use jointlab_workbench::data::{self, Arrays, Columns, DataError, Recording, ARRAYS};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::{PrepareError, Prepared};

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

/// A value of one of the kinds that break naive arithmetic: NaN, ±inf, the largest doubles,
/// values whose square overflows, subnormals, zero, or any bit pattern.
fn special() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(-f64::MAX),
        Just(1e300),
        Just(1e155),
        Just(-1e160),
        Just(5e-324),
        Just(0.0),
        any::<f64>(),
    ]
}

/// One arbitrary call of `Recording::from_arrays` and the cut-off a caller would pass with it.
#[derive(Debug, Clone)]
struct Case {
    columns: [Vec<f64>; 5],
    given: (bool, bool),
    cols: Columns,
    cutoff: Option<f64>,
}

/// Arbitrary calls, most of them near a valid recording so that many get past the checks:
/// a clock of steps `dt·(1 + jitter)`, random inputs and positions, then a few cells
/// overwritten by [`special`] values, arrays cut to other lengths, steps made negative,
/// optional arrays given without a name or named without an array, unit suffixes (known and
/// unknown), gains, windows and cut-offs that are wild or not finite.
fn case() -> impl Strategy<Value = Case> {
    let n = prop_oneof![1 => 0usize..60, 4 => 60usize..400];
    let dt = prop_oneof![4 => Just(1e-3), 1 => 1e-9..10.0f64, 1 => special()];
    (n, dt).prop_flat_map(|(n, dt)| {
        let signal = move |amp: f64| prop::collection::vec(-amp..amp, n);
        // Jitter of the clock: none, a polled clock (resampled), or steps going backwards.
        let jitter = prop_oneof![3 => Just(0.0), 2 => Just(0.4), 1 => Just(3.0)]
            .prop_flat_map(move |a| prop::collection::vec(-a..=a, n));
        let arrays = (
            jitter,
            signal(10.0),
            signal(1.0),
            signal(1.0),
            prop::collection::vec(1.0..20.0f64, n),
        );
        let corrupt = prop_oneof![
            2 => Just(Vec::new()),
            1 => prop::collection::vec((0usize..5, 0..n.max(1), special()), 1..4),
        ];
        let lengths = prop::collection::vec(
            prop_oneof![29 => Just(None), 1 => (0..n + 5).prop_map(Some)],
            5,
        );
        // Names with known unit suffixes, and now and then an unknown one (`_ks`, `_kV`, `_km`).
        let name = |known: Vec<&'static str>, unknown: &'static str| {
            prop_oneof![15 => prop::sample::select(known), 1 => Just(unknown)]
        };
        let names = (
            name(vec!["t_s", "t_ms", "t_us", "time"], "t_ks"),
            name(vec!["u", "u_V", "tau_Nm", "force_N"], "u_kV"),
            name(vec!["q", "q_rad", "q_deg", "pos_mm", "pos_m"], "q_km"),
        );
        // An optional array given and named, mostly alike; now and then one without the other.
        let optional = || {
            (any::<bool>(), prop_oneof![19 => Just(false), 1 => Just(true)])
                .prop_map(|(given, flip)| (given, given != flip))
        };
        let optional = (optional(), optional());
        let gain = || prop_oneof![4 => Just(1.0), 1 => -1e3..1e3f64, 1 => special()];
        let window = prop_oneof![
            3 => Just(None),
            1 => (-1.0..2.0f64, -1.0..2.0f64).prop_map(Some),
            1 => (special(), special()).prop_map(Some),
        ];
        let cutoff = prop_oneof![3 => Just(None), 1 => (0.0..600.0f64).prop_map(Some), 1 => special().prop_map(Some)];
        let shape = (
            prop::sample::select(vec![Intersample::Zoh, Intersample::Foh, Intersample::Mid]),
            prop_oneof![4 => Just(1.0), 1 => special()],
        );
        (
            arrays,
            corrupt,
            lengths,
            names,
            optional,
            (gain(), gain()),
            window,
            cutoff,
            shape,
        )
            .prop_map(
                move |(
                    (jitter, u, q, load, supply),
                    corrupt,
                    lengths,
                    (time, input, output),
                    ((load_given, load_named), (times_given, times_named)),
                    (input_gain, load_gain),
                    window,
                    cutoff,
                    (intersample, gear_ratio),
                )| {
                    let mut now = 0.0;
                    let t = jitter
                        .iter()
                        .map(|j| {
                            let at = now;
                            now += dt * (1.0 + j);
                            at
                        })
                        .collect();
                    let mut columns = [t, u, q, load, supply];
                    for (c, k, v) in corrupt {
                        if let Some(x) = columns[c].get_mut(k) {
                            *x = v;
                        }
                    }
                    for (x, len) in columns.iter_mut().zip(lengths) {
                        if let Some(len) = len {
                            x.resize(len, 0.5);
                        }
                    }
                    let cols = Columns {
                        time: time.into(),
                        load_output: load_named.then(|| "q_load_rad".into()),
                        input_times: times_named.then(|| "supply_V".into()),
                        input_gain,
                        load_gain,
                        window,
                        intersample,
                        gear_ratio,
                        ..Columns::new(input, output)
                    };
                    Case {
                        columns,
                        given: (load_given, times_given),
                        cols,
                        cutoff,
                    }
                },
            )
    })
}

/// Every value of `x` finite, or which one is not.
fn all_finite(what: &str, x: &[f64]) -> Result<(), TestCaseError> {
    match x.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(k) => Err(TestCaseError::fail(format!("{what}[{k}] = {}", x[k]))),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    /// Whatever the arrays hold, `from_arrays` and the preparation for a fit return Ok or an
    /// error, never panic; and what they accept is finite everywhere a fit reads it, so a
    /// bad input is an error naming it and never a NaN result.
    #[test]
    fn any_arrays_give_a_finite_recording_or_an_error(c in case()) {
        let [t, u, q, load, supply] = &c.columns;
        let arrays = Arrays {
            time: t,
            input: u,
            output: q,
            load_output: c.given.0.then_some(load.as_slice()),
            input_times: c.given.1.then_some(supply.as_slice()),
        };
        let Ok(rec) = Recording::from_arrays(arrays, &c.cols) else {
            return Ok(());
        };
        prop_assert!(rec.len() >= 50, "{} rows", rec.len());
        prop_assert!(rec.dt.is_finite() && rec.dt > 0.0, "dt {}", rec.dt);
        all_finite("time", &rec.time)?;
        all_finite("input", &rec.input)?;
        all_finite("output", &rec.output)?;
        all_finite("load_output", rec.load_output.as_deref().unwrap_or_default())?;
        let Ok(p) = Prepared::checked(&rec, c.cutoff) else {
            return Ok(());
        };
        for (what, x) in [
            ("prepared time", &p.time),
            ("prepared input", &p.input),
            ("prepared position", &p.position),
            ("prepared velocity", &p.velocity),
            ("prepared acceleration", &p.acceleration),
            ("prepared load position", &p.load_position),
            ("prepared raw input", &p.raw_input),
            ("prepared raw position", &p.raw_position),
            ("prepared raw acceleration", &p.raw_acceleration),
            ("prepared input instrument", &p.input_instrument),
        ] {
            all_finite(what, x)?;
        }
        for (what, x) in [
            ("dt", p.dt),
            ("cut-off", p.cutoff_hz),
            ("noise floor", p.noise_floor),
            ("input noise variance", p.input_noise_var),
            ("position noise variance", p.position_noise_var),
            ("acceleration noise variance", p.acceleration_noise_var),
            ("load acceleration noise variance", p.load_acceleration_noise_var),
            ("stick velocity", p.stick_velocity),
        ] {
            prop_assert!(x.is_finite(), "{what} = {x}");
        }
    }
}

/// Deterministic signals for the cases below: an input with some content, a position moving.
fn wave(n: usize) -> (Vec<f64>, Vec<f64>) {
    let u = (0..n).map(|k| (0.37 * k as f64).sin()).collect();
    let q = (0..n).map(|k| 0.01 * (0.05 * k as f64).sin()).collect();
    (u, q)
}

/// A clock far faster than the default cut-off (a µs clock read as s, scaled once more): the
/// filter's padding, 3·fs/fc samples, is more than a usize holds and is capped by the record.
#[test]
fn a_clock_far_faster_than_the_cutoff_prepares_without_overflow() {
    let n = 300;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-300).collect();
    let (u, q) = wave(n);
    let arrays = Arrays {
        time: &t,
        input: &u,
        output: &q,
        load_output: None,
        input_times: None,
    };
    let rec = Recording::from_arrays(arrays, &Columns::new("u", "q")).expect("uniform, finite");
    if let Ok(p) = Prepared::checked(&rec, None) {
        assert!(p.acceleration.iter().all(|a| a.is_finite()));
    }
}

/// A position cell finite in itself and in its derivatives' sums of squares, but whose jump
/// overflows the noise estimate the significance tests use: an error naming the record, not
/// an infinite noise floor that would hide every effect.
#[test]
fn a_jump_that_overflows_the_noise_statistics_is_refused() {
    let n = 213;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 5.0).collect();
    let (u, mut q) = wave(n);
    q[100] = 1e155;
    let arrays = Arrays {
        time: &t,
        input: &u,
        output: &q,
        load_output: None,
        input_times: None,
    };
    let rec = Recording::from_arrays(arrays, &Columns::new("u", "q_deg"))
        .expect("1e155° is in range as a value");
    let e = Prepared::checked(&rec, None).expect_err("its differences are not");
    assert!(matches!(e, PrepareError::Data(_)), "{e:?}");
    let text = e.to_string();
    assert!(
        text.starts_with("<arrays>: the ") && text.contains("out of scale"),
        "{text}"
    );
}
