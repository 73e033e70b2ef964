//! End-to-end tests across crates live in `tests/tests/`; shared fixtures live here.

pub mod hidden;
pub mod synth;

use std::path::{Path, PathBuf};

use jointlab_workbench::data::{self, Columns, Recording};

/// `../shared/data/real/<folder>` beside the repository, if it holds `probe`; otherwise a loud
/// SKIPPING line and `None` (the real-data tests need the shared folder, which CI has and a
/// bare clone does not). With `JOINTLAB_REQUIRE_REAL_DATA` set (CI sets it) a missing folder
/// is a failure, not a skip.
pub fn real_data(folder: &str, probe: &str) -> Option<PathBuf> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real")
        .join(folder);
    if d.join(probe).exists() {
        Some(d)
    } else if std::env::var_os("JOINTLAB_REQUIRE_REAL_DATA").is_some() {
        panic!(
            "{} not found and JOINTLAB_REQUIRE_REAL_DATA is set: the real-data tests must run",
            d.join(probe).display()
        );
    } else {
        eprintln!(
            "\n!!!!!! SKIPPING REAL-DATA TEST: {} not found (CI must have ../shared) !!!!!!\n",
            d.join(probe).display()
        );
        None
    }
}

/// The HIL lab's identification record of `preset`, written into `dir` by `hil-host demo
/// --scenario identify` and loaded as a user would (motor torque command in, motor encoder
/// out).
pub fn hil_identify_record(dir: &Path, preset: &str) -> Recording {
    let out = dir.to_str().expect("a UTF-8 temporary directory");
    hil_host::cli::run(<hil_host::cli::Cli as clap::Parser>::parse_from([
        "hil-host",
        "demo",
        "--scenario",
        "identify",
        "--preset",
        preset,
        "--quiet",
        "--out",
        out,
    ]))
    .expect("identify run");
    let cols = Columns::new("torque_cmd_Nm", "motor_pos_rad");
    data::load(&dir.join(format!("demo-identify-{preset}.csv")), &cols).expect("HIL record")
}
