//! Fuzz the workbench's CSV recording loader (`jointlab_workbench::data::load_bytes`, what
//! `compare`/`diagnose`/`fit` read): any bytes must load or give an error, never a panic; a
//! recording that loads has as many samples in every signal, finite values, a finite positive
//! sample period and strictly increasing time.
#![no_main]

use std::path::Path;

use jointlab_workbench::data::{load_bytes, Columns};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    // The first byte picks the column set, so the seeds can be the project's record layouts:
    // the HIL lab's identify record, and the EMPS record (a drive gain, a time window).
    let Some((&pick, text)) = input.split_first() else {
        return;
    };
    let mut cols = Columns::new("torque_cmd_Nm", "motor_pos_rad");
    cols.time = "time_s".into();
    match pick % 4 {
        0 => {}
        1 => cols.load_output = Some("output_pos_rad".into()),
        2 => {
            cols = Columns::new("vir_V", "qm_m");
            cols.time = "t_s".into();
            cols.input_gain = 35.15065188248547;
        }
        _ => {
            cols = Columns::new("duty", "position_rad");
            cols.time = "t_s".into();
            cols.input_times = Some("input_volts_V".into());
            cols.window = Some((0.1, 10.0));
        }
    }
    let Ok(rec) = load_bytes(text, Path::new("fuzz.csv"), &cols) else {
        return;
    };
    let n = rec.time.len();
    assert_eq!(rec.input.len(), n);
    assert_eq!(rec.output.len(), n);
    if let Some(l) = &rec.load_output {
        assert_eq!(l.len(), n);
    }
    assert!(
        rec.dt.is_finite() && rec.dt > 0.0,
        "sample period {}",
        rec.dt
    );
    for x in [&rec.time, &rec.input, &rec.output] {
        assert!(x.iter().all(|v| v.is_finite()), "a non-finite sample");
    }
    for w in rec.time.windows(2) {
        assert!(w[1] > w[0], "time {} then {}", w[0], w[1]);
    }
});
