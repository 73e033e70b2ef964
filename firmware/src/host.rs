//! Host side of the QEMU images (std only): build an image, run it under
//! `qemu-system-arm`, exchange the replay stream. Used by `tests/card_replay.rs` and
//! `benches/insn.rs`; `.ci/run` installs QEMU so CI runs them, a plain `cargo test` without
//! QEMU prints a `SKIPPED` line instead.
// Host-side test support, never in an image: the firmware's no-panic lints do not apply.
#![allow(
    clippy::panic,
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects
)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::string::{String, ToString};
use std::time::{Duration, Instant};
use std::vec::Vec;
use std::{format, println};

/// A QEMU machine the card runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Machine {
    /// mps2-an386, Cortex-M4F (thumbv7em-none-eabihf).
    Mps2An386,
    /// BBC micro:bit, nRF51 Cortex-M0 (thumbv6m-none-eabi).
    Microbit,
}

impl Machine {
    /// Both machines.
    pub const ALL: [Machine; 2] = [Machine::Mps2An386, Machine::Microbit];

    /// The Rust target of its images.
    pub const fn target(self) -> &'static str {
        match self {
            Machine::Mps2An386 => "thumbv7em-none-eabihf",
            Machine::Microbit => "thumbv6m-none-eabi",
        }
    }

    /// Short name (table columns).
    pub const fn core(self) -> &'static str {
        match self {
            Machine::Mps2An386 => "M4",
            Machine::Microbit => "M0",
        }
    }

    /// `-machine` and `-cpu`.
    pub const fn qemu_machine(self) -> [&'static str; 4] {
        match self {
            Machine::Mps2An386 => ["-machine", "mps2-an386", "-cpu", "cortex-m4"],
            Machine::Microbit => ["-machine", "microbit", "-cpu", "cortex-m0"],
        }
    }
}

/// Cargo profile of the images: release with fat LTO, one codegen unit, opt-level "s"
/// (root Cargo.toml `[profile.firmware]`).
pub const PROFILE: &str = "firmware";

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// `qemu-system-arm` if it is on the PATH (its `--version` first line).
pub fn qemu_version() -> Option<String> {
    let out = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .ok()?;
    out.status.success().then(|| {
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .next()
            .unwrap_or("")
            .to_string()
    })
}

/// Returns true (and prints the `SKIPPED` line) when QEMU is missing. With
/// `JOINTLAB_REQUIRE_QEMU` set (CI installs QEMU and sets it) a missing QEMU is an error.
pub fn skip_without_qemu(what: &str) -> bool {
    match qemu_version() {
        Some(_) => false,
        None if std::env::var_os("JOINTLAB_REQUIRE_QEMU").is_some() => {
            panic!("{what}: qemu-system-arm not found, and JOINTLAB_REQUIRE_QEMU is set")
        }
        None => {
            println!(
                "SKIPPED: {what}: qemu-system-arm not found (apt-get install -y --no-install-recommends qemu-system-arm; .ci/run installs it)"
            );
            true
        }
    }
}

/// Builds `bin` of the firmware crate for `machine` (nested cargo, own target directory so
/// it never waits on the outer build's lock) and returns the ELF path.
pub fn build_image(machine: Machine, bin: &str) -> Result<PathBuf, String> {
    let root = workspace_root();
    let target_dir = root.join("target").join("qemu-images");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args(["build", "-q", "-p", "firmware", "--bin", bin])
        .args(["--no-default-features", "--features", "qemu"])
        .args(["--profile", PROFILE, "--target", machine.target()])
        .arg("--target-dir")
        .arg(&target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .status()
        .map_err(|e| format!("cargo build {bin}: {e}"))?;
    if !status.success() {
        return Err(format!(
            "cargo build {bin} for {}: {status}",
            machine.target()
        ));
    }
    Ok(target_dir.join(machine.target()).join(PROFILE).join(bin))
}

/// What a QEMU run left behind.
#[derive(Debug)]
pub struct Run {
    /// Its console output (semihosting).
    pub stdout: String,
    /// Wall time of the run.
    pub wall: Duration,
}

/// Runs `image` on `machine` in `dir` with `-icount shift=0` (one instruction = 1 ns of
/// virtual time: SysTick counts instructions), killing it after `timeout`.
pub fn run_qemu(
    machine: Machine,
    image: &Path,
    dir: &Path,
    timeout: Duration,
) -> Result<Run, String> {
    let t0 = Instant::now();
    let mut child = Command::new("qemu-system-arm")
        .current_dir(dir)
        .args(machine.qemu_machine())
        .args(["-nographic", "-monitor", "none", "-serial", "none"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0", "-kernel"])
        .arg(image)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("qemu-system-arm: {e}"))?;
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if t0.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("{} timed out after {timeout:?}", image.display()));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut stdout = String::new();
    let mut stderr = String::new();
    if let Some(mut o) = child.stdout.take() {
        let _ = o.read_to_string(&mut stdout);
    }
    if let Some(mut e) = child.stderr.take() {
        let _ = e.read_to_string(&mut stderr);
    }
    if !status.success() {
        return Err(format!(
            "{} on {machine:?} exited with {status}: {stdout}{stderr}",
            image.display()
        ));
    }
    Ok(Run {
        stdout,
        wall: t0.elapsed(),
    })
}

/// Replays `input` (a [`crate::stream`] byte stream) to the `qemu-card` image and returns
/// the card's output stream.
pub fn replay(machine: Machine, image: &Path, input: &[u8]) -> Result<(Vec<u8>, Run), String> {
    let dir = std::env::temp_dir().join(format!(
        "jointlab-qemu-card-{}-{}",
        machine.core(),
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("card-in.bin"), input).map_err(|e| e.to_string())?;
    let run = run_qemu(machine, image, &dir, Duration::from_secs(120))?;
    let out = std::fs::read(dir.join("card-out.bin")).map_err(|e| e.to_string());
    let _ = std::fs::remove_dir_all(&dir);
    Ok((out?, run))
}

/// One row of the instruction-count table.
#[derive(Clone, Debug, PartialEq)]
pub struct InsnRow {
    /// What was measured.
    pub what: String,
    /// Instructions per step (or per call) on the bench's inputs, M4 and M0.
    pub bench: [f64; 2],
    /// The same on small tracking errors (laws only; equal to `bench` otherwise).
    pub tracking: [f64; 2],
}

/// Parses the `qemu-bench` output of one machine into (what, inputs, instructions).
fn parse_bench(out: &str) -> Result<Vec<(String, String, f64)>, String> {
    let mut per_tick = None;
    let mut base: Vec<(String, f64)> = Vec::new();
    let mut rows = Vec::new();
    let num = |s: Option<&str>| -> Result<f64, String> {
        s.and_then(|v| v.parse::<f64>().ok())
            .ok_or_else(|| format!("bad qemu-bench line in: {out}"))
    };
    for l in out.lines() {
        let f: Vec<&str> = l.split_whitespace().collect();
        match f.first().copied() {
            Some("calib") => per_tick = Some(num(f.get(1).copied())? / num(f.get(2).copied())?),
            Some(kind @ ("case" | "tick" | "build" | "commit")) => {
                let k = per_tick.ok_or("no calibration line")?;
                match kind {
                    "case" => {
                        let (case, inputs) = (
                            f.get(1).copied().unwrap_or(""),
                            f.get(2).copied().unwrap_or(""),
                        );
                        let per = num(f.get(4).copied())? * k / num(f.get(3).copied())?;
                        if case == "Baseline" {
                            base.push((inputs.to_string(), per));
                        } else {
                            let b = base
                                .iter()
                                .find(|(i, _)| i == inputs)
                                .map(|x| x.1)
                                .unwrap_or(0.0);
                            rows.push((case.to_string(), inputs.to_string(), per - b));
                        }
                    }
                    "tick" => {
                        let n = num(f.get(1).copied())?;
                        rows.push((
                            "card tick (mean)".into(),
                            String::new(),
                            num(f.get(2).copied())? * k / n,
                        ));
                        rows.push((
                            "card tick (max)".into(),
                            String::new(),
                            num(f.get(3).copied())? * k,
                        ));
                    }
                    _ => {
                        let n = num(f.get(1).copied())?;
                        let what = if kind == "build" {
                            "config::build"
                        } else {
                            "commit (card, while enabled)"
                        };
                        rows.push((what.into(), String::new(), num(f.get(2).copied())? * k / n));
                    }
                }
            }
            _ => {}
        }
    }
    if rows.is_empty() {
        return Err(format!("no figures in qemu-bench output: {out}"));
    }
    Ok(rows)
}

/// Builds and runs `qemu-bench` on both machines and returns the table.
pub fn instruction_table() -> Result<Vec<InsnRow>, String> {
    let mut per_machine = Vec::new();
    for m in Machine::ALL {
        let image = build_image(m, "qemu-bench")?;
        let dir = std::env::temp_dir();
        let run = run_qemu(m, &image, &dir, Duration::from_secs(120))?;
        per_machine.push(parse_bench(&run.stdout)?);
    }
    let [m4, m0] = [&per_machine[0], &per_machine[1]];
    let get = |rows: &Vec<(String, String, f64)>, what: &str, inputs: &str| {
        rows.iter()
            .find(|(w, i, _)| w == what && (i == inputs || i.is_empty()))
            .map(|r| r.2)
            .unwrap_or(f64::NAN)
    };
    let mut out: Vec<InsnRow> = Vec::new();
    for (what, _, _) in m4.iter() {
        if out.iter().any(|r| &r.what == what) {
            continue;
        }
        out.push(InsnRow {
            what: what.clone(),
            bench: [get(m4, what, "Bench"), get(m0, what, "Bench")],
            tracking: [get(m4, what, "Tracking"), get(m0, what, "Tracking")],
        });
    }
    Ok(out)
}

/// The table as the README shows it (Markdown).
pub fn format_table(table: &[InsnRow]) -> String {
    let mut s = String::new();
    s.push_str("| per step | M4 bench | M0 bench | M4 tracking | M0 tracking |\n");
    s.push_str("|---|---:|---:|---:|---:|\n");
    for r in table {
        let label = match r.what.as_str() {
            "Pd" => "position PD",
            "Pid" => "position PID",
            "InputDamping" => "input damping",
            "Impedance" => "impedance (Km ≠ 0)",
            "ForcePi" => "force PI",
            "Friction" => "friction comp",
            "ImpComp" => "impedance comp",
            "Ripple" => "ripple table",
            "Full" => "**full pipeline** (PID + B1e + friction + imp. comp + ripple)",
            other => other,
        };
        let laws = r.tracking != r.bench || r.what.chars().next().is_some_and(char::is_uppercase);
        let (t4, t0) = if laws {
            (
                format!("{:.0}", r.tracking[0]),
                format!("{:.0}", r.tracking[1]),
            )
        } else {
            ("—".into(), "—".into())
        };
        s.push_str(&format!(
            "| {label} | {:.0} | {:.0} | {t4} | {t0} |\n",
            r.bench[0], r.bench[1]
        ));
    }
    s
}
