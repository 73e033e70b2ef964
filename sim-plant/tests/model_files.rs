//! Model files: strict parsing with file:line:col errors, units, round-trip.

use proptest::prelude::*;
use sim_plant::effects::{backlash, coulomb, ripple, EffectKind};
use sim_plant::param::Param;
use sim_plant::{Model, ModelError};

const GOOD: &str = r#"name = "test-joint"
description = "a joint"

[motor]
inertia = 2.5e-4
max_torque = 2.0

[plant]
gear_ratio = 30
output_inertia = { value = 0.05, free = true, min = 0.01, max = 1.0 }

[effects.coulomb]
torque = { value = 1.3, free = true }

[effects.backlash]
width = "0.8 deg"

[effects.viscous]
damping = { value = 0.02, unit = "N·m/(deg/s)" }
"#;

fn located(text: &str) -> (usize, usize, String) {
    match Model::from_toml_str(text, "joint.toml") {
        Err(ModelError::At(l)) => {
            assert_eq!(l.file, "joint.toml");
            let shown = ModelError::At(l.clone()).to_string();
            assert!(
                shown.starts_with(&format!("joint.toml:{}:{}: ", l.line, l.col)),
                "{shown}"
            );
            (l.line, l.col, l.message)
        }
        other => panic!("expected a located error, got {other:?}"),
    }
}

#[test]
fn a_good_file_parses_with_units_converted() {
    let m = Model::from_toml_str(GOOD, "joint.toml").unwrap();
    assert_eq!(m.name, "test-joint");
    assert_eq!(m.plant.gear_ratio.value, 30.0);
    assert!(m.plant.output_inertia.free);
    assert_eq!(m.plant.output_inertia.max, Some(1.0));
    let b = m.effects.backlash.as_ref().unwrap().width.value;
    assert!((b - 0.8f64.to_radians()).abs() < 1e-15);
    let v = m.effects.viscous.as_ref().unwrap().damping.value;
    assert!((v - 0.02 * 180.0 / std::f64::consts::PI).abs() < 1e-12);
    assert_eq!(
        m.effects.kinds(),
        vec![
            EffectKind::Viscous,
            EffectKind::Coulomb,
            EffectKind::Backlash
        ]
    );
    assert_eq!(m.kind(), sim_plant::PlantKind::TwoMass);
    let names: Vec<String> = m.parameters().into_iter().map(|p| p.0).collect();
    assert!(names.contains(&"effects.coulomb.torque".to_string()));
}

#[test]
fn a_typo_in_a_key_names_line_and_column() {
    let text = GOOD.replace("torque = { value = 1.3", "torqe = { value = 1.3");
    let (line, col, msg) = located(&text);
    assert_eq!((line, col), (13, 1), "{msg}");
    assert!(msg.contains("torqe"), "{msg}");
}

#[test]
fn a_typo_in_an_effect_name_names_line_and_column() {
    let text = GOOD.replace("[effects.backlash]", "[effects.backlahs]");
    let (line, col, msg) = located(&text);
    assert_eq!(line, 15, "{msg}");
    assert!(col >= 1);
    assert!(msg.contains("backlahs"), "{msg}");
}

#[test]
fn a_wrong_type_names_line_and_column() {
    let text = GOOD.replace("max_torque = 2.0", "max_torque = true");
    let (line, col, msg) = located(&text);
    assert_eq!((line, col), (6, 14), "{msg}");
}

#[test]
fn a_wrong_unit_names_line_and_column_of_the_value() {
    let text = GOOD.replace("\"0.8 deg\"", "\"0.8 N·m\"");
    let (line, col, msg) = located(&text);
    assert_eq!((line, col), (16, 9), "{msg}");
    assert!(msg.contains("width") && msg.contains("rad"), "{msg}");
    let text = GOOD.replace("unit = \"N·m/(deg/s)\"", "unit = \"furlong\"");
    let (line, col, msg) = located(&text);
    assert_eq!((line, col), (19, 11), "{msg}");
    assert!(msg.contains("unknown unit"), "{msg}");
}

#[test]
fn an_impossible_value_names_line_and_column() {
    let text = GOOD.replace("torque = { value = 1.3", "torque = { value = -1.3");
    let (line, col, msg) = located(&text);
    assert_eq!((line, col), (13, 10), "{msg}");
    assert!(msg.contains("physical range"), "{msg}");
}

/// Fitting bounds that no fit could honour are refused where they are written: a NaN bound
/// (it compares false with everything, so it passed every check and was written back), a
/// min above the max, and a start value outside its own bounds.
#[test]
fn bad_bounds_name_line_column_and_parameter() {
    for (table, want) in [
        ("{ value = 1.3, free = true, min = nan }", "min is NaN"),
        ("{ value = 1.3, free = true, max = nan }", "max is NaN"),
        (
            "{ value = 1.3, free = true, min = 2.0, max = 1.0 }",
            "min 2 is above max 1",
        ),
        (
            "{ value = 1.3, free = true, min = 1.5 }",
            "is below its min 1.5",
        ),
        (
            "{ value = 1.3, free = true, max = 1.0 }",
            "is above its max 1",
        ),
    ] {
        let text = GOOD.replace("{ value = 1.3, free = true }", table);
        let (line, col, msg) = located(&text);
        assert_eq!((line, col), (13, 10), "{table}: {msg}");
        assert!(
            msg.contains("`torque`") && msg.contains(want),
            "{table}: {msg}"
        );
    }
    // Inside its bounds (or on one) a start is fine.
    let text = GOOD.replace(
        "{ value = 1.3, free = true }",
        "{ value = 1.3, free = true, min = 1.3, max = 2.0 }",
    );
    assert!(Model::from_toml_str(&text, "joint.toml").is_ok());
}

#[test]
fn an_unknown_key_in_a_parameter_table_names_line_and_column() {
    let text = GOOD.replace(
        "free = true }\n\n[effects.backlash]",
        "fre = true }\n\n[effects.backlash]",
    );
    let (line, _col, msg) = located(&text);
    assert_eq!(line, 13, "{msg}");
    assert!(msg.contains("fre"), "{msg}");
}

#[test]
fn a_missing_file_names_the_file() {
    let err = Model::load("/nonexistent/joint.toml").unwrap_err();
    assert!(
        err.to_string().starts_with("/nonexistent/joint.toml: "),
        "{err}"
    );
}

#[test]
fn files_round_trip_through_disk() {
    let m = Model::from_toml_str(GOOD, "joint.toml").unwrap();
    let dir = std::env::temp_dir().join(format!("sim-plant-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("refit.toml");
    m.save(&path).unwrap();
    assert_eq!(Model::load(&path).unwrap(), m);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![0.0..1e3f64, 1e-9..1e-3f64, Just(0.0), 1e3..1e6f64]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The writer's output parses back to the same model, whatever the values, freedom and
    /// bounds (the fitter writes refit models with it).
    #[test]
    fn written_models_parse_back_equal(
        tc in finite(), free in any::<bool>(), lo in proptest::option::of(0.0..1.0f64),
        width in 0.0..0.5f64, s in -10.0..10.0f64, period in 1e-3..1.0f64,
        name in "[a-z][a-z0-9 _\"\\\\-]{0,20}",
    ) {
        let mut m = Model { name, ..Model::default() };
        let mut torque = if free { Param::free(tc) } else { Param::fixed(tc) };
        // A start below its own min is refused on reading; keep the bound under it.
        torque.min = lo.map(|l| l.min(tc));
        m.effects.coulomb = Some(coulomb::Params { torque });
        m.effects.backlash = Some(backlash::Params { width: Param::fixed(width) });
        m.effects.ripple = Some(ripple::Params {
            sin: Param::free(s),
            period: Param::fixed(period),
            ..Default::default()
        });
        m.plant.output_inertia = Param::fixed(0.05);
        let text = m.to_toml_string();
        let back = Model::from_toml_str(&text, "written.toml").map_err(|e| {
            TestCaseError::fail(format!("{e}\n{text}"))
        })?;
        prop_assert_eq!(back, m);
    }
}

/// A model name of any content writes back as itself: the `toml` crate's writer overflowed on
/// a run of 256 quotes (found by fuzzing `model_toml`), so the model writes its strings itself.
#[test]
fn names_of_any_content_write_back() {
    for name in [
        format!("rede\t\t\t{}\t", "'".repeat(300)),
        "a \"quoted\" \\ back\\slash\nnew\u{1}line\u{7f}".to_string(),
        "\"".repeat(300),
    ] {
        let m = sim_plant::Model {
            name: name.clone(),
            ..sim_plant::Model::default()
        };
        let back = sim_plant::Model::from_toml_str(&m.to_toml_string(), "t.toml").unwrap();
        assert_eq!(back.name, name);
        assert_eq!(back, m);
    }
}

/// A linear axis (a ball-screw carriage): the file names N, m, kg, accepts their multiples,
/// refuses a joint's units, and writes itself back in its own units.
#[test]
fn a_linear_axis_file_reads_and_writes_newtons_and_metres() {
    let text = "name = \"carriage\"\naxis = \"linear\"\n[motor]\ninertia = \"95 kg\"\n\
                [plant]\noutput_inertia = \"5 kg\"\n[effects.coulomb]\ntorque = \"20 N\"\n[effects.backlash]\nwidth = \"0.5 mm\"\n\
                [effects.viscous]\ndamping = \"205 N·s/m\"\n";
    let m = Model::from_toml_str(text, "axis.toml").unwrap();
    assert_eq!(m.axis, Some(sim_plant::units::Axis::Linear));
    assert_eq!(m.motor.inertia.value, 95.0);
    assert_eq!(m.effects.coulomb.as_ref().unwrap().torque.value, 20.0);
    let w = m.effects.backlash.as_ref().unwrap().width.value;
    assert!((w - 0.5e-3).abs() < 1e-15, "{w}");
    let out = m.to_toml_string();
    assert!(out.contains("axis = \"linear\""), "{out}");
    assert!(
        out.contains("# N·s/m") && out.contains("# kg") && out.contains("# m\n"),
        "{out}"
    );
    assert!(!out.contains("N·m") && !out.contains("rad"), "{out}");
    assert_eq!(Model::from_toml_str(&out, "again.toml").unwrap(), m);

    // A joint's unit in a linear file, and a linear unit in a joint's, name the line.
    let (line, _, msg) = located(&text.replace("\"20 N\"", "\"20 N·m\""));
    assert_eq!(line, 8);
    assert!(msg.contains("rotary unit") && msg.contains("in N"), "{msg}");
    let (line, _, msg) = located(&text.replace("axis = \"linear\"\n", ""));
    assert_eq!(line, 3);
    assert!(msg.contains("unknown unit `kg`"), "{msg}");
}
