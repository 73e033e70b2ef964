//! Defects of the lockstep lab, written only against the API that existed before they were
//! fixed, so the same file compiles on both sides: an error frame stopped the lab (2), the
//! card never saw bus-off (2), error frames never reached the candump log (3), and the
//! recorder kept every row in memory (5). The fuller tests are in `lab_faults.rs`.
use controller::proto::{FaultCode, State};
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};
use jointlab_can::bus::BusFault;
use jointlab_can::candump::{read_log, LoggedFrame};

fn lab(kind: ScenarioKind) -> Lab {
    let model = sim_plant::preset("harmonic-drive-60").unwrap();
    let sc = Scenario::new(kind, &model).unwrap();
    Lab::new(&model, sc, &LabOptions::default()).unwrap()
}

#[test]
fn defect2_a_no_ack_does_not_stop_the_lockstep_lab() {
    let mut l = lab(ScenarioKind::Step);
    while l.time() < 0.5 {
        l.step().unwrap();
    }
    l.hub().inject_fault(BusFault::no_ack());
    l.step().expect("an error frame does not stop the lab");
}

#[test]
fn defect2_bus_off_puts_the_card_in_its_safe_state() {
    let mut l = lab(ScenarioKind::Step);
    while l.time() < 0.5 {
        l.step().unwrap();
    }
    l.hub().inject_fault(BusFault::bus_off());
    for _ in 0..3 {
        let _ = l.step();
    }
    assert_eq!(
        l.card.card().fault().map(|f| f.0),
        Some(FaultCode::BusError)
    );
    assert_ne!(l.card.card().state(), State::Enabled);
}

#[test]
fn defect3_error_frames_reach_the_candump_log() {
    let dir = std::env::temp_dir().join(format!("jl-before-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("x.log");
    let mut l = lab(ScenarioKind::Step);
    l.recorder.write_candump(&log, "vcan0").unwrap();
    while l.time() < 0.5 {
        l.step().unwrap();
    }
    l.hub().inject_fault(BusFault::no_ack());
    for _ in 0..10 {
        let _ = l.step();
    }
    l.recorder.flush().unwrap();
    let errors = read_log(&log)
        .unwrap()
        .into_iter()
        .filter(|r| matches!(r.frame, LoggedFrame::Error(_)))
        .count();
    assert_eq!(errors, 1);
}

#[test]
fn defect5_rows_in_memory_stay_bounded() {
    let model = sim_plant::preset("whoi-cable-30").unwrap();
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model).unwrap();
    sc.duration_s = 20.0;
    let mut l = Lab::new(&model, sc, &LabOptions::default()).unwrap();
    l.run(|_, _| {}).unwrap();
    assert!(
        l.recorder.rows.len() <= 2000,
        "{} rows in memory",
        l.recorder.rows.len()
    );
}

/// Defect 4: receive queues of two frames lose most of the gain set on its way to the card.
/// The supervisor must not wait for its commit forever in silence: it says the set was not
/// committed.
#[test]
fn defect4_an_uncommitted_gain_set_is_reported() {
    use controller::proto::Message;
    use hil_host::lab::card_node::CardNode;
    use hil_host::lab::plant_node::PlantNode;
    use hil_host::lab::supervisor::{Event, Phase, Supervisor};
    use jointlab_can::bus::{CanBus, ClassicFrame, InprocHub};

    let model = sim_plant::preset("harmonic-drive-60").unwrap();
    let sc = Scenario::new(ScenarioKind::Step, &model).unwrap();
    let node = controller::proto::NodeId::new(1).unwrap();
    let plant = sim_plant::Plant::new(&model, sim_plant::PlantOptions::default()).unwrap();
    let mut sup = Supervisor::new(
        node,
        sc.scale,
        sc.gains.entries(&sc.scale, sc.mode).unwrap(),
        sc.mode,
        sc.target,
        sc.trajectory.clone(),
        sc.rate_hz,
        Some(sc.streaming_s()),
    );
    let mut card = CardNode::new(node, true).unwrap();
    let mut plant = PlantNode::new(plant, node);
    let hub = InprocHub::with_rx_capacity("defect4", 2);
    let (mut cb, mut pb, mut sb) = (hub.attach("card"), hub.attach("plant"), hub.attach("sup"));
    for tick in 1..=2000u64 {
        for m in sup.on_tick(tick) {
            let f: ClassicFrame = m.encode(node).unwrap();
            sb.send(&f).unwrap();
        }
        for f in plant.sensor_frames() {
            pb.send(&f).unwrap();
        }
        loop {
            match cb.try_recv() {
                Ok(Some(f)) => {
                    for g in card.on_frame(0, &f).frames {
                        cb.send(&g).unwrap();
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    for g in card.on_bus_fault(e.fault().unwrap()).frames {
                        cb.send(&g).unwrap();
                    }
                }
            }
        }
        loop {
            match pb.try_recv() {
                Ok(Some(f)) => {
                    plant.on_frame(&f);
                }
                Ok(None) => break,
                Err(_) => {} // the plant's own overflow: nothing to do about it
            }
        }
        loop {
            match sb.try_recv() {
                Ok(Some(f)) => {
                    if let Ok((n, m)) = Message::decode(&f) {
                        sup.on_message(n, &m);
                    }
                }
                Ok(None) => break,
                Err(_) => {}
            }
        }
        plant.advance();
    }
    assert_ne!(sup.phase(), Phase::Running);
    assert!(
        sup.events
            .iter()
            .any(|e| matches!(e, Event::Refused(w) if w.contains("gain set"))),
        "the supervisor says the gain set was not committed: {:?}",
        sup.events
    );
}
