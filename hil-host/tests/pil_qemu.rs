//! Processor-in-the-loop: the firmware's `qemu-pil` image under qemu-system-arm
//! (mps2-an386, Cortex-M4F) as the lab's card, frames crossing its UART as SLCAN.
//!
//! The claim tested: the card is the same integer code on both sides, so a lockstep run with
//! the QEMU card gives the same recording (CSV and candump log, byte for byte) and the same
//! summary (every figure, bit for bit) as the host card on the same seed. Two scenarios
//! cover position PD (step) and force PI in contact (wall). The `run --card qemu` tests
//! check the threaded bridge in lockstep and in real time (late/missing frames reported).
//!
//! Needs `qemu-system-arm` and the thumbv7em-none-eabihf target. Without QEMU the tests
//! print `SKIPPED`, unless `JOINTLAB_REQUIRE_QEMU` is set (CI), where that is a failure.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Instant;

use hil_host::lab::qemu_card::{build_image, QemuCard};
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};

fn skip_without_qemu(what: &str) -> bool {
    let found = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    match found {
        true => false,
        false if std::env::var_os("JOINTLAB_REQUIRE_QEMU").is_some() => {
            panic!("{what}: qemu-system-arm not found, and JOINTLAB_REQUIRE_QEMU is set")
        }
        false => {
            println!(
                "SKIPPED: {what}: qemu-system-arm not found (apt-get install -y --no-install-recommends qemu-system-arm; .ci/run installs it)"
            );
            true
        }
    }
}

/// The image, built once per test binary (the tests run in parallel threads).
fn image() -> &'static Path {
    static IMG: OnceLock<PathBuf> = OnceLock::new();
    IMG.get_or_init(|| build_image().expect("build the qemu-pil image"))
}

/// What one lockstep lab run left behind.
struct Outcome {
    csv: Vec<u8>,
    candump: Vec<u8>,
    /// Summary figures as bits (equality is bit-identity, not approximate).
    figures: Vec<(String, u64)>,
    table: String,
    cycles_per_s: f64,
}

fn lab_run(kind: ScenarioKind, preset: &str, seed: u64, qemu: bool) -> Outcome {
    let model = sim_plant::preset(preset).expect("preset");
    let sc = Scenario::new(kind, &model).expect("scenario");
    let opts = LabOptions {
        seed,
        ..LabOptions::default()
    };
    let mut lab = Lab::new(&model, sc, &opts).expect("lab");
    if qemu {
        lab.use_qemu_card(QemuCard::spawn(image(), opts.node, false).expect("start QEMU"));
    }
    let dir = std::env::temp_dir().join(format!(
        "jl-pil-{}-{}-{}",
        std::process::id(),
        kind.name(),
        if qemu { "qemu" } else { "host" }
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, log) = (dir.join("run.csv"), dir.join("run.log"));
    lab.recorder.write_csv(&csv).unwrap();
    lab.recorder.write_candump(&log, "inproc").unwrap();
    let t0 = Instant::now();
    lab.run(|_, _| {}).expect("lab run");
    let rate = lab.scenario.ticks() as f64 / t0.elapsed().as_secs_f64();
    let s = lab.summary().expect("summary");
    let bits = s
        .rows
        .iter()
        .map(|(n, v, _)| (n.clone(), v.to_bits()))
        .collect();
    drop(lab); // stops QEMU, closes the files
    let out = Outcome {
        csv: std::fs::read(&csv).unwrap(),
        candump: std::fs::read(&log).unwrap(),
        figures: bits,
        table: s.table(),
        cycles_per_s: rate,
    };
    std::fs::remove_dir_all(&dir).ok();
    out
}

fn assert_same(kind: ScenarioKind, preset: &str) {
    let host = lab_run(kind, preset, 7, false);
    let qemu = lab_run(kind, preset, 7, true);
    assert!(
        host.csv.len() > 50_000,
        "a full recording: {} bytes",
        host.csv.len()
    );
    assert_eq!(
        host.figures, qemu.figures,
        "summary figures differ:\nhost\n{}\nqemu\n{}",
        host.table, qemu.table
    );
    assert!(host.csv == qemu.csv, "the CSV recordings differ");
    assert!(host.candump == qemu.candump, "the candump logs differ");
    println!(
        "[pil] {} on {preset}: CSV {} B, candump {} B, {} summary figures identical; host card {:.0} cycles/s, QEMU card {:.0} cycles/s\n{}",
        kind.name(),
        host.csv.len(),
        host.candump.len(),
        host.figures.len(),
        host.cycles_per_s,
        qemu.cycles_per_s,
        qemu.table
    );
}

#[test]
fn qemu_card_step_run_equals_host_card_bit_for_bit() {
    if skip_without_qemu("qemu_card_step_run_equals_host_card_bit_for_bit") {
        return;
    }
    assert_same(ScenarioKind::Step, "harmonic-drive-60");
}

#[test]
fn qemu_card_wall_run_equals_host_card_bit_for_bit() {
    if skip_without_qemu("qemu_card_wall_run_equals_host_card_bit_for_bit") {
        return;
    }
    assert_same(ScenarioKind::Wall, "whoi-cable-30");
}

/// `run --card qemu` for half a second; its stdout and exit code.
fn hil_run(extra: &[&str]) -> (String, Option<i32>) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hil-host"));
    cmd.args(["run", "--bus", "inproc", "--scenario", "step"])
        .args([
            "--preset",
            "harmonic-drive-60",
            "--seconds",
            "0.5",
            "--quiet",
        ])
        .arg("--card")
        .arg(format!("qemu:{}", image().display()))
        .args(extra);
    let out = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        text.contains("QEMU card") && text.contains("frames over SLCAN"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (text, out.status.code())
}

#[test]
fn run_with_the_qemu_card_in_lockstep_misses_no_frame() {
    if skip_without_qemu("run_with_the_qemu_card_in_lockstep_misses_no_frame") {
        return;
    }
    let (text, code) = hil_run(&[]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("lockstep"), "{text}");
    assert!(text.contains(" 0 actuator frames missing"), "{text}");
    println!("{text}");
}

#[test]
fn run_with_the_qemu_card_in_real_time_reports_late_and_missing_frames() {
    if skip_without_qemu("run_with_the_qemu_card_in_real_time_reports_late_and_missing_frames") {
        return;
    }
    // A loaded host may stall the plant past the card's sensor timeout: then the run
    // faults and says so (exit 1); either way the lateness is reported.
    let (text, code) = hil_run(&["--realtime"]);
    assert!(matches!(code, Some(0 | 1)), "exit {code:?}: {text}");
    assert!(text.contains("real time"), "{text}");
    assert!(text.contains("lateness p50"), "{text}");
    assert!(text.contains("actuator frames missing"), "{text}");
    println!("{text}");
}
