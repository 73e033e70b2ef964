//! The HIL commands: `demo`, `run`, `card`, `plant`, `supervise`, `bench` (`replay` is in `replay`).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use controller::proto::{Mode, NodeId};
use indicatif::{ProgressBar, ProgressStyle};
use sim_plant::{Model, Plant, PlantOptions};

use crate::lab::backlash_cycle;
use crate::lab::card_node::CardNode;
use crate::lab::close_loop;
use crate::lab::compensate::{self, Compensation};
use crate::lab::coulomb_ff;
use crate::lab::fidelity;
use crate::lab::gains::{self, GainsFile};
use crate::lab::inject::{FaultPlan, Injection, Node, Window};
use crate::lab::plant_node::PlantNode;
use crate::lab::plot::{html_report, plot_recording};
use crate::lab::qemu_card::{resolve_image, run_qemu_card, CardChoice, QemuCard};
use crate::lab::recorder::{read_rows, Recorder};
use crate::lab::report::{self, CardFacts, Facts, Report, RunFailed, SupervisorFacts, Verdict};
use crate::lab::scenario::{Scenario, ScenarioKind};
use crate::lab::stability;
use crate::lab::summary::summarize_with;
use crate::lab::supervisor::{Event, Phase, Supervisor};
use crate::lab::threaded::{run_card, run_plant, run_supervisor, Clock, PlantLoop, PlantStats};
use crate::lab::trajectory::Trajectory;
use crate::lab::velocity_pulse;
use crate::lab::{Lab, LabOptions};
use jointlab_can::bus::{open_bus, BusSpec, CanBus, Impaired, InprocHub, LinkClock, LinkStats};
use jointlab_workbench::units::eng;

/// What `--inject` takes, for the help texts.
pub const INJECT_HELP: &str = "Faults (--inject, repeatable; T and D in seconds of run time):
  bus-off@T  error-passive@T  error-warning@T  no-ack@T  protocol@T  rx-overflow@T
                                 one error frame at T, seen by every node (in-process bus)
  drop:NODE=RATE[@T[+D]]         NODE (card, plant, supervisor) loses received frames (0.05 or 5%)
  delay:NODE=DUR[@T[+D]]         NODE receives frames DUR late (2ms, 500us)
  jitter:NODE=DUR[@T[+D]]        NODE receives frames up to DUR late
  stall-plant@T+D                the plant node sends nothing for D
  kill-supervisor@T[+D]          the supervisor sends and hears nothing from T (for D)
  rx-queue=N                     receive queues of N frames (in-process bus)
Exit codes: 0 the run completed clean; 1 it faulted, did not complete, or ran degraded
(bus error frames, frames lost above --max-loss); 130 interrupted (Ctrl-C); 2 bad input.";
/// `demo` examples.
pub const DEMO_EXAMPLES: &str = "Examples:
  hil-host demo                                   # stiffness emulation on the WHOI cable reducer
  hil-host demo --scenario all --preset harmonic-drive-60
  hil-host demo --scenario backlash --preset cyclo-29 --out results/
  hil-host demo --scenario step --inject bus-off@1.0 --json
  hil-host demo --seconds 600 --recover --inject drop:card=2%@60+10 --inject stall-plant@120+0.05
  hil-host demo --card qemu --scenario step       # the firmware image under QEMU as the card";
/// `run` examples.
pub const RUN_EXAMPLES: &str = "Examples:
  hil-host run --bus vcan0 --scenario step --preset harmonic-drive-60
  hil-host run --bus vcan0 --scenario stiffness --realtime --csv run.csv --candump run.log
  hil-host run --bus inproc --scenario damper        # threads on the in-process bus
  hil-host run --bus inproc --realtime --inject stall-plant@2+0.005 --sensor-timeout-us 3000
  hil-host run --bus inproc --scenario step --die-after 500   # the card's watchdog stops the joint
  hil-host run --bus inproc --card qemu --scenario step   # processor-in-the-loop (QEMU, SLCAN)
  hil-host run --bus vcan0 --card qemu --realtime    # the QEMU card against the wall clock";
/// `card` examples.
pub const CARD_EXAMPLES: &str = "Examples:
  hil-host card --bus vcan0 --node 1
  hil-host card --bus can0 --node 3 --realtime";
/// `plant` examples.
pub const PLANT_EXAMPLES: &str = "Examples:
  hil-host plant --bus vcan0 --node 1 --preset whoi-cable-30 --scenario stiffness --csv rec.csv
  hil-host plant --bus vcan0 --model my-joint.toml --seconds 10 --realtime";
/// `supervise` examples.
pub const SUPERVISE_EXAMPLES: &str = "Examples:
  hil-host supervise --bus vcan0 --node 1 --preset whoi-cable-30 --scenario step
  hil-host supervise --bus vcan0 --preset harmonic-drive-60 --mode position-pd-colocated \\
      --stiffness 60 --damping 5 --trajectory sine:0.1:0.5 --rate 200 --seconds 10";
/// `bench` examples.
pub const BENCH_EXAMPLES: &str = "Examples:
  hil-host bench                          # lockstep cycles/s on the in-process bus, bus load
  hil-host bench --bus vcan0 --seconds 5";

/// Which plant: a thesis preset or a model file.
#[derive(Debug, Clone, Args)]
pub struct PlantChoice {
    /// Thesis preset (see `--preset list`).
    #[arg(long, default_value = "whoi-cable-30")]
    pub preset: String,
    /// A sim-plant model TOML (overrides --preset).
    #[arg(long)]
    pub model: Option<PathBuf>,
}

impl PlantChoice {
    /// Whether `--preset list` asked for the preset names (answered once, in `cli::run`,
    /// before any command runs).
    pub fn lists_presets(&self) -> bool {
        self.model.is_none() && self.preset == "list"
    }

    /// Loads the model.
    pub fn load(&self) -> Result<Model> {
        if let Some(p) = &self.model {
            return Ok(Model::load(p)?);
        }
        sim_plant::preset(&self.preset).ok_or_else(|| {
            anyhow!(
                "unknown preset `{}`; one of: {}",
                self.preset,
                sim_plant::preset_names().join(", ")
            )
        })
    }
    fn label(&self) -> String {
        match &self.model {
            Some(p) => p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            None => self.preset.clone(),
        }
    }
}

fn node(n: u8) -> Result<NodeId> {
    NodeId::new(n)
        .filter(|n| !n.is_broadcast())
        .ok_or_else(|| anyhow!("--node must be 1..=127, got {n}"))
}

/// What every lab command that reports a run takes.
#[derive(Debug, Clone, Args)]
pub struct ReportArgs {
    /// Print the report as JSON (one object per run) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Share of ticks without an actuator frame above which the run counts as degraded.
    #[arg(long, default_value_t = report::MAX_LOSS)]
    pub max_loss: f64,
}

/// The HTML report of a run that records (`demo`, `run`).
#[derive(Debug, Clone, Args)]
pub struct HtmlArgs {
    /// Also write an HTML report (zoomable plots, the report, the files with their hashes)
    /// into this directory, as `compare` and `diagnose --auto` do (`demo`: a subdirectory per
    /// scenario).
    #[arg(long = "report", value_name = "DIR")]
    pub html: Option<PathBuf>,
    /// With --report, also write PNGs beside the report's SVGs.
    #[arg(long, requires = "html")]
    pub png: bool,
}

impl ReportArgs {
    fn check(&self) -> Result<()> {
        if !(0.0..=1.0).contains(&self.max_loss) {
            bail!("--max-loss must be between 0 and 1, got {}", self.max_loss);
        }
        Ok(())
    }
}

/// Prints a report (text or JSON).
fn print_report(r: &Report, json: bool) {
    if json {
        println!("{}", r.json());
    } else {
        println!("\n{}", r.text());
    }
}

/// The worst of several verdicts (interrupted first), as an error carrying its exit code.
fn verdicts(reports: &[Report]) -> Result<()> {
    let worst = reports
        .iter()
        .find(|r| r.verdict == Verdict::Interrupted)
        .or_else(|| reports.iter().find(|r| r.verdict != Verdict::Ok));
    match worst {
        Some(r) => RunFailed::check(r).map_err(Into::into),
        None => Ok(()),
    }
}

fn stop_on_ctrl_c() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    // A second handler registration (tests run several commands in one process) is harmless.
    let _ = ctrlc::set_handler(move || s.store(true, Ordering::SeqCst));
    stop
}

fn bar(len: u64, quiet: bool) -> ProgressBar {
    if quiet || len < 5_000 {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(st) = ProgressStyle::with_template("{bar:40} {pos}/{len} ticks {msg}") {
        pb.set_style(st);
    }
    pb
}

/// The card's laws beyond the scenario's: a gains file and a model to compensate.
#[derive(Debug, Clone, Args)]
pub struct LawArgs {
    /// Gains in output-side SI from a TOML file: stiffness, damping, integral, input_damping,
    /// force_kp/kd/ki, km, limits, `[friction]`, `[feedforward]` (see the README, "Close the
    /// loop").
    #[arg(long, value_name = "FILE.toml")]
    pub gains: Option<PathBuf>,
    /// Compensate what a model file (from `diagnose --auto` or `fit`) measured: friction,
    /// ripple and cogging, offset and gravity become the card's feed-forward; what the card
    /// cannot compensate is named.
    #[arg(long, value_name = "MODEL.toml")]
    pub compensate: Option<PathBuf>,
    /// Under-compensation of friction (thesis: "slightly below" the measured friction).
    #[arg(long, default_value_t = compensate::DEFAULT_UNDER)]
    pub under: f64,
}

impl LawArgs {
    /// Applies the gains file to `sc` (before any single-gain flag).
    fn apply_gains(&self, sc: &mut Scenario) -> Result<()> {
        if let Some(f) = &self.gains {
            let g = GainsFile::load(f)?;
            if self.compensate.is_some() && (g.friction.is_some() || g.feedforward.is_some()) {
                bail!(
                    "{} sets [friction] or [feedforward] and --compensate sets them from a                      model: give one of the two",
                    f.display()
                );
            }
            g.apply(&mut sc.gains);
        }
        Ok(())
    }

    /// Applies `--compensate` to `sc`, saying on stderr what goes to the card and what not.
    fn apply_compensation(&self, sc: &mut Scenario) -> Result<()> {
        let Some(path) = &self.compensate else {
            return Ok(());
        };
        let m = jointlab_workbench::model::Model::load(path)?.to_sim();
        let mut c = Compensation::from_model(&m, &sc.scale, self.under)
            .with_context(|| format!("--compensate {}", path.display()))?;
        c.within_damping(&sc.gains);
        for l in &c.applied {
            eprintln!("compensate: {l}");
        }
        for l in &c.left_out {
            eprintln!("not compensated: {l}");
        }
        sc.gains.friction = c.friction;
        sc.gains.feedforward = c.feedforward;
        Ok(())
    }
}

/// `hil-host demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Experiment: stiffness, damper, step, wall, backlash, identify (or `all` of these);
    /// compensate (identify → diagnose --auto → compensate → tasks without and with);
    /// coulomb-ff (the thesis's Coulomb feed-forward at under-compensation 0.6–1.2);
    /// fidelity (the six transmissions' stiffness emulation ranked; --preset is not used);
    /// velocity-pulse (a 1 s speed pulse under the card's velocity loop, motor vs load);
    /// stability (the thesis's stability maps: the lab's boundaries beside Routh's; --preset
    /// is not used); backlash-cycle (the thesis's limit cycle vs gap width and preload, on
    /// cyclo-29 and kamo-ball-10 with the thesis's rotor; --preset is not used).
    #[arg(long, default_value = "stiffness")]
    pub scenario: String,
    #[command(flatten)]
    pub plant: PlantChoice,
    /// Seed of the sensor noise and of injected losses (same seed → identical recording).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory for the CSV, candump log and PNG.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Seconds of the experiment (default: the scenario's own).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Inject a fault (repeatable; see below).
    #[arg(long, value_name = "SPEC")]
    pub inject: Vec<String>,
    /// After a fault the supervisor clears it and arms the card again (the run still
    /// reports every fault and exits non-zero).
    #[arg(long)]
    pub recover: bool,
    /// The card's sensor timeout, µs (default 3000).
    #[arg(long)]
    pub sensor_timeout_us: Option<u32>,
    #[command(flatten)]
    pub laws: LawArgs,
    #[command(flatten)]
    pub report: ReportArgs,
    #[command(flatten)]
    pub html: HtmlArgs,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// The card: `host` (this process), `qemu` (the firmware's qemu-pil image under
    /// qemu-system-arm, built if needed) or `qemu:IMAGE`.
    #[arg(long, default_value = "host")]
    pub card: CardChoice,
}

fn scenarios(spec: &str) -> Result<Vec<ScenarioKind>> {
    if spec == "all" {
        return Ok(ScenarioKind::ALL.to_vec());
    }
    ScenarioKind::ALL
        .iter()
        .copied()
        .find(|k| k.name() == spec)
        .map(|k| vec![k])
        .ok_or_else(|| {
            let names: Vec<_> = ScenarioKind::ALL.iter().map(|k| k.name()).collect();
            anyhow!(
                "unknown scenario `{spec}`; one of: {}, compensate, backlash-cycle, \
                 coulomb-ff, fidelity, stability, velocity-pulse, all",
                names.join(", ")
            )
        })
}

fn check_seconds(s: Option<f64>) -> Result<()> {
    match s {
        Some(v) if !(v.is_finite() && v > 0.0) => {
            bail!("--seconds must be a number of seconds above 0, got {v}")
        }
        _ => Ok(()),
    }
}

/// Runs the zero-setup demo. Every scenario's report is printed; the exit code is the
/// worst verdict's.
pub fn demo(a: DemoArgs) -> Result<()> {
    let model = a.plant.load()?;
    if a.scenario == "compensate" {
        return compensate_demo(&a, &model);
    }
    if matches!(
        a.scenario.as_str(),
        "coulomb-ff" | "fidelity" | "velocity-pulse" | "stability" | "backlash-cycle"
    ) {
        experiment_flags(&a)?;
        return match a.scenario.as_str() {
            "backlash-cycle" => backlash_cycle_demo(&a),
            "coulomb-ff" => coulomb_ff_demo(&a, &model),
            "fidelity" => fidelity_demo(&a),
            "stability" => stability_demo(&a),
            _ => velocity_pulse_demo(&a, &model),
        };
    }
    a.report.check()?;
    check_seconds(a.seconds)?;
    let plan = FaultPlan::parse(&a.inject)?;
    let kinds = scenarios(&a.scenario)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let stop = stop_on_ctrl_c();
    let image = match &a.card {
        CardChoice::Host => None,
        CardChoice::Qemu(p) => Some(resolve_image(p.as_deref())?),
    };
    let mut reports = vec![];
    for kind in kinds {
        let mut sc = Scenario::new(kind, &model)?;
        if let Some(s) = a.seconds {
            sc.duration_s = s;
        }
        sc.gains.sensor_timeout_us = a.sensor_timeout_us;
        a.laws.apply_gains(&mut sc)?;
        a.laws.apply_compensation(&mut sc)?;
        let opts = LabOptions {
            seed: a.seed,
            faults: plan.clone(),
            max_loss: a.report.max_loss,
            ..LabOptions::default()
        };
        let mut lab = Lab::new(&model, sc, &opts)?;
        if let Some(img) = &image {
            lab.use_qemu_card(QemuCard::spawn(img, opts.node, false)?);
        }
        lab.supervisor.set_recovery(a.recover);
        // Appended, not `with_extension`: a model named `cyclo-bl0.2` must not lose its `.2`
        // (and overwrite `cyclo-bl0.4`'s files).
        let stem = format!("demo-{}-{}", kind.name(), a.plant.label());
        let (csv, log, png) = (
            a.out.join(format!("{stem}.csv")),
            a.out.join(format!("{stem}.log")),
            a.out.join(format!("{stem}.png")),
        );
        lab.recorder.write_csv(&csv)?;
        lab.recorder.write_candump(&log, "inproc")?;
        let n = lab.scenario.ticks();
        let pb = bar(n, a.quiet || a.report.json);
        let t0 = std::time::Instant::now();
        while lab.ticks() < n && !stop.load(Ordering::Relaxed) {
            lab.step()
                .with_context(|| format!("{} at tick {}", kind.name(), lab.ticks()))?;
            if lab.ticks().is_multiple_of(100) {
                pb.set_position(lab.ticks());
            }
        }
        let wall = t0.elapsed().as_secs_f64();
        pb.finish_and_clear();
        lab.recorder.flush()?;
        let interrupted = lab.ticks() < n;
        let title = format!(
            "{} on {} — card + plant + supervisor on the in-process bus, lockstep, seed {}",
            kind.name(),
            a.plant.label(),
            a.seed
        );
        let mut r = lab.report(&title, interrupted)?;
        if let Some(q) = lab.qemu_card() {
            // Not in the table: the table is what must equal the host card's.
            r.details.push(format!(
                "card: {}; {} frames over SLCAN, {:.0} cycles/s",
                a.card.label(),
                q.frames_sent(),
                lab.ticks() as f64 / wall.max(1e-9)
            ));
        }
        // Every file is complete before anything is printed (stdout may be a closed pipe).
        plot_recording(
            &png,
            &format!("{} — {}", kind.name(), a.plant.label()),
            &csv,
            lab.recorder.tally().rows,
            lab.scenario.scale.gear_ratio(),
        )?;
        r.files = [&csv, &log, &png]
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        if let Some(dir) = &a.html.html {
            let html = html_report(
                &dir.join(&stem),
                &format!("demo {} — {}", kind.name(), a.plant.label()),
                &r,
                &csv,
                lab.recorder.tally().rows,
                lab.scenario.scale.gear_ratio(),
                &[&csv, &log, &png],
                &a.plant.model.iter().cloned().collect::<Vec<_>>(),
                a.html.png,
            )?;
            r.files.push(html.display().to_string());
        }
        print_report(&r, a.report.json);
        reports.push(r);
        if interrupted {
            break;
        }
    }
    verdicts(&reports)
}

/// `demo --scenario compensate`: identify, diagnose, compensate, and the tasks without and
/// with. Fails (exit 1) when the compensation made tracking worse.
fn compensate_demo(a: &DemoArgs, model: &Model) -> Result<()> {
    let under = a.laws.under;
    let label = a.plant.label();
    let quiet = a.quiet || a.report.json;
    let given = a.laws.compensate.as_deref();
    let o = close_loop::run_all(model, &label, a.seed, under, given, &a.out, |what| {
        if !quiet {
            eprintln!("compensate: {what}");
        }
    })?;
    if a.report.json {
        let fig = |f: &close_loop::Figures| {
            serde_json::json!({
                "tracking_rms_rad": f.tracking_rms,
                "peak_error_rad": f.peak_error,
                "steady_state_rad": f.steady_state,
                "limit_cycle_counts": f.limit_cycle_counts,
                "loop_area_J": f.loop_area,
            })
        };
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "preset": label,
                "added": o.added,
                "model": o.model_file.display().to_string(),
                "coulomb_model_Nm": o.model_coulomb,
                "applied": o.compensation.applied,
                "left_out": o.compensation.left_out,
                "hold_limit_cycle_counts": o.hold.iter().map(|(u, c)| serde_json::json!({"under": u, "counts": c})).collect::<Vec<_>>(),
                "refused": o.refusal(under),
                "before": fig(&o.before),
                "after": fig(&o.after),
                "files": o.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            })
        );
    } else {
        println!(
            "\ncompensate on {label} — identify, {}, compensate (under {under}), seed {}",
            match (given, o.added.is_empty()) {
                (Some(f), _) => format!("the model {}", f.display()),
                (None, true) => "diagnose --auto (nothing added)".to_string(),
                (None, false) => format!("diagnose --auto ({})", o.added.join(" → ")),
            },
            a.seed
        );
        for l in &o.compensation.applied {
            println!("  on the card: {l}");
        }
        for l in &o.compensation.left_out {
            println!("  not compensated: {l}");
        }
        print!("{}", o.table());
        println!(
            "  the hold with friction compensated on the measured velocity instead: limit \
             cycle {} counts p-p at under-compensation {}, {} at {}",
            o.hold[0].1, o.hold[0].0, o.hold[1].1, o.hold[1].0
        );
        for f in &o.files {
            println!("  wrote {}", f.display());
        }
    }
    if let Some(headline) = o.refusal(under) {
        if !a.report.json {
            println!("  {}: {headline}", Verdict::Incomplete.word());
        }
        return Err(RunFailed {
            verdict: Verdict::Incomplete,
            headline,
        }
        .into());
    }
    Ok(())
}

/// The thesis's experiments set their own laws, length and card: a flag they would ignore
/// is refused by name.
fn experiment_flags(a: &DemoArgs) -> Result<()> {
    let ignored = [
        ("--seconds", a.seconds.is_some()),
        ("--inject", !a.inject.is_empty()),
        ("--recover", a.recover),
        ("--sensor-timeout-us", a.sensor_timeout_us.is_some()),
        ("--gains", a.laws.gains.is_some()),
        ("--compensate", a.laws.compensate.is_some()),
        ("--under", a.laws.under != compensate::DEFAULT_UNDER),
        ("--html", a.html.html.is_some()),
        ("--card", a.card != CardChoice::Host),
        (
            "--preset/--model",
            matches!(
                a.scenario.as_str(),
                "fidelity" | "stability" | "backlash-cycle"
            ) && (a.plant.model.is_some() || a.plant.preset != "whoi-cable-30"),
        ),
    ];
    if let Some((flag, _)) = ignored.iter().find(|(_, given)| *given) {
        bail!(
            "{flag} does not apply to `--scenario {}`: the experiment sets its own (see \
             docs/design/thesis-experiments.md)",
            a.scenario
        );
    }
    Ok(())
}

/// `demo --scenario coulomb-ff`: the thesis's Coulomb feed-forward at under-compensation
/// 0.6–1.2 on a held step and a tracking task.
fn coulomb_ff_demo(a: &DemoArgs, model: &Model) -> Result<()> {
    let label = a.plant.label();
    let s = coulomb_ff::sweep(model, &label, a.seed, &a.out)?;
    if a.report.json {
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "preset": label,
                "coulomb_Nm": s.coulomb,
                "backlash_deg": s.backlash_deg,
                "rows": s.rows,
                "files": s.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            })
        );
        return Ok(());
    }
    println!(
        "\ncoulomb-ff on {label} — Coulomb feed-forward on the measured velocity (τc⁺ {} / τc⁻ {} \
         N·m at the output, × under), a held step at the high stiffness and the tracking \
         triangle, seed {}",
        eng(s.coulomb[0]),
        eng(s.coulomb[1]),
        a.seed
    );
    print!("{}", s.table());
    for f in &s.files {
        println!("  wrote {}", f.display());
    }
    Ok(())
}

/// `demo --scenario fidelity`: the six transmissions' stiffness emulation at the thesis's
/// three stiffnesses, ranked by the work lost.
fn fidelity_demo(a: &DemoArgs) -> Result<()> {
    let cells = fidelity::sweep(a.seed, &a.out, || {})?;
    let png = fidelity::plot(&a.out.join("fidelity.png"), &cells)?;
    if a.report.json {
        let ranks: Vec<_> = fidelity::STIFFNESSES
            .iter()
            .map(|&k| {
                serde_json::json!({
                    "stiffness_Nm_per_deg": k,
                    "best_first": fidelity::ranking(&cells, k).iter().map(|c| c.preset.clone()).collect::<Vec<_>>(),
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "cells": cells,
                "ranking": ranks,
                "plot": png.display().to_string(),
            })
        );
        return Ok(());
    }
    println!(
        "\nfidelity — stiffness emulation cranked on the six transmissions, seed {}",
        a.seed
    );
    print!("{}", fidelity::table(&cells));
    println!("  wrote {} (and a recording per run)", png.display());
    Ok(())
}

/// `demo --scenario backlash-cycle`: the thesis's high-gain hold with a light rotor before
/// the gap, the cycle against the gap's width and a preload.
fn backlash_cycle_demo(a: &DemoArgs) -> Result<()> {
    let mut runs = Vec::new();
    for name in backlash_cycle::PRESETS {
        let preset = sim_plant::presets::preset(name).ok_or_else(|| anyhow!("no preset {name}"))?;
        runs.push(backlash_cycle::run(&preset, name, a.seed, &a.out)?);
    }
    let cable = backlash_cycle::no_gap(a.seed, &a.out)?;
    let pngs = backlash_cycle::plot(&a.out, &runs)?;
    if a.report.json {
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "gain_Nm_per_deg": backlash_cycle::GAIN_NM_PER_DEG,
                "rotor_inertia": backlash_cycle::ROTOR_INERTIA,
                "presets": runs,
                "no_gap": { "preset": backlash_cycle::NO_GAP, "cycle": cable },
                "plots": pngs.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            })
        );
        return Ok(());
    }
    println!(
        "\nbacklash-cycle — the high-gain hold ({} N·m/deg) with the thesis's rotor before the \
         gap and the load beyond it, tapped; seed {}",
        backlash_cycle::GAIN_NM_PER_DEG,
        a.seed
    );
    for r in &runs {
        println!(
            "\n{} (own gap: motor p-p {:.3}° over a {:.2}° gap)",
            r.preset, r.own.motor_pp_deg, r.own.gap_deg
        );
        print!("{}", r.table());
    }
    println!(
        "\n{} (no gap): motor p-p {:.3}° ({} counts)",
        backlash_cycle::NO_GAP,
        cable.motor_pp_deg,
        cable.counts
    );
    for f in &pngs {
        println!("  wrote {}", f.display());
    }
    Ok(())
}

/// `demo --scenario stability`: the thesis's stability maps, each boundary bisected on the
/// lab beside the closed form and the Routh criterion.
fn stability_demo(a: &DemoArgs) -> Result<()> {
    let pb = if a.quiet || a.report.json {
        ProgressBar::hidden()
    } else {
        let pb = ProgressBar::new_spinner();
        if let Ok(st) = ProgressStyle::with_template("{spinner} {elapsed} {pos} lab runs") {
            pb.set_style(st);
        }
        pb
    };
    let maps = stability::maps(a.seed, &a.out, || pb.inc(1))?;
    let ceiling = stability::ceiling(a.seed, &a.out, || pb.inc(1))?;
    pb.finish_and_clear();
    let mut pngs = stability::plot(&a.out, &maps)?;
    pngs.push(stability::plot_ceiling(
        &a.out.join("stability-ceiling.png"),
        &ceiling,
    )?);
    if a.report.json {
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "plant_free": stability::FREE,
                "plant_contact": stability::CONTACT,
                "joint": stability::JOINT,
                "maps": maps,
                "ceiling": ceiling,
                "plots": pngs.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            })
        );
        return Ok(());
    }
    println!(
        "\nstability — the thesis's stability maps on the lab (two-mass plant, output-referred: \
         KT = {} N·m/rad; I1 = I2 = {} kg·m² free and against Kf = KT, {} kg·m² against \
         Kf = {} N·m/rad), seed {}",
        stability::FREE.kt,
        stability::FREE.j1,
        stability::CONTACT.j1,
        stability::CONTACT.kf,
        a.seed
    );
    print!("{}", stability::table(&maps));
    print!("{}", stability::ceiling_table(&ceiling));
    for f in &pngs {
        println!("  wrote {}", f.display());
    }
    Ok(())
}

/// `demo --scenario velocity-pulse`: the machine-tool paper's 1 s speed pulse under the
/// card's velocity loop, each step's load response measured.
fn velocity_pulse_demo(a: &DemoArgs, model: &Model) -> Result<()> {
    let label = a.plant.label();
    let p = velocity_pulse::run(model, &label, a.seed, &a.out)?;
    if a.report.json {
        println!(
            "{}",
            serde_json::json!({
                "schema_version": 1,
                "pulse": p,
            })
        );
        return Ok(());
    }
    println!(
        "\nvelocity-pulse on {label} — velocity PI on the motor, a {} s pulse to {} rad/s at \
         the output, seed {}",
        velocity_pulse::PULSE_S,
        velocity_pulse::PULSE_SPEED,
        a.seed
    );
    print!("{}", p.table());
    println!(
        "  paper (machine-tool axis, validation): the load's response after the two steps is \
         \"quite different\"; here the start takes {:+.1} ms longer than the stop to reach \
         half (backlash {:.2}°)",
        1e3 * (p.start.delay_s - p.stop.delay_s),
        p.backlash_rad.to_degrees()
    );
    for f in &p.files {
        println!("  wrote {}", f.display());
    }
    Ok(())
}

/// Options shared by the nodes on a real bus.
#[derive(Debug, Clone, Args)]
pub struct BusArgs {
    /// Bus: a SocketCAN interface (vcan0, can0) or `inproc`.
    #[arg(long, default_value = "vcan0")]
    pub bus: String,
    /// Joint (node) number, 1..=127.
    #[arg(long, default_value_t = 1)]
    pub node: u8,
    /// Real time (1 kHz wall clock) instead of lockstep.
    #[arg(long)]
    pub realtime: bool,
}

fn open(b: &BusArgs) -> Result<Box<dyn CanBus>> {
    open_bus(&b.bus).map_err(|e| anyhow!("{e}"))
}

/// `hil-host card`.
#[derive(Debug, Args)]
pub struct CardArgs {
    #[command(flatten)]
    pub bus: BusArgs,
}

/// Runs the card node until Ctrl-C.
pub fn card(a: CardArgs) -> Result<()> {
    let mut bus = open(&a.bus)?;
    let mut card =
        CardNode::new(node(a.bus.node)?, !a.bus.realtime).map_err(|e| anyhow!("{e:?}"))?;
    eprintln!(
        "card node {} on {} ({})",
        a.bus.node,
        a.bus.bus,
        if a.bus.realtime {
            "real time"
        } else {
            "lockstep"
        }
    );
    let stop = stop_on_ctrl_c();
    run_card(bus.as_mut(), &mut card, !a.bus.realtime, &stop)
}

/// `hil-host plant`.
#[derive(Debug, Args)]
pub struct PlantArgs {
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub plant: PlantChoice,
    /// Environment schedule of this experiment (default: free output).
    #[arg(long)]
    pub scenario: Option<String>,
    /// Seconds to simulate.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the 1 kHz recording here.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write every frame here as a candump -L log.
    #[arg(long)]
    pub candump: Option<PathBuf>,
    /// Give up waiting for one actuator frame after this many ms (lockstep).
    #[arg(long, default_value_t = 200)]
    pub timeout_ms: u64,
    /// The card's sensor timeout, µs, against which real-time lateness is judged (default
    /// the card's, 3000).
    #[arg(long)]
    pub sensor_timeout_us: Option<u32>,
    #[command(flatten)]
    pub report: ReportArgs,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The plant loop of `plant` and `run`, with its recorder.
fn plant_loop(
    a: &PlantArgs,
    bus: &mut dyn CanBus,
    model: &Model,
    sc: Option<&Scenario>,
    stop: &AtomicBool,
    faults: (FaultPlan, Option<InprocHub>, Option<Arc<AtomicU64>>),
) -> Result<(PlantStats, Recorder)> {
    let n = node(a.bus.node)?;
    let env = sc
        .map(|s| s.environment(0.0))
        .unwrap_or(sim_plant::Environment::Free);
    let plant = Plant::new(
        model,
        PlantOptions {
            seed: a.seed,
            environment: env,
            ..PlantOptions::default()
        },
    )?;
    let mut pn = PlantNode::new(plant, n);
    let mut rec = Recorder::new(
        n,
        model.motor.counts_per_rev.value,
        model.plant.gear_ratio.value,
    )
    .with_output_encoder(model.sensors.output_counts_per_rev.value.round());
    if let Some(p) = &a.csv {
        rec.write_csv(p)?;
    }
    if let Some(p) = &a.candump {
        rec.write_candump(p, &a.bus.bus)?;
    }
    let ticks = (a.seconds * 1000.0).round() as u64;
    let mut lp = PlantLoop::lockstep(ticks);
    if a.bus.realtime {
        lp.clock = Clock::RealTime;
    } else {
        lp.clock = Clock::Lockstep {
            timeout: Duration::from_millis(a.timeout_ms),
        };
    }
    (lp.faults, lp.hub, lp.tick) = faults;
    let pb = bar(ticks, a.quiet || a.report.json);
    let st = run_plant(bus, &mut pn, sc, &mut rec, lp, stop, |k, _| {
        pb.set_position(k)
    })?;
    pb.finish_and_clear();
    Ok((st, rec))
}

/// The report of a run whose plant ran in this process.
#[allow(clippy::too_many_arguments)]
fn plant_report(
    title: String,
    ticks_planned: u64,
    st: &PlantStats,
    rec: &mut Recorder,
    sc: Option<&Scenario>,
    card: Option<CardFacts>,
    supervisor: Option<SupervisorFacts>,
    links: Vec<(Node, LinkStats)>,
    plan: &FaultPlan,
    sensor_timeout_us: Option<u32>,
    ra: &ReportArgs,
    interrupted: bool,
) -> Result<Report> {
    let facts = Facts {
        title,
        ticks_planned,
        ticks_run: st.ticks,
        interrupted,
        tally: rec.tally().clone(),
        missing_actuator: st.missing,
        stale_actuator: st.stale,
        plant_bus_faults: st.bus_faults.clone(),
        card,
        supervisor,
        links,
        injected: plan.items.iter().map(|i| i.to_string()).collect(),
        lateness: st.lateness.clone(),
        sensor_timeout_us: sensor_timeout_us
            .map_or_else(report::default_sensor_timeout_us, u64::from),
        max_loss: ra.max_loss,
    };
    let r = Report::judge(facts);
    let (exact, worst) = st.bus_load();
    rec.flush()?;
    let path = rec
        .csv_path()
        .ok_or_else(|| anyhow!("the recording was not kept"))?
        .to_path_buf();
    let figures = match sc {
        Some(sc) => summarize_with(sc, || read_rows(&path), exact, worst, r.withholds())?,
        None => {
            let mut s = crate::lab::summary::Summary::default();
            s.rows.push((
                "bus load (exact bits)".into(),
                exact * 100.0,
                "% of 1 Mbit/s".into(),
            ));
            s.rows.push((
                "bus load (worst-case stuffing)".into(),
                worst * 100.0,
                "% of 1 Mbit/s".into(),
            ));
            s
        }
    };
    let mut r = r.with_figures(figures);
    r.details.push(plant_stats_line(st));
    Ok(r)
}

fn plant_stats_line(st: &PlantStats) -> String {
    format!(
        "plant: {} ticks, {} actuator frames missing, {} stale, {:.2} s wall ({:.0} cycles/s)",
        st.ticks,
        st.missing,
        st.stale,
        st.wall.as_secs_f64(),
        st.cycles_per_second()
    )
}

/// Runs the plant node for `--seconds`, then reports what it saw.
pub fn plant(a: PlantArgs) -> Result<()> {
    let model = a.plant.load()?;
    a.report.check()?;
    check_seconds(Some(a.seconds))?;
    let sc = match &a.scenario {
        Some(s) => Some(Scenario::new(scenarios(s)?[0], &model)?),
        None => None,
    };
    let mut bus = open(&a.bus)?;
    let stop = stop_on_ctrl_c();
    let plan = FaultPlan::default();
    let (st, mut rec) = plant_loop(
        &a,
        bus.as_mut(),
        &model,
        sc.as_ref(),
        &stop,
        (plan.clone(), None, None),
    )?;
    let ticks = (a.seconds * 1000.0).round() as u64;
    let title = format!(
        "plant node {} on {} ({}, {})",
        a.bus.node,
        a.bus.bus,
        a.plant.label(),
        if a.bus.realtime {
            "real time"
        } else {
            "lockstep"
        }
    );
    let mut r = plant_report(
        title,
        ticks,
        &st,
        &mut rec,
        sc.as_ref(),
        None,
        None,
        vec![],
        &plan,
        a.sensor_timeout_us,
        &a.report,
        stop.load(Ordering::Relaxed) && st.ticks < ticks,
    )?;
    r.files = [&a.csv, &a.candump]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    print_report(&r, a.report.json);
    verdicts(&[r])
}

/// `hil-host supervise`.
#[derive(Debug, Args)]
pub struct SuperviseArgs {
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub plant: PlantChoice,
    /// A thesis experiment (gains, mode, trajectory); the flags below override parts of it.
    #[arg(long, default_value = "step")]
    pub scenario: String,
    /// Mode to arm (e.g. position-pd-colocated, damper, force-pi, impedance-colocated, velocity: a PI on the motor velocity with --stiffness as Ki and --damping as Kv, following the trajectory's velocity).
    #[arg(long)]
    pub mode: Option<String>,
    /// Desired output stiffness, N·m/rad.
    #[arg(long)]
    pub stiffness: Option<f64>,
    /// Desired output damping, N·m·s/rad.
    #[arg(long)]
    pub damping: Option<f64>,
    /// Setpoint trajectory: step:TO or step:TO@T, ramp:TO:S, sine:AMP:HZ, chirp:AMP:F0:F1:S, csv:FILE.
    #[arg(long)]
    pub trajectory: Option<String>,
    /// Setpoint rate, Hz (20–400).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Seconds of streaming before disabling.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Send gains even if the stability guard refuses them.
    #[arg(long)]
    pub force: bool,
    /// Stop sending after this many ticks (to watch the card's watchdog react): `supervise`
    /// exits as a crashed supervisor would; in `run` the supervisor thread falls silent.
    #[arg(long)]
    pub die_after: Option<u64>,
    /// The card's sensor timeout, µs (sent with the gains; the card's default is 3000).
    /// A card that drives and hears no sensor frame for longer faults with SensorTimeout.
    #[arg(long)]
    pub sensor_timeout_us: Option<u32>,
    #[command(flatten)]
    pub laws: LawArgs,
    /// No live telemetry line.
    #[arg(long)]
    pub quiet: bool,
}

fn parse_mode(s: &str) -> Result<Mode> {
    let want: String = s
        .chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_lowercase();
    Mode::ALL
        .iter()
        .copied()
        .find(|m| m.name().to_lowercase() == want)
        .ok_or_else(|| {
            let names: Vec<_> = Mode::ALL.iter().map(|m| m.name()).collect();
            anyhow!("unknown mode `{s}`; one of: {}", names.join(", "))
        })
}

/// Builds the supervisor a `supervise` command describes (also used by `run`).
pub fn build_supervisor(a: &SuperviseArgs, model: &Model) -> Result<(Scenario, Supervisor)> {
    let mut sc = Scenario::new(scenarios(&a.scenario)?[0], model)?;
    a.laws.apply_gains(&mut sc)?;
    if let Some(m) = &a.mode {
        sc.mode = parse_mode(m)?;
        // The velocity loop's setpoint is the trajectory's velocity.
        sc.velocity_ff |= sc.mode == Mode::Velocity;
    }
    if let Some(k) = a.stiffness {
        sc.gains.stiffness = k;
    }
    if let Some(b) = a.damping {
        sc.gains.damping = b;
    }
    if let Some(t) = &a.trajectory {
        sc.trajectory = Trajectory::parse(t)?;
    }
    if sc.mode == Mode::Velocity && matches!(sc.trajectory, Trajectory::Step { .. }) {
        eprintln!(
            "note: in velocity mode the card follows the trajectory's velocity, and a step has \
             none (the joint holds still); give --trajectory ramp:TO:S, sine:AMP:HZ or csv:FILE"
        );
    }
    if let Some(r) = a.rate {
        sc.rate_hz = r;
    }
    if let Some(s) = a.seconds {
        check_seconds(Some(s))?;
        sc.duration_s = s;
    }
    sc.gains.sensor_timeout_us = a.sensor_timeout_us;
    a.laws.apply_compensation(&mut sc)?;
    let entries = sc.gains.entries(&sc.scale, sc.mode)?;
    if let Err(e) = gains::check(&entries, sc.mode) {
        if a.force {
            eprintln!("warning: {e:#} — sending anyway (--force); the card will refuse an unstable set itself");
        } else {
            return Err(e);
        }
    }
    let mut sup = Supervisor::new(
        node(a.bus.node)?,
        sc.scale,
        entries,
        sc.mode,
        sc.target,
        sc.trajectory.clone(),
        sc.rate_hz,
        Some(sc.streaming_s()),
    );
    sup.set_velocity_ff(sc.velocity_ff);
    Ok((sc, sup))
}

/// Runs the supervisor until its script ends (or Ctrl-C).
pub fn supervise(a: SuperviseArgs) -> Result<()> {
    let model = a.plant.load()?;
    let (_, mut sup) = build_supervisor(&a, &model)?;
    let mut bus = open(&a.bus)?;
    let stop = stop_on_ctrl_c();
    let die = a.die_after;
    let quiet = a.quiet;
    let mut seen = 0usize;
    let ticks = run_supervisor(
        bus.as_mut(),
        &mut sup,
        node(a.bus.node)?,
        &stop,
        50,
        |k, s| {
            for e in s.events.iter().skip(seen) {
                eprintln!(
                    "\n[{:>7.3} s] {}",
                    k as f64 * 1e-3,
                    match e {
                        Event::Committed => "parameter set committed".to_string(),
                        Event::Refused(w) => format!("REFUSED: {w}"),
                        Event::Fault(w) => format!("FAULT: {w}"),
                    }
                );
            }
            seen = s.events.len();
            if !quiet && k % 100 == 0 {
                let t = &s.telemetry;
                eprint!(
                "\r[{:>7.3} s] {:?} {:?}  sp {:+.4}  pos {:+.4} rad  vel {:+.3} rad/s  τcmd {:+.3} N·m  τout {:+.2} N·m   ",
                k as f64 * 1e-3, s.phase(), t.state, s.last_setpoint, t.position, t.velocity, t.torque_cmd, t.output_torque
            );
            }
            if die.is_some_and(|d| k >= d) {
                // simulated crash: exit without a word, as a killed supervisor would
                std::process::exit(0);
            }
        },
    )?;
    eprintln!();
    println!(
        "supervisor done after {ticks} ticks, phase {:?}",
        sup.phase()
    );
    let fault = sup.events.iter().find_map(|e| match e {
        Event::Fault(w) => Some(w.clone()),
        _ => None,
    });
    let refused = sup.events.iter().find_map(|e| match e {
        Event::Refused(w) => Some(w.clone()),
        _ => None,
    });
    let (verdict, headline) = if stop.load(Ordering::Relaxed) {
        (
            Verdict::Interrupted,
            format!("stopped by Ctrl-C after {ticks} ticks"),
        )
    } else if let Some(w) = fault {
        (Verdict::Faulted, format!("the card reported a fault: {w}"))
    } else if let Some(w) = refused {
        (Verdict::Incomplete, format!("the card refused: {w}"))
    } else if sup.phase() != Phase::Stopped {
        (
            Verdict::Incomplete,
            format!(
                "the script ended in phase {:?}, before it finished",
                sup.phase()
            ),
        )
    } else {
        return Ok(());
    };
    println!("  {}: {headline}", verdict.word());
    Err(RunFailed { verdict, headline }.into())
}

/// `hil-host run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Experiment, gains and setpoints (as for `supervise`).
    #[command(flatten)]
    pub sup: SuperviseArgs,
    /// Seed of the sensor noise (and of injected losses).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the 1 kHz recording here.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write every frame here as a candump -L log.
    #[arg(long)]
    pub candump: Option<PathBuf>,
    /// Write a PNG plot here.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Inject a fault (repeatable; see below).
    #[arg(long, value_name = "SPEC")]
    pub inject: Vec<String>,
    #[command(flatten)]
    pub report: ReportArgs,
    #[command(flatten)]
    pub html: HtmlArgs,
    /// The card: `host` (a thread of this process), `qemu` (the firmware's qemu-pil image
    /// under qemu-system-arm, a thread relaying the bus to it over SLCAN) or `qemu:IMAGE`.
    #[arg(long, default_value = "host")]
    pub card: CardChoice,
}

/// Checks that the bus and the clock can produce the faults asked for.
fn check_plan(plan: &FaultPlan, bus: &BusSpec, realtime: bool) -> Result<()> {
    if let (Some(i), BusSpec::SocketCan(iface)) = (plan.needs_inproc(), bus) {
        bail!(
            "--inject {i}: error frames and receive queues can only be injected on the \
             in-process bus (--bus inproc), not on {iface}"
        );
    }
    if let (Some(i), false) = (plan.has_delay(), realtime) {
        bail!(
            "--inject {i}: a delay needs a clock; threads in lockstep have none. Use \
             --realtime, or `hil-host demo` (lockstep, delays in whole ticks)"
        );
    }
    Ok(())
}

/// Card, plant and supervisor as threads, each with its own handle on the bus.
pub fn run(a: RunArgs) -> Result<()> {
    let model = a.sup.plant.load()?;
    a.report.check()?;
    let plan = FaultPlan::parse(&a.inject)?;
    let spec = BusSpec::parse(&a.sup.bus.bus).map_err(|e| anyhow!("{e}"))?;
    let lockstep = !a.sup.bus.realtime;
    check_plan(&plan, &spec, a.sup.bus.realtime)?;
    let (sc, mut sup) = build_supervisor(&a.sup, &model)?;
    let n = node(a.sup.bus.node)?;
    let stop = stop_on_ctrl_c();
    // Open all three handles first, so a missing interface fails before anything runs. On
    // the in-process bus the run has a hub of its own (with the receive queues asked for).
    let hub = match (&spec, plan.rx_queue()) {
        (BusSpec::Inproc(name), Some(q)) => Some(InprocHub::with_rx_capacity(name, q)),
        (BusSpec::Inproc(name), None) => Some(InprocHub::new(name)),
        _ => None,
    };
    let open_node = |who: &str| -> Result<Box<dyn CanBus>> {
        match &hub {
            Some(h) => Ok(Box::new(h.attach(who))),
            None => open(&a.sup.bus),
        }
    };
    let tick = Arc::new(AtomicU64::new(0));
    let t0 = std::time::Instant::now();
    let link = |who: Node, k: u64, bus: Box<dyn CanBus>| {
        let clock = if lockstep {
            LinkClock::Ticks(tick.clone())
        } else {
            LinkClock::Wall(t0)
        };
        let mut b = Impaired::new(
            bus,
            clock,
            a.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(k),
        );
        for f in plan.link_faults(who) {
            b.add(f);
        }
        b
    };
    let mut card_bus = link(Node::Card, 1, open_node("card")?);
    let mut sup_bus = link(Node::Supervisor, 3, open_node("supervisor")?);
    let mut plant_bus = link(Node::Plant, 2, open_node("plant")?);
    let mut silent: Vec<Window> = plan
        .items
        .iter()
        .filter_map(|i| match i {
            Injection::KillSupervisor(w) => Some(*w),
            _ => None,
        })
        .collect();
    if let Some(d) = a.sup.die_after {
        silent.push(Window {
            from: d,
            until: None,
        });
    }
    sup.set_silent_windows(silent);
    let qemu_card = a.card != CardChoice::Host;
    // QEMU is started (and the image built) before any thread, so a failure stops the run
    // before the plant waits for a card that is not there.
    let mut qemu = match &a.card {
        CardChoice::Host => None,
        CardChoice::Qemu(p) => Some(QemuCard::spawn(
            &resolve_image(p.as_deref())?,
            n,
            !lockstep,
        )?),
    };
    let done = Arc::new(AtomicBool::new(false));
    let card_thread = {
        let done = done.clone();
        std::thread::spawn(
            move || -> Result<(Option<CardNode>, Option<QemuCard>, LinkStats)> {
                if let Some(q) = qemu.as_mut() {
                    run_qemu_card(&mut card_bus, q, lockstep, &done)?;
                    return Ok((None, qemu, card_bus.stats()));
                }
                let mut card = CardNode::new(n, lockstep).map_err(|e| anyhow!("{e:?}"))?;
                run_card(&mut card_bus, &mut card, lockstep, &done)?;
                Ok((Some(card), None, card_bus.stats()))
            },
        )
    };
    let sup_thread = {
        let done = done.clone();
        std::thread::spawn(move || -> Result<(Supervisor, LinkStats)> {
            run_supervisor(&mut sup_bus, &mut sup, n, &done, 20, |_, _| {})?;
            Ok((sup, sup_bus.stats()))
        })
    };
    let pa = PlantArgs {
        bus: a.sup.bus.clone(),
        plant: a.sup.plant.clone(),
        scenario: Some(a.sup.scenario.clone()),
        seconds: sc.streaming_s() + 0.05,
        seed: a.seed,
        csv: a.csv.clone(),
        candump: a.candump.clone(),
        // An emulated card answers in about a millisecond, but a loaded host can stall QEMU
        // for much longer; in lockstep a late answer is still the right one.
        timeout_ms: if qemu_card { 2000 } else { 200 },
        sensor_timeout_us: a.sup.sensor_timeout_us,
        report: a.report.clone(),
        quiet: a.sup.quiet,
    };
    let res = plant_loop(
        &pa,
        &mut plant_bus,
        &model,
        Some(&sc),
        &stop,
        (plan.clone(), hub.clone(), Some(tick.clone())),
    );
    done.store(true, Ordering::SeqCst);
    let (sup, sup_link) = sup_thread
        .join()
        .map_err(|_| anyhow!("supervisor thread panicked"))??;
    let (card, qemu, card_link) = card_thread
        .join()
        .map_err(|_| anyhow!("card thread panicked"))??;
    let (st, mut rec) = res?;
    let ticks = (pa.seconds * 1000.0).round() as u64;
    let title = format!(
        "{} on {} over {} ({})",
        sc.kind.name(),
        a.sup.plant.label(),
        a.sup.bus.bus,
        if lockstep { "lockstep" } else { "real time" }
    );
    let mut r = plant_report(
        title,
        ticks,
        &st,
        &mut rec,
        Some(&sc),
        // An emulated card's state is inside QEMU: the report reads it from the bus only.
        card.as_ref().map(|c| {
            let c = c.card();
            CardFacts {
                state: c.state(),
                fault: c.fault(),
                bus_warnings: c.bus_warnings(),
                sensor_frames_lost: c.sensor_frames_lost(),
            }
        }),
        Some(SupervisorFacts {
            phase: sup.phase(),
            committed: sup.committed(),
            commit_attempts: sup.commit_attempts(),
            events: sup.events.clone(),
            bus_faults: sup.bus_faults().clone(),
            recoveries: sup.recoveries(),
        }),
        vec![
            (Node::Card, card_link),
            (Node::Plant, plant_bus.stats()),
            (Node::Supervisor, sup_link),
        ],
        &plan,
        a.sup.sensor_timeout_us,
        &a.report,
        stop.load(Ordering::Relaxed) && st.ticks < ticks,
    )?;
    if let Some(q) = &qemu {
        r.details.push(format!(
            "card: {}; {} frames over SLCAN",
            a.card.label(),
            q.frames_sent()
        ));
    }
    if let Some(p) = &a.plot {
        let csv = rec
            .csv_path()
            .ok_or_else(|| anyhow!("the recording was not kept"))?
            .to_path_buf();
        plot_recording(
            p,
            &format!("{} — {}", sc.kind.name(), a.sup.plant.label()),
            &csv,
            rec.tally().rows,
            sc.scale.gear_ratio(),
        )?;
    }
    r.files = [&a.csv, &a.candump, &a.plot]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    if let Some(dir) = &a.html.html {
        let csv = rec
            .csv_path()
            .ok_or_else(|| anyhow!("--report needs the recording: give --csv"))?
            .to_path_buf();
        let written: Vec<&std::path::Path> = [&a.csv, &a.candump, &a.plot]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect();
        let html = html_report(
            dir,
            &format!("run {} — {}", sc.kind.name(), a.sup.plant.label()),
            &r,
            &csv,
            rec.tally().rows,
            sc.scale.gear_ratio(),
            &written,
            &a.sup.plant.model.iter().cloned().collect::<Vec<_>>(),
            a.html.png,
        )?;
        r.files.push(html.display().to_string());
    }
    print_report(&r, a.report.json);
    verdicts(&[r])
}

/// `hil-host bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Also measure over this SocketCAN interface (threads, lockstep).
    #[arg(long)]
    pub bus: Option<String>,
    /// Simulated seconds per measurement.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    #[command(flatten)]
    pub plant: PlantChoice,
}

/// Prints lockstep cycles per second and bus load against the protocol's figure.
pub fn bench(a: BenchArgs) -> Result<()> {
    let model = a.plant.load()?;
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model)?;
    sc.duration_s = a.seconds;
    let mut lab = Lab::new(&model, sc.clone(), &LabOptions::default())?;
    let t0 = std::time::Instant::now();
    lab.run(|_, _| {})?;
    let wall = t0.elapsed().as_secs_f64();
    let ticks = lab.scenario.ticks() as f64;
    let s = lab.summary()?;
    println!(
        "in-process bus, one thread, lockstep ({}):",
        a.plant.label()
    );
    println!(
        "  {:.0} cycles/s  ({:.1}× real time)",
        ticks / wall,
        ticks / wall / 1000.0
    );
    println!(
        "  bus load measured {:.1} % exact / {:.1} % worst-case; protocol's computed figure 35.5 % (sensor + actuator + telemetry, worst case)",
        s.get("bus load (exact bits)").unwrap_or(0.0),
        s.get("bus load (worst-case stuffing)").unwrap_or(0.0)
    );
    if let Some((now, peak)) = crate::lab::mem::rss_bytes() {
        println!(
            "  memory: {:.1} MB resident, {:.1} MB at the peak (the recording streams to disk)",
            now as f64 / 1e6,
            peak as f64 / 1e6
        );
    }
    if let Some(bus) = &a.bus {
        let ra = RunArgs {
            sup: SuperviseArgs {
                bus: BusArgs {
                    bus: bus.clone(),
                    node: 1,
                    realtime: false,
                },
                plant: a.plant.clone(),
                scenario: "stiffness".into(),
                mode: None,
                stiffness: None,
                damping: None,
                trajectory: None,
                rate: None,
                seconds: Some(a.seconds),
                force: false,
                die_after: None,
                sensor_timeout_us: None,
                laws: LawArgs {
                    gains: None,
                    compensate: None,
                    under: compensate::DEFAULT_UNDER,
                },
                quiet: true,
            },
            seed: 1,
            csv: None,
            candump: None,
            plot: None,
            inject: vec![],
            report: ReportArgs {
                json: false,
                max_loss: report::MAX_LOSS,
            },
            html: HtmlArgs {
                html: None,
                png: false,
            },
            card: CardChoice::Host,
        };
        println!("\n{bus}, three threads, lockstep:");
        run(ra)?;
    }
    Ok(())
}
