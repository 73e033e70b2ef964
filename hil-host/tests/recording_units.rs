//! A lab recording loads in the workbench with every column's unit: the recorder names its
//! columns with suffixes from the workbench's table (`jointlab_workbench::units`).

use hil_host::lab::recorder::COLUMNS;
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};
use jointlab_workbench::data::{self, Columns};
use jointlab_workbench::units::unit_of;

/// The SI unit each recorder column holds (the recorder's `Row` docs), in `COLUMNS` order:
/// the recorder writes SI, so every factor is 1.
const HOLDS: [&str; 16] = [
    "s", "", "rad", "N·m", "rad", "rad", "rad/s", "rad/s", "rad/s", "N·m", "N·m", "N·m", "", "",
    "", "",
];

#[test]
fn every_recorder_column_reads_with_its_unit_and_factor_one() {
    for (name, unit) in COLUMNS.iter().zip(HOLDS) {
        assert_eq!(unit_of(name), Ok((unit, 1.0)), "column `{name}`");
    }
}

#[test]
fn a_lab_recording_loads_with_its_units() {
    let model = sim_plant::preset("whoi-cable-30").expect("preset");
    let mut sc = Scenario::new(ScenarioKind::Identify, &model).expect("scenario");
    sc.duration_s = 1.0;
    let mut lab = Lab::new(&model, sc, &LabOptions::default()).expect("lab");
    let dir = std::env::temp_dir().join(format!("jl-units-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("identify.csv");
    lab.recorder.write_csv(&csv).unwrap();
    lab.run(|_, _| {}).expect("run");
    let rows = lab.recorder.rows.clone();
    drop(lab);

    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().next(), Some(COLUMNS.join(",").as_str()));
    let rec = data::load(&csv, &Columns::new("torque_cmd_Nm", "motor_pos_rad")).unwrap();
    assert_eq!(rec.units, ("N·m".to_string(), "rad".to_string()));
    let vel = data::load(&csv, &Columns::new("torque_sensor_Nm", "motor_vel_rad_s")).unwrap();
    assert_eq!(vel.units, ("N·m".to_string(), "rad/s".to_string()));
    // Factor 1: the loaded values are the recorded ones, to the CSV's printed digits (the
    // latest rows are kept in memory).
    let last = rows.last().expect("rows");
    let torque = rec.input.last().copied().unwrap_or(f64::NAN);
    assert!(
        (torque - last.torque_cmd_nm).abs() <= 5e-5,
        "{torque} vs {last:?}"
    );
    let w = vel.output.last().copied().unwrap_or(f64::NAN);
    assert!((w - last.motor_vel_rad_s).abs() <= 5e-7, "{w} vs {last:?}");
    assert!(
        last.motor_vel_rad_s.abs() > 1e-3,
        "the joint moves: {last:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
