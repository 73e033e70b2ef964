//! The workbench's speed figures, each the best of three runs (release build):
//!
//! ```sh
//! cargo run --release -p jointlab-tests --bin workbench-speed
//! ```
//! * `diagnose` on a 12 k-sample record and at N = 10⁵ (the RK4 truth's joint, 1 kHz, Coulomb
//!   friction hidden), the whole path after loading: differentiation, baseline fit, every
//!   library effect's shape search and test;
//! * `diagnose --auto` on EMPS with its validation record (when `../shared` is beside the
//!   repository);
//! * `diagnose --auto` on the HIL lab's identification record (whoi-cable-30).
//!
//! It prints each wall time, its ratio to the goal and the CPU time the process spent in it
//! (all threads; on a busy host the CPU time moves less than the wall time); it asserts
//! nothing (a wall clock depends on the machine).

use std::time::Instant;

use jointlab_tests::hidden::long_record;
use jointlab_workbench::data::{self, Columns, Recording};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;

/// User + system CPU seconds of this process so far, all threads.
fn cpu_seconds() -> f64 {
    use nix::sys::resource::{getrusage, UsageWho};
    getrusage(UsageWho::RUSAGE_SELF)
        .map(|u| {
            let t = |v: nix::sys::time::TimeVal| v.tv_sec() as f64 + v.tv_usec() as f64 * 1e-6;
            t(u.user_time()) + t(u.system_time())
        })
        .unwrap_or(f64::NAN)
}

/// Best of three wall-clock times of `f` with that run's CPU time, and the last result.
fn best_of_3<T>(mut f: impl FnMut() -> T) -> ((f64, f64), T) {
    let mut best = (f64::INFINITY, f64::NAN);
    let mut last = None;
    for _ in 0..3 {
        let (t0, c0) = (Instant::now(), cpu_seconds());
        last = Some(f());
        let wall = t0.elapsed().as_secs_f64();
        if wall < best.0 {
            best = (wall, cpu_seconds() - c0);
        }
    }
    (best, last.expect("three runs"))
}

fn row(what: &str, n: usize, (secs, cpu): (f64, f64), goal: f64, result: &str) {
    println!(
        "{what:<30} N = {n:>7}  {secs:>7.3} s (CPU {cpu:>7.3} s)  goal {goal:>5.2} s  \
         ratio {:>5.2}  {result}",
        secs / goal
    );
}

fn diagnose_time(what: &str, rec: &Recording, goal: f64) {
    // The default band (the record's encoder and rate), as a user gets it.
    let (secs, verdict) = best_of_3(|| {
        let p = Prepared::new(rec, None);
        let mut m = Model::baseline();
        refine::refit_all(&mut m, &p).expect("baseline fit");
        diagnose(&m, &p, &Options::default()).verdict.text
    });
    row(what, rec.len(), secs, goal, &verdict);
}

fn auto_time(what: &str, rec: &Recording, val: Option<&Recording>, goal: f64) {
    let (secs, steps) = best_of_3(|| {
        let p = Prepared::new(rec, None);
        let pv = val.map(|v| Prepared::new(v, None));
        let mut m = Model::baseline();
        refine::refit_all(&mut m, &p).expect("baseline fit");
        let run = refine::auto(&mut m, &p, pv.as_ref(), &Options::default(), 6).expect("--auto");
        run.steps
            .iter()
            .filter_map(|s| s.added.clone())
            .collect::<Vec<_>>()
            .join(" → ")
    });
    row(what, rec.len(), secs, goal, &steps);
}

/// The 1-minute load average (Linux), so that a figure measured on a busy host says so.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}

fn main() {
    println!("(load average when started: {})", load_average());
    diagnose_time("diagnose, 12 k samples", &long_record(42, 12.0, 1), 0.15);
    diagnose_time("diagnose, 10⁵ samples", &long_record(42, 20.0, 5), 1.0);
    let emps = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real/emps");
    if emps.join("DATA_EMPS.csv").exists() {
        let mut cols = Columns::new("vir_V", "qm_m");
        cols.time = "t_s".into();
        cols.input_gain = 35.15065188248547;
        let est = data::load(&emps.join("DATA_EMPS.csv"), &cols).expect("EMPS");
        let val = data::load(&emps.join("DATA_EMPS_PULSES.csv"), &cols).expect("EMPS pulses");
        auto_time("--auto, EMPS (validated)", &est, Some(&val), 5.0);
    } else {
        println!("--auto, EMPS: SKIPPED ({} not found)", emps.display());
    }
    let dir = std::env::temp_dir().join(format!("jointlab-speed-{}", std::process::id()));
    let preset = "whoi-cable-30";
    let hil = jointlab_tests::hil_identify_record(&dir, preset);
    auto_time("--auto, HIL identify record", &hil, None, 10.0);
    std::fs::remove_dir_all(&dir).ok();
}
