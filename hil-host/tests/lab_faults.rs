//! The lab under faults: what each node does with an error frame, a lost frame, a stalled
//! plant or a silent supervisor, and what the run then reports (verdict, exit code,
//! counts that agree with the CSV and the candump log).

use std::path::PathBuf;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use controller::proto::{FaultCode, Message, State};
use hil_host::lab::card_node::CardNode;
use hil_host::lab::inject::{BusEvent, FaultPlan};
use hil_host::lab::recorder::{read_rows, RECENT_ROWS};
use hil_host::lab::report::Verdict;
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};
use jointlab_can::bus::BusFault;
use jointlab_can::candump::{read_log, LoggedFrame};

fn hil() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hil-host"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("jl-faults-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn lab(kind: ScenarioKind, preset: &str, faults: &[&str]) -> Lab {
    let model = sim_plant::preset(preset).expect("preset");
    let sc = Scenario::new(kind, &model).expect("scenario");
    let specs: Vec<String> = faults.iter().map(|s| s.to_string()).collect();
    Lab::new(
        &model,
        sc,
        &LabOptions {
            faults: FaultPlan::parse(&specs).expect("faults"),
            ..LabOptions::default()
        },
    )
    .expect("lab")
}

fn text(o: &Output) -> String {
    format!(
        "{}\n--- stderr\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The line after the title: where the report says what happened.
fn verdict_line(stdout: &str) -> &str {
    stdout
        .lines()
        .skip_while(|l| l.trim().is_empty())
        .nth(1)
        .unwrap_or("")
}

/// Asserts the exit code of `o` and returns its stdout and report verdict line.
fn exited(o: &Output, code: i32) -> (String, String) {
    assert_eq!(o.status.code(), Some(code), "{}", text(o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let v = verdict_line(&out).to_string();
    (out, v)
}

// ---------------------------------------------------------------- defect 1: a faulted run

/// A run whose card latched a fault exits non-zero; its report opens with the fault, when,
/// and the share of ticks affected; the figures computed over faulted data are withheld.
#[test]
fn a_faulted_demo_exits_non_zero_and_withholds_its_figures() {
    let dir = tmp("faulted-demo");
    let o = hil()
        .args([
            "demo",
            "--scenario",
            "step",
            "--inject",
            "stall-plant@1+0.01",
            "--quiet",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let (out, v) = exited(&o, 1);
    assert!(
        v.starts_with("  FAULTED: the card latched SensorTimeout at 1.00"),
        "{v}"
    );
    assert!(v.contains("ticks") && v.contains("%) ran faulted"), "{v}");
    assert!(out.contains("figures withheld"), "{out}");
    assert!(
        !out.contains("rise time"),
        "a figure over faulted data: {out}"
    );
    // the JSON report says the same
    let o = hil()
        .args([
            "demo",
            "--scenario",
            "step",
            "--inject",
            "stall-plant@1+0.01",
            "--json",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(j["verdict"], "faulted");
    assert_eq!(j["exit_code"], 1);
    assert_eq!(j["card_faults"][0]["code"], "SensorTimeout");
    assert!(j["ticks"]["faulted_share"].as_f64().unwrap() > 0.3);
    assert!(j["figures_withheld"].is_string());
    assert!(j["figures"]
        .as_array()
        .unwrap()
        .iter()
        .all(|f| f["name"] != "rise time (10–90 % of final)"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A card fault through the threads (`run`): a mode the joint has no sensor for, forced
/// past the supervisor's own check, is refused by the card when armed. Exit 1, and no
/// step figures made of a joint that never moved.
#[test]
fn a_faulted_run_exits_non_zero_and_says_which_fault() {
    let o = hil()
        .args([
            "run",
            "--bus",
            "inproc",
            "--scenario",
            "step",
            "--preset",
            "harmonic-drive-60",
            "--mode",
            "position-pd-non-colocated",
            "--force",
            "--quiet",
        ])
        .output()
        .unwrap();
    let (out, v) = exited(&o, 1);
    assert!(
        v.starts_with("  FAULTED: the card latched ConfigRejected at "),
        "{v}"
    );
    assert!(out.contains("figures withheld"), "{out}");
    assert!(!out.contains("settling time"), "{out}");
}

/// The report of issue 26: a real-time run whose plant stalls longer than the card's sensor
/// timeout. The card faults, the run exits 1, and the report says the machine did not hold
/// 1 kHz, with the worst stall.
#[test]
fn a_realtime_run_whose_plant_stalls_reports_the_fault_and_the_stall() {
    let o = hil()
        .args([
            "run",
            "--bus",
            "inproc",
            "--realtime",
            "--scenario",
            "step",
            "--seconds",
            "0.8",
            "--inject",
            "stall-plant@0.6+0.02",
            "--quiet",
        ])
        .output()
        .unwrap();
    let (out, v) = exited(&o, 1);
    assert!(
        v.starts_with("  FAULTED: the card latched SensorTimeout"),
        "{out}"
    );
    assert!(
        out.contains("did NOT hold 1 kHz: the worst stall was"),
        "{out}"
    );
    assert!(out.contains("sensor timeout, 3.0 ms"), "{out}");
}

// ------------------------------------------------- defect 2: error frames in the lockstep lab

/// An error frame no longer stops the lockstep lab; bus-off puts the card in its safe state
/// with the torque off in the very tick the error frame arrived.
#[test]
fn bus_off_zeroes_the_torque_within_a_tick_and_the_lab_runs_on() {
    let mut l = lab(ScenarioKind::Stiffness, "whoi-cable-30", &[]);
    while l.time() < 1.0 {
        l.step().unwrap();
    }
    let before = l.recorder.rows.last().unwrap().clone();
    assert!(before.torque_cmd_nm.abs() > 1e-3, "driving: {before:?}");
    assert_eq!(l.card.card().state(), State::Enabled);
    l.hub().inject_fault(BusFault::bus_off());
    l.step().expect("an error frame does not stop the lab");
    let at = l.recorder.rows.last().unwrap().clone();
    assert_eq!(
        at.torque_cmd_nm, 0.0,
        "torque off in the tick of the bus-off"
    );
    assert!(at.fault, "{at:?}");
    assert_eq!(
        l.plant.command().map(|a| (a.torque, a.drive)),
        Some((0, false))
    );
    assert_eq!(
        l.card.card().fault().map(|f| f.0),
        Some(FaultCode::BusError)
    );
    l.run(|_, _| {}).expect("the lab runs to the end");
    assert_eq!(l.ticks(), l.scenario.ticks());
    let r = l.report("bus-off", false).unwrap();
    assert_eq!(r.verdict, Verdict::Faulted);
    assert!(r.headline.contains("BusError at 1.001 s"), "{}", r.headline);
}

/// The same through `--inject` in the demo: the card's bus-fault handling runs.
#[test]
fn an_injected_bus_off_faults_the_card_in_the_demo() {
    let mut l = lab(ScenarioKind::Step, "harmonic-drive-60", &["bus-off@0.8"]);
    l.run(|_, _| {}).unwrap();
    assert_eq!(l.card.card().state(), State::Fault);
    let rows: Vec<_> = read_rows(l.recorder.csv_path().unwrap())
        .unwrap()
        .map(Result::unwrap)
        .collect();
    let k = rows.iter().position(|r| r.time_s >= 0.8 - 1e-9).unwrap();
    assert!(rows[k - 1].torque_cmd_nm != 0.0 && !rows[k - 1].fault);
    assert!(rows[k..].iter().all(|r| r.torque_cmd_nm == 0.0 && r.fault));
}

// ------------------------------------------------ defect 3: minor bus faults reach everyone

/// Every minor fault reaches every node: the card counts it (and stays enabled), the
/// supervisor and the plant count it, the recorder logs it to candump and tallies it, and
/// the report counts it.
#[test]
fn minor_bus_faults_are_counted_logged_and_reported() {
    let dir = tmp("minor");
    let minor = [
        BusEvent::ErrorWarning,
        BusEvent::NoAck,
        BusEvent::Protocol,
        BusEvent::RxOverflow,
    ];
    let mut l = lab(ScenarioKind::Step, "harmonic-drive-60", &[]);
    let log = dir.join("minor.log");
    l.recorder.write_candump(&log, "vcan0").unwrap();
    for (i, ev) in minor.iter().enumerate() {
        while l.time() < 0.5 + 0.1 * i as f64 {
            l.step().unwrap();
        }
        l.hub().inject_fault(ev.fault());
    }
    l.run(|_, _| {}).unwrap();
    let card = l.card.card();
    assert_eq!(card.state(), State::Enabled, "warnings change nothing");
    assert_eq!(card.bus_warnings(), 4);
    assert_eq!(l.supervisor.bus_faults().values().sum::<u64>(), 4);
    let errors: Vec<_> = read_log(&log)
        .unwrap()
        .into_iter()
        .filter_map(|r| match r.frame {
            LoggedFrame::Error(f) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(errors, minor.map(|e| e.fault()).to_vec(), "logged in order");
    let r = l.report("minor", false).unwrap();
    assert_eq!(r.verdict, Verdict::Degraded);
    for ev in minor {
        assert_eq!(r.facts.tally.error_frames.get(&ev), Some(&1), "{ev}");
    }
    let d = r.details.join("\n");
    assert!(d.contains("bus error frames: 4"), "{d}");
    assert!(d.contains("the card counted 4 bus warning(s)"), "{d}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The card node's reaction to each kind of error frame.
#[test]
fn the_card_node_reacts_to_each_error_frame() {
    let node = controller::proto::NodeId::new(1).unwrap();
    let react = |f: BusFault| {
        let mut c = CardNode::new(node, true).unwrap();
        let out = c.on_bus_fault(&f);
        let fault = out.frames.iter().any(|g| {
            matches!(Message::decode(g), Ok((_, Message::Fault(x))) if x.code == FaultCode::BusError)
        });
        (
            c.card().fault().map(|x| x.0),
            c.card().bus_warnings(),
            fault,
        )
    };
    let safe = (Some(FaultCode::BusError), 0, true);
    assert_eq!(react(BusEvent::BusOff.fault()), safe);
    assert_eq!(react(BusEvent::ErrorPassive.fault()), safe);
    assert_eq!(
        react(BusFault::controller(
            jointlab_can::bus::fault::ctrl::RX_PASSIVE,
            0,
            128
        )),
        safe,
        "error-passive on receive, as the firmware treats it"
    );
    for ev in [
        BusEvent::ErrorWarning,
        BusEvent::NoAck,
        BusEvent::Protocol,
        BusEvent::RxOverflow,
    ] {
        assert_eq!(react(ev.fault()), (None, 1, false), "{ev}");
    }
    let recovered = BusFault::controller(jointlab_can::bus::fault::ctrl::ACTIVE, 0, 0);
    assert_eq!(react(recovered), (None, 0, false));
}

// ------------------------------------------------------------- defect 4: silent frame loss

/// Losing a third of the card's received frames while it drives: the card faults (its
/// clock runs on without sensor frames) and the report counts the frames lost.
#[test]
fn heavy_sensor_frame_loss_faults_the_card_and_is_counted() {
    let mut l = lab(
        ScenarioKind::Step,
        "harmonic-drive-60",
        &["drop:card=0.33@0.5"],
    );
    l.run(|_, _| {}).unwrap();
    let (code, _) = l.card.card().fault().expect("faulted");
    assert!(
        matches!(code, FaultCode::SensorTimeout | FaultCode::SequenceError),
        "{code:?}"
    );
    let lost = l.card.card().sensor_frames_lost();
    assert!(lost > 100, "{lost}");
    let r = l.report("drop", false).unwrap();
    assert_eq!(r.verdict, Verdict::Faulted);
    let d = r.details.join("\n");
    assert!(
        d.contains(&format!("the card missed {lost} of its sensor frames")),
        "{d}"
    );
    assert!(d.contains("injected losses: card:"), "{d}");
}

/// A loss the card tolerates (single gaps) is still counted, and above the threshold the
/// run is not a success.
#[test]
fn tolerated_frame_loss_above_the_threshold_degrades_the_run() {
    let mut l = lab(
        ScenarioKind::Step,
        "harmonic-drive-60",
        &["drop:plant=5%@0.5"],
    );
    l.run(|_, _| {}).unwrap();
    assert_eq!(l.card.card().state(), State::Enabled, "the card never knew");
    let r = l.report("lossy plant", false).unwrap();
    assert_eq!(r.verdict, Verdict::Degraded);
    assert!(r
        .headline
        .contains("had no actuator frame, above the 1.00 % threshold"));
    // the count is the recording's
    let missing = read_rows(l.recorder.csv_path().unwrap())
        .unwrap()
        .filter(|r| r.as_ref().unwrap().cmd_missing)
        .count() as u64;
    assert_eq!(missing, r.facts.tally.missing_rows);
    assert_eq!(missing, l.plant.missing);
    assert!(
        r.headline.contains(&format!("{missing} of")),
        "{}",
        r.headline
    );
}

/// Receive queues of two frames: the gain set never gets through. The supervisor retries,
/// gives up, and the run says so.
#[test]
fn an_uncommitted_gain_set_is_reported() {
    let mut l = lab(ScenarioKind::Step, "harmonic-drive-60", &["rx-queue=2"]);
    l.run(|_, _| {}).unwrap();
    assert!(!l.supervisor.committed());
    assert_eq!(l.supervisor.commit_attempts(), 3);
    assert!(
        l.card.card().bus_warnings() > 0,
        "the overflows reached the card"
    );
    let r = l.report("short queues", false).unwrap();
    assert_eq!(r.verdict, Verdict::Incomplete);
    assert!(
        r.headline
            .starts_with("the gain set was never committed: no answer to 3 commits"),
        "{}",
        r.headline
    );
    assert!(r.withholds().is_some());
    // an overflow is the receiving controller's own error frame: the nodes heard theirs
    assert!(l.supervisor.bus_faults().get(&BusEvent::RxOverflow) > Some(&0));
    let d = r.details.join("\n");
    assert!(d.contains("error frames heard by the nodes"), "{d}");
    assert!(d.contains("rx-overflow"), "{d}");
}

// ------------------------------------------------------------ defect 5: bounded recordings

/// A long run keeps a bounded window of rows in memory and the whole recording on disk;
/// the summary, read back from the file, covers every row.
#[test]
fn recordings_stream_to_disk_and_memory_stays_bounded() {
    let dir = tmp("stream");
    let model = sim_plant::preset("whoi-cable-30").unwrap();
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model).unwrap();
    sc.duration_s = 40.0;
    let mut l = Lab::new(&model, sc, &LabOptions::default()).unwrap();
    let csv = dir.join("long.csv");
    l.recorder.write_csv(&csv).unwrap();
    // Flushed at least every second of wall time: rows recorded more than a second ago
    // are on disk while the run goes on.
    let t0 = Instant::now();
    let mut early = None;
    while l.ticks() < l.scenario.ticks() && t0.elapsed() < Duration::from_millis(1500) {
        l.step().unwrap();
        if early.is_none() && t0.elapsed() > Duration::from_millis(200) {
            early = Some(l.recorder.tally().rows);
        }
    }
    let on_disk = std::fs::read_to_string(&csv).unwrap().lines().count() as u64 - 1;
    assert!(on_disk >= early.unwrap_or(0), "{on_disk} < {early:?}");
    l.run(|_, _| {}).unwrap();
    assert!(
        l.recorder.rows.len() <= 2 * RECENT_ROWS,
        "{} rows in memory",
        l.recorder.rows.len()
    );
    assert_eq!(l.recorder.recent().len(), RECENT_ROWS);
    let n = l.scenario.ticks();
    assert_eq!(l.recorder.tally().rows, n);
    let rows = read_rows(&csv).unwrap().count() as u64;
    assert_eq!(rows, n, "every tick on disk");
    let s = l.summary().unwrap();
    let ratio = s.get("achieved / desired").unwrap();
    assert!((0.9..=1.02).contains(&ratio), "{ratio}");
    std::fs::remove_dir_all(&dir).ok();
}

// ------------------------------------------------------------------- defect 6: Ctrl-C

/// Runs the CLI and sends it SIGINT once `ready` (its CSV, created after the Ctrl-C handler
/// is installed) holds rows, plus `after`: a fixed sleep alone would, on a loaded machine,
/// signal a process that has no handler yet and kill it outright.
fn interrupt(args: &[&str], ready: &std::path::Path, after: Duration) -> Output {
    let child = hil()
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let give_up = Instant::now() + Duration::from_secs(120);
    while std::fs::metadata(ready).map_or(0, |m| m.len()) < 4096 {
        assert!(Instant::now() < give_up, "{} never filled", ready.display());
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(after);
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success(), "kill -INT");
    child.wait_with_output().unwrap()
}

/// Ctrl-C: exit 130 and a report that opens with the interruption; the CSV holds every
/// tick that ran.
#[test]
fn an_interrupted_run_exits_130_and_says_so() {
    let dir = tmp("ctrlc");
    let csv = dir.join("int.csv");
    let o = interrupt(
        &[
            "run",
            "--bus",
            "inproc",
            "--realtime",
            "--scenario",
            "stiffness",
            "--quiet",
            "--csv",
            csv.to_str().unwrap(),
        ],
        &csv,
        Duration::from_millis(500),
    );
    let (out, v) = exited(&o, 130);
    assert!(v.starts_with("  INTERRUPTED: stopped by Ctrl-C at "), "{v}");
    assert!(out.contains("figures withheld"), "{out}");
    let ran: u64 = v
        .split("after ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .expect("ticks run");
    let rows = read_rows(&csv).unwrap().count() as u64;
    assert_eq!(rows, ran, "the CSV is complete and flushed");
    // lockstep, one thread
    let o = interrupt(
        &[
            "demo",
            "--seconds",
            "600",
            "--quiet",
            "--out",
            dir.to_str().unwrap(),
        ],
        &dir.join("demo-stiffness-whoi-cable-30.csv"),
        Duration::from_millis(500),
    );
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    assert!(
        verdict_line(&String::from_utf8_lossy(&o.stdout)).starts_with("  INTERRUPTED"),
        "{}",
        text(&o)
    );
    std::fs::remove_dir_all(&dir).ok();
}

// ------------------------------------------------------------------- defect 7: --die-after

/// `run --die-after N`: the supervisor thread falls silent after N ticks, the card's
/// watchdog stops the joint, and the run says so (text and JSON).
#[test]
fn run_die_after_trips_the_watchdog() {
    let args = [
        "run",
        "--bus",
        "inproc",
        "--scenario",
        "step",
        "--preset",
        "harmonic-drive-60",
        "--die-after",
        "500",
        "--quiet",
    ];
    let o = hil().args(args).output().unwrap();
    let (out, v) = exited(&o, 1);
    assert!(
        v.starts_with("  FAULTED: the card latched SupervisorWatchdog"),
        "{out}"
    );
    let o = hil().args(args).arg("--json").output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(j["verdict"], "faulted");
    assert_eq!(j["card_faults"][0]["code"], "SupervisorWatchdog");
    let t = j["card_faults"][0]["time_s"].as_f64().unwrap();
    assert!((0.69..0.72).contains(&t), "200 ms after tick 500: {t}");
}

// ------------------------------------------------------- the card's configured reactions

/// The supervisor watchdog's configured reaction (QuickStop, the default) damps the joint
/// to standstill: torque against the motion, then off.
#[test]
fn a_killed_supervisor_gets_a_quick_stop() {
    let mut l = lab(
        ScenarioKind::Stiffness,
        "whoi-cable-30",
        &["kill-supervisor@1.0"],
    );
    let mut reaction = vec![];
    while l.time() < 2.0 {
        l.step().unwrap();
        if l.card.card().state() == State::FaultReaction {
            reaction.push(l.recorder.rows.last().unwrap().clone());
        }
    }
    assert_eq!(
        l.card.card().fault().map(|f| f.0),
        Some(FaultCode::SupervisorWatchdog)
    );
    assert!(
        reaction.len() >= 2,
        "a damped stop, not a cut: {}",
        reaction.len()
    );
    for r in &reaction {
        assert!(
            r.torque_cmd_nm * r.motor_vel_rad_s <= 1e-12,
            "quick-stop torque opposes the motion: {r:?}"
        );
    }
    assert!(reaction.iter().any(|r| r.torque_cmd_nm != 0.0));
    // then standstill: the reaction is done, the torque off
    assert_eq!(l.card.card().state(), State::Fault);
    assert_eq!(l.recorder.rows.last().unwrap().torque_cmd_nm, 0.0);
}

/// Bad `--inject` specs are refused before anything runs, naming what is wrong.
#[test]
fn bad_inject_specs_are_refused() {
    for (args, want) in [
        (
            &["demo", "--inject", "bus-of@1"][..],
            "unknown fault `bus-of`",
        ),
        (
            &["demo", "--inject", "drop:crad=0.1"][..],
            "unknown node `crad`",
        ),
        (
            &["run", "--bus", "inproc", "--inject", "delay:card=2ms"][..],
            "a delay needs a clock",
        ),
        (
            &["run", "--bus", "vcan0", "--inject", "bus-off@1"][..],
            "only be injected on the in-process bus",
        ),
        (
            &["demo", "--max-loss", "2"][..],
            "--max-loss must be between 0 and 1",
        ),
    ] {
        let o = hil().args(args).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(want), "{args:?}: {e}");
    }
}
