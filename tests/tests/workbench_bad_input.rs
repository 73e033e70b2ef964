//! Bad input to the workbench library: each case is an error that names what and where, never
//! a panic and never a NaN result.

use std::path::{Path, PathBuf};

use jointlab_tests::synth::PdMass;
use jointlab_workbench::data::{self, Columns, DataError};
use jointlab_workbench::fit::{self, FitError};
use jointlab_workbench::model::{Model, ModelError, Unfittable};
use jointlab_workbench::refine;
use jointlab_workbench::residual::{PrepareError, Prepared};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("jointlab-bad-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The PD-tracked mass of [`PdMass`], `rows` rows in m; `edit(row, [t, u, x])` may change a
/// row's cells (as text).
fn record(path: &Path, rows: usize, edit: impl Fn(usize, &mut [String; 3])) {
    PdMass::new(rows).write(path, edit);
}

fn cols() -> Columns {
    Columns::new("force_N", "pos_m")
}

fn prepared(path: &Path) -> Prepared {
    let rec = data::load(path, &cols()).expect("loads");
    Prepared::checked(&rec, None).expect("in range")
}

/// A model with nothing free (every parameter fixed, or an empty file: the defaults are
/// fixed) panicked in the SVD of an empty matrix; `fit` is now an error saying there is
/// nothing to fit, and refitting such a model (what `compare`/`diagnose` do) is a no-op.
#[test]
fn a_model_with_no_free_parameter_is_an_error_not_a_panic() {
    let d = dir("nofree");
    let rec = d.join("rec.csv");
    record(&rec, 3000, |_, _| {});
    let p = prepared(&rec);
    for (name, text) in [
        (
            "fixed.toml",
            "name = \"fixed\"\n[motor]\ninertia = 2.0\n[effects.viscous]\ndamping = 3.0\n",
        ),
        ("empty.toml", ""),
    ] {
        let f = d.join(name);
        std::fs::write(&f, text).unwrap();
        let mut m = Model::load(&f).expect("a fixed model loads");
        assert!(m.params().iter().all(|q| !q.free), "{name}");
        refine::refit_all(&mut m, &p).expect("nothing to refit is fine");
        let e = refine::fit_add(&mut m, &p, None, None).expect_err(name);
        assert!(matches!(e, FitError::NothingFree), "{name}: {e}");
        assert!(e.to_string().contains("no free parameter"), "{e}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// One cell of 1e308 is finite, so the CSV reader took it, and the fit came out NaN. It is
/// refused after scaling, naming the file, line and column: a value whose square overflows
/// (1e160 as well as 1e308), and a product that overflows (an input gain of 1e308).
#[test]
fn a_value_out_of_scale_is_refused_after_scaling_with_file_line_and_column() {
    let d = dir("huge");
    for (name, column, cell, gain, want) in [
        ("in.csv", 1, "1e308", 1.0, "its square overflows"),
        ("out.csv", 2, "1e160", 1.0, "its square overflows"),
        ("gain.csv", 1, "", 1e308, "after --input-gain 1e308"),
    ] {
        let f = d.join(name);
        record(&f, 3000, |k, c| {
            if k == 2000 && !cell.is_empty() {
                c[column] = cell.into();
            }
        });
        let cols = Columns {
            input_gain: gain,
            ..cols()
        };
        let e = data::load(&f, &cols).expect_err(name);
        assert!(matches!(e, DataError::OutOfRange { .. }), "{name}: {e}");
        let text = e.to_string();
        let col = ["time_s", "force_N", "pos_m"][column];
        assert!(text.contains(&format!("{name}:")), "{text}");
        assert!(text.contains(&format!("column `{col}`")), "{text}");
        assert!(text.contains(want), "{text}");
        if !cell.is_empty() {
            // Line 1 is the header: row 2000 is line 2002.
            assert!(text.contains(":2002:"), "{text}");
        }
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Finite cells whose squares do not overflow can still differentiate to values that do (a
/// jump of 1e152 m in one millisecond): refused after differentiation, naming the signal and
/// the time, instead of a NaN fit.
#[test]
fn a_derivative_out_of_range_is_refused_after_differentiation() {
    let d = dir("deriv");
    let f = d.join("jump.csv");
    record(&f, 3000, |k, c| {
        if k == 1500 {
            c[2] = "1e152".into();
        }
    });
    let rec = data::load(&f, &cols()).expect("the cells themselves are in range");
    let e = Prepared::checked(&rec, None).expect_err("its derivatives are not");
    let text = e.to_string();
    assert!(
        matches!(e, PrepareError::Data(DataError::Derived { .. })),
        "{text}"
    );
    assert!(
        text.contains("jump.csv") && text.contains("after differentiation"),
        "{text}"
    );
    assert!(
        text.contains("t = 1.49") || text.contains("t = 1.50"),
        "{text}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// Finite regressors whose Gram matrix overflows gave NaN estimates; now an error.
#[test]
fn a_least_squares_solution_that_overflows_is_an_error() {
    let x: Vec<f64> = (0..100).map(|i| 1e200 * (1.0 + (i as f64).sin())).collect();
    let y: Vec<f64> = (0..100).map(|i| (i as f64).cos()).collect();
    let e = fit::least_squares(&[x], &y).expect_err("XᵀX overflows");
    assert!(matches!(e, FitError::NonFiniteResult { .. }), "{e}");
}

/// `min`/`max` on an effect amplitude are honoured: the viscous coefficient fits to about 3
/// without bounds; with `max = 2.5` it is held at 2.5 (no 1σ: not estimated), and the file
/// written keeps the bound. A bound on a parameter the fitter does not fit as itself (the
/// motor's share of the rigid inertia) is refused at load, naming the file and parameter.
#[test]
fn bounds_on_an_amplitude_are_honoured_and_others_refused() {
    let d = dir("bounds");
    let rec = d.join("rec.csv");
    record(&rec, 6000, |_, _| {});
    let p = prepared(&rec);
    let model = |damping: &str| {
        format!(
            "name = \"b\"\n[motor]\ninertia = {{ value = 1.0, free = true }}\n\
             [effects.viscous]\ndamping = {damping}\n\
             [effects.coulomb]\ntorque = {{ value = 0.5, free = true }}\n"
        )
    };
    let free = d.join("free.toml");
    std::fs::write(&free, model("{ value = 1.0, free = true }")).unwrap();
    let mut m = Model::load(&free).unwrap();
    refine::fit_add(&mut m, &p, None, None).unwrap();
    let viscous = |m: &Model| m.effects[0].params[0].clone();
    let unbounded = viscous(&m).value;
    assert!(unbounded > 2.7, "viscous fits near 3: {unbounded}");

    let bounded = d.join("bounded.toml");
    std::fs::write(
        &bounded,
        model("{ value = 1.0, free = true, min = 0.0, max = 2.5 }"),
    )
    .unwrap();
    let mut m = Model::load(&bounded).unwrap();
    let r = refine::fit_add(&mut m, &p, None, None).unwrap();
    let v = viscous(&m);
    assert_eq!(v.value, 2.5, "held at its max");
    assert!(v.free && v.sigma.is_none(), "{v:?}");
    assert_eq!(v.bound_reached(), Some(2.5));
    // The others are refitted around it: the fit is worse than unbounded, but finite.
    assert!(r.after.fit_percent.is_finite());
    let out = d.join("out.toml");
    m.save(&out).unwrap();
    let back = sim_plant::Model::load(&out).unwrap();
    let damping = &back.effects.viscous.as_ref().unwrap().damping;
    assert_eq!((damping.value, damping.max), (2.5, Some(2.5)));

    let inertia = d.join("inertia.toml");
    std::fs::write(
        &inertia,
        model("3.0").replace(
            "inertia = { value = 1.0, free = true }",
            "inertia = { value = 1.0, free = true, max = 5.0 }",
        ),
    )
    .unwrap();
    let e = Model::load(&inertia).expect_err("a bound on the motor's inertia");
    assert!(
        matches!(
            &e,
            ModelError::Unfittable {
                source: Unfittable::Bound { .. },
                ..
            }
        ),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("inertia.toml") && text.contains("`motor.inertia`"),
        "{text}"
    );
    std::fs::remove_dir_all(&d).ok();
}
