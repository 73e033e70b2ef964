//! Memory of a long lockstep run: one simulated hour (3.6 M ticks) of the stiffness
//! experiment on the in-process bus, recorded as the demo records (CSV and candump log on
//! disk, summary and plot read back from the CSV), printing resident memory as it goes.
//!
//! `cargo bench -p hil-host --bench long_run` (or `-- 600` for ten minutes). It prints
//! figures and asserts nothing: the recording streams to disk, so the resident set should
//! stay flat after the first seconds; the goal is under 50 MB for the hour.

use std::time::Instant;

use hil_host::lab::mem::rss_bytes;
use hil_host::lab::plot::plot_recording;
use hil_host::lab::scenario::{Scenario, ScenarioKind, SETTLE_S};
use hil_host::lab::{Lab, LabOptions};

fn mb(b: u64) -> f64 {
    b as f64 / 1e6
}

fn main() {
    let seconds: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(3600.0);
    let dir = tempfile::tempdir().expect("temp dir");
    let model = sim_plant::preset("whoi-cable-30").expect("preset");
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model).expect("scenario");
    sc.duration_s = seconds - SETTLE_S;
    let mut lab = Lab::new(&model, sc, &LabOptions::default()).expect("lab");
    let csv = dir.path().join("long.csv");
    lab.recorder.write_csv(&csv).expect("csv");
    lab.recorder
        .write_candump(&dir.path().join("long.log"), "inproc")
        .expect("candump");
    let n = lab.scenario.ticks();
    let t0 = Instant::now();
    let report_every = (n / 6).max(1);
    if let Some((rss, _)) = rss_bytes() {
        println!("long_run: {seconds} s simulated; resident at start {:.1} MB", mb(rss));
    }
    while lab.ticks() < n {
        lab.step().expect("step");
        if lab.ticks() % report_every == 0 {
            if let Some((rss, peak)) = rss_bytes() {
                println!(
                    "  t = {:>6.0} s  resident {:>6.1} MB  peak {:>6.1} MB  ({:.0} ticks/s)",
                    lab.time(),
                    mb(rss),
                    mb(peak),
                    lab.ticks() as f64 / t0.elapsed().as_secs_f64()
                );
            }
        }
    }
    let run_wall = t0.elapsed().as_secs_f64();
    let r = lab.report("long run", false).expect("report");
    plot_recording(
        &dir.path().join("long.png"),
        "long run",
        &csv,
        lab.recorder.tally().rows,
        lab.scenario.scale.gear_ratio,
    )
    .expect("plot");
    let sizes: u64 = std::fs::read_dir(dir.path())
        .map(|d| d.flatten().filter_map(|e| e.metadata().ok()).map(|m| m.len()).sum())
        .unwrap_or(0);
    println!(
        "long_run: {n} ticks in {run_wall:.1} s ({:.0}× real time), report + plot {:.1} s; \
         files on disk {:.0} MB; verdict {}",
        seconds / run_wall,
        t0.elapsed().as_secs_f64() - run_wall,
        mb(sizes),
        r.verdict.word()
    );
    match rss_bytes() {
        Some((rss, peak)) => println!(
            "long_run: resident at the end {:.1} MB, peak (VmHWM) {:.1} MB",
            mb(rss),
            mb(peak)
        ),
        None => println!("long_run: this kernel does not report resident memory"),
    }
}
