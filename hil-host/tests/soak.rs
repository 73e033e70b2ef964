//! Soak: ten minutes of simulated time in the lockstep lab, with every kind of injected
//! fault once (`rx-queue=N` is whole-run and has its own test in `lab_faults.rs`), and an
//! operator supervisor that clears each fault and arms the card again.
//!
//! It passes when the lab ran every tick without a panic or an error, its memory did not
//! grow with the recording, every fault was reported, and the CSV, the candump log and
//! the report agree on every count. Lockstep runs many times faster than real time: the
//! ten minutes take well under a minute of CI time (it prints its wall time and memory).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::time::Instant;

use controller::proto::{FaultCode, Message};
use hil_host::lab::inject::{BusEvent, FaultPlan, Node};
use hil_host::lab::mem::rss_bytes;
use hil_host::lab::recorder::read_rows;
use hil_host::lab::report::Verdict;
use hil_host::lab::scenario::{Scenario, ScenarioKind, SETTLE_S};
use hil_host::lab::{Lab, LabOptions};
use jointlab_can::candump::{CandumpReader, LoggedFrame};

const FAULTS: [&str; 12] = [
    "bus-off@60",
    "error-passive@120",
    "error-warning@180",
    "no-ack@200",
    "protocol@220",
    "rx-overflow@240",
    "drop:card=0.4@300+2",
    "drop:plant=2%@330+10",
    "delay:card=2ms@360+0.5",
    "jitter:supervisor=3ms@380+5",
    "stall-plant@420+0.02",
    "kill-supervisor@480+0.5",
];

#[test]
fn ten_minutes_with_every_fault_kind() {
    let dir = tempfile::tempdir().unwrap();
    let model = sim_plant::preset("whoi-cable-30").unwrap();
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model).unwrap();
    sc.duration_s = 600.0 - SETTLE_S;
    let specs: Vec<String> = FAULTS.iter().map(|s| s.to_string()).collect();
    let mut lab = Lab::new(
        &model,
        sc,
        &LabOptions {
            faults: FaultPlan::parse(&specs).unwrap(),
            ..LabOptions::default()
        },
    )
    .unwrap();
    lab.supervisor.set_recovery(true);
    let (csv, log) = (dir.path().join("soak.csv"), dir.path().join("soak.log"));
    lab.recorder.write_csv(&csv).unwrap();
    lab.recorder.write_candump(&log, "inproc").unwrap();

    let t0 = Instant::now();
    let n = lab.scenario.ticks();
    assert_eq!(n, 600_000);
    let mut rss_at_1min = None;
    while lab.ticks() < n {
        lab.step()
            .unwrap_or_else(|e| panic!("tick {}: {e:#}", lab.ticks()));
        if lab.ticks() == 60_000 {
            rss_at_1min = rss_bytes();
        }
    }
    let wall = t0.elapsed();
    let rss_end = rss_bytes();
    let r = lab.report("soak", false).unwrap();
    let j = r.json();
    println!("{}", r.text());
    println!(
        "soak: {n} ticks in {:.1} s wall ({:.0}× real time)",
        wall.as_secs_f64(),
        600.0 / wall.as_secs_f64()
    );

    // --- memory stays bounded: nothing grows with the recording
    if let (Some((a, _)), Some((b, peak))) = (rss_at_1min, rss_end) {
        let grew = b.saturating_sub(a) as f64 / 1e6;
        println!(
            "soak: resident {:.1} MB after 1 min, {:.1} MB after 10 min, peak {:.1} MB",
            a as f64 / 1e6,
            b as f64 / 1e6,
            peak as f64 / 1e6
        );
        // An in-memory recording would add ~70 MB over the nine minutes.
        assert!(grew < 16.0, "resident memory grew {grew:.1} MB");
    }

    // --- every fault reported
    assert_eq!(r.verdict, Verdict::Faulted);
    assert_eq!(r.verdict.exit_code(), 1);
    let t = &r.facts.tally;
    for ev in BusEvent::ALL {
        assert_eq!(t.error_frames.get(&ev), Some(&1), "{ev} once: {t:?}");
    }
    let faults_in = |from: f64, to: f64| -> Vec<FaultCode> {
        t.card_faults
            .iter()
            .filter(|f| f.time_s >= from && f.time_s < to)
            .map(|f| f.code)
            .collect()
    };
    assert_eq!(faults_in(60.0, 60.1), [FaultCode::BusError], "bus-off");
    assert_eq!(
        faults_in(120.0, 120.1),
        [FaultCode::BusError],
        "error-passive"
    );
    assert!(faults_in(170.0, 299.0).is_empty(), "warnings fault nothing");
    let dropped = faults_in(300.0, 303.0);
    assert!(
        !dropped.is_empty()
            && dropped
                .iter()
                .all(|c| matches!(c, FaultCode::SensorTimeout | FaultCode::SequenceError)),
        "40 % of the card's frames lost: {dropped:?}"
    );
    assert!(
        faults_in(320.0, 419.0).is_empty(),
        "tolerated losses and delays"
    );
    assert_eq!(faults_in(420.0, 421.0), [FaultCode::SensorTimeout], "stall");
    assert_eq!(
        faults_in(480.0, 481.0),
        [FaultCode::SupervisorWatchdog],
        "killed supervisor"
    );
    let card = r.facts.card.as_ref().unwrap();
    assert_eq!(card.bus_warnings, 4, "warning, no-ACK, protocol, overflow");
    assert!(card.sensor_frames_lost > 0);
    let sup = r.facts.supervisor.as_ref().unwrap();
    assert!(
        sup.recoveries >= 5,
        "each fault cleared: {} recoveries, {} faults",
        sup.recoveries,
        t.card_fault_frames
    );
    assert_eq!(
        card.state,
        controller::proto::State::Enabled,
        "driving again at the end"
    );
    let link = |who: Node| r.facts.links.iter().find(|l| l.0 == who).unwrap().1;
    assert!(link(Node::Card).dropped > 0 && link(Node::Card).delayed > 0);
    assert!(link(Node::Plant).dropped > 0);
    assert!(link(Node::Supervisor).delayed > 0);
    let text = r.text();
    for want in [
        "bus error frames: 6",
        "injected losses: card:",
        "the supervisor cleared the fault and re-armed the card",
        "frames lost:",
    ] {
        assert!(text.contains(want), "report lacks `{want}`");
    }
    for f in FAULTS {
        let shown = f.replace("2%", "0.02");
        assert!(text.contains(&shown), "report lacks the injected `{f}`");
    }

    // --- the CSV, the candump log and the report agree
    let (mut rows, mut faulted, mut missing) = (0u64, 0u64, 0u64);
    let mut last_t = 0.0;
    for row in read_rows(&csv).unwrap() {
        let row = row.unwrap();
        rows += 1;
        faulted += u64::from(row.fault);
        missing += u64::from(row.cmd_missing);
        assert!(row.time_s > last_t, "time runs forward");
        last_t = row.time_s;
    }
    assert_eq!(rows, t.rows);
    assert_eq!(rows, n - 20, "every tick but the stalled plant's 20");
    assert_eq!(faulted, t.faulted_rows);
    assert_eq!(missing, t.missing_rows);
    assert_eq!(missing, lab.plant.missing);
    assert_eq!(j["ticks"]["recorded"], rows);
    assert_eq!(j["ticks"]["faulted"], faulted);
    assert_eq!(j["ticks"]["cmd_missing"], missing);
    let mut errors: BTreeMap<BusEvent, u64> = BTreeMap::new();
    let (mut frames, mut fault_frames) = (0u64, 0u64);
    // Streamed, as the CSV is: a 600 k-tick log read into memory would be 180 MB.
    for rec in CandumpReader::new(BufReader::new(File::open(&log).unwrap())) {
        match rec.unwrap().frame {
            LoggedFrame::Error(f) => {
                *errors.entry(BusEvent::classify(&f).unwrap()).or_default() += 1;
            }
            LoggedFrame::Can(f) => {
                frames += 1;
                if let Ok((_, Message::Fault(_))) = Message::decode(&f) {
                    fault_frames += 1;
                }
            }
        }
    }
    assert_eq!(errors, t.error_frames);
    assert_eq!(j["bus_error_frames_total"], 6);
    assert_eq!(frames, t.frames);
    assert_eq!(fault_frames, t.card_fault_frames);
    assert_eq!(j["card_fault_frames"], fault_frames);

    // --- the whole test, report and checks included, stayed small
    if let Some((_, peak)) = rss_bytes() {
        println!("soak: peak resident {:.1} MB", peak as f64 / 1e6);
        assert!(peak < 50_000_000, "peak resident {peak} bytes");
    }
}
