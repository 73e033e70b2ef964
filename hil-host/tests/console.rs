//! The card console against the lab's card, over a named in-process hub (the CI VM runs the
//! same commands against a card on vcan0): reads, an atomic set, the card's refusals named,
//! the heartbeat decoded; a node that is not there is an error, not a hang.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use controller::proto::params;
use controller::proto::{Message, NodeId, RawFrame, Sensor, State};
use hil_host::cli::console::{lookup, Console};
use hil_host::cli::{run, Cli};
use hil_host::lab::card_node::CardNode;
use hil_host::lab::threaded::run_card;
use jointlab_can::bus::{CanBus, CanBusExt, InprocHub};

/// A card (node 1) running in real time on the hub `name`, ticked by a sensor stream at
/// about 1 kHz (a commit is applied at a tick boundary), until the guard drops.
struct Card(Arc<AtomicBool>, Vec<std::thread::JoinHandle<()>>);

impl Drop for Card {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
        for h in self.1.drain(..) {
            h.join().ok();
        }
    }
}

fn card_on(name: &str) -> Card {
    let stop = Arc::new(AtomicBool::new(false));
    let mut bus = InprocHub::named(name).attach("card");
    let mut plant = InprocHub::named(name).attach("plant");
    let s = stop.clone();
    let card = std::thread::spawn(move || {
        let mut card = CardNode::new(NodeId::new(1).unwrap(), false).unwrap();
        run_card(&mut bus, &mut card, false, &s).unwrap();
    });
    let s = stop.clone();
    let ticks = std::thread::spawn(move || {
        let node = NodeId::new(1).unwrap();
        let mut seq = 0u8;
        while !s.load(Ordering::Relaxed) {
            let f: RawFrame = Message::Sensor(Sensor {
                motor_counts: 0,
                output_torque: Some(0),
                seq,
                output_encoder: false,
                encoder_error: false,
            })
            .encode(node)
            .unwrap();
            plant.send_frame(&f).unwrap();
            seq = seq.wrapping_add(1);
            // Drain what the card sends back so the plant's queue stays short.
            while plant.try_recv().unwrap().is_some() {}
            std::thread::sleep(Duration::from_millis(1));
        }
    });
    Card(stop, vec![card, ticks])
}

#[test]
fn reads_sets_and_refusals_over_the_bus() {
    let _card = card_on("console-rw");
    let mut bus = InprocHub::named("console-rw").attach("console");
    let mut c = Console::new(&mut bus, 1, Duration::from_millis(500)).unwrap();
    let (tl, def) = lookup("torque_limit").unwrap();
    assert_eq!(tl, params::TORQUE_LIMIT);
    assert_eq!(c.get(tl).unwrap(), def.default);
    assert_eq!(
        c.get(params::PROTOCOL_VERSION).unwrap(),
        i32::from(controller::proto::PROTOCOL_VERSION)
    );
    // A set is committed as a whole.
    let (vl, _) = lookup("velocity_limit").unwrap();
    c.set(&[(tl, 12_345), (vl, 1_000)], 0x81).unwrap();
    assert_eq!(c.get(tl).unwrap(), 12_345);
    assert_eq!(c.get(vl).unwrap(), 1_000);
    // The card's refusals come back named; nothing of a refused set is applied.
    let e = c
        .set(&[(tl, 1), (params::PROTOCOL_VERSION, 2)], 0x82)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("ReadOnly") && e.contains("protocol_version"),
        "{e}"
    );
    assert_eq!(c.get(tl).unwrap(), 12_345);
    let e = c.set(&[(tl, -5)], 0x83).unwrap_err().to_string();
    assert!(
        e.contains("OutOfRange") && e.contains("torque_limit"),
        "{e}"
    );
    // The heartbeat, decoded.
    let l = c.listen(Duration::from_millis(400)).unwrap();
    let h = l.heartbeat.expect("a heartbeat within 400 ms");
    assert_eq!(h.state, State::Disabled);
    assert!(
        l.frames.get("Heartbeat").copied().unwrap_or(0) >= 1,
        "{l:?}"
    );
    assert!(l.bits > 0);
}

#[test]
fn the_command_line_reaches_the_card_and_a_missing_node_is_an_error() {
    let _card = card_on("console-cli");
    let cli = |args: &[&str]| {
        let mut v = vec!["hil-host"];
        v.extend(args);
        v.extend(["--bus", "inproc:console-cli", "--timeout-ms", "300"]);
        run(Cli::parse_from(v))
    };
    cli(&["param", "set", "torque_limit=2000"]).unwrap();
    cli(&["param", "get", "torque_limit", "0x0302"]).unwrap();
    cli(&["status", "--seconds", "0.3"]).unwrap();
    cli(&["status", "--follow", "--seconds", "0.3", "--every-ms", "50"]).unwrap();
    let e = cli(&["status", "--follow", "--seconds", "0.2", "--node", "9"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("no telemetry or heartbeat from node 9"), "{e}");
    let e = cli(&["param", "get", "torque_limit", "--node", "5"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("node 5") && e.contains("did not answer"), "{e}");
    let e = cli(&["param", "set", "torque_limit=-1"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("torque_limit takes 0..="), "{e}");
    let e = cli(&["param", "get", "torqe_limit"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("did you mean `torque_limit`"), "{e}");
    let mut bus = InprocHub::named("console-cli").attach("check");
    let mut c = Console::new(&mut bus, 1, Duration::from_millis(500)).unwrap();
    assert_eq!(c.get(params::TORQUE_LIMIT).unwrap(), 2000);
}
