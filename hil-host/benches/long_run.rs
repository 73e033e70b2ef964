//! Long runs: the memory of one simulated hour (3.6 M ticks) of the stiffness experiment in
//! the lockstep lab, recorded as the demo records (CSV and candump log on disk, summary and
//! plot read back from the CSV), then the plant's late-tick histogram of a 60 s real-time
//! run (`hil-host run --bus inproc --realtime`, three threads on a 1 kHz wall clock).
//!
//! `cargo bench -p hil-host --bench long_run [-- SECONDS] [--realtime SECONDS]` (lockstep
//! seconds, default 3600; real-time seconds, default 60, 0 to skip). It prints figures and
//! asserts nothing: the recording streams to disk, so the resident set should stay flat after
//! the first seconds (the goal is under 50 MB for the hour); the lateness depends on the
//! machine and its load, which is why it is measured rather than tested.

use std::process::Command;
use std::time::Instant;

use hil_host::lab::mem::rss_bytes;
use hil_host::lab::plot::plot_recording;
use hil_host::lab::scenario::{Scenario, ScenarioKind, SETTLE_S};
use hil_host::lab::{Lab, LabOptions};

fn mb(b: u64) -> f64 {
    b as f64 / 1e6
}

/// The lockstep and real-time durations from the command line (cargo passes `--bench`).
fn durations() -> (f64, f64) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut lockstep = 3600.0;
    let mut realtime = 60.0;
    let mut i = 0;
    while i < args.len() {
        if args[i] == "--realtime" {
            if let Some(s) = args.get(i + 1).and_then(|a| a.parse().ok()) {
                realtime = s;
            }
            i += 1;
        } else if let Ok(s) = args[i].parse() {
            lockstep = s;
        }
        i += 1;
    }
    (lockstep, realtime)
}

fn main() {
    let (seconds, realtime) = durations();
    if seconds > 0.0 {
        lockstep(seconds);
    }
    if realtime > 0.0 {
        realtime_lateness(realtime);
    }
}

/// A real-time run of `seconds` through the CLI; prints the plant's tick lateness.
fn realtime_lateness(seconds: f64) {
    let out = Command::new(env!("CARGO_BIN_EXE_hil-host"))
        .args([
            "run",
            "--bus",
            "inproc",
            "--realtime",
            "--scenario",
            "stiffness",
        ])
        .args(["--quiet", "--json", "--seconds", &seconds.to_string()])
        .output()
        .expect("run hil-host");
    let text = String::from_utf8_lossy(&out.stdout);
    let Some(j) = text
        .lines()
        .find_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
    else {
        println!(
            "realtime: no report ({})",
            String::from_utf8_lossy(&out.stderr)
        );
        return;
    };
    let l = &j["lateness_us"];
    println!(
        "realtime: {seconds} s at 1 kHz, verdict {} (exit {:?}); tick lateness p50 {} µs, \
         p99 {} µs, max {} µs at {} s; {} of {} ticks over 0.5 ms late; holds 1 kHz: {}",
        j["verdict"],
        out.status.code(),
        l["p50"],
        l["p99"],
        l["max"],
        l["worst_at_s"],
        l["late_ticks"],
        l["ticks"],
        l["holds_1khz"]
    );
}

/// `seconds` of the stiffness experiment in lockstep; prints resident memory as it goes.
fn lockstep(seconds: f64) {
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
        println!(
            "long_run: {seconds} s simulated; resident at start {:.1} MB",
            mb(rss)
        );
    }
    while lab.ticks() < n {
        lab.step().expect("step");
        if lab.ticks().is_multiple_of(report_every) {
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
        lab.scenario.scale.gear_ratio(),
    )
    .expect("plot");
    let sizes: u64 = std::fs::read_dir(dir.path())
        .map(|d| {
            d.flatten()
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
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
