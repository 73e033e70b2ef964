//! The in-process bus in the shape the HIL uses it: a plant thread and a card thread in
//! lockstep at 1 kHz (the sensor frame is the card's tick), a recorder node that writes a
//! candump log with simulated timestamps, and the bus load by simulated time.

use std::time::Duration;

use jointlab_can::bus::{open_bus, CanBus, ClassicFrame, InprocHub};
use jointlab_can::candump::{CandumpReader, CandumpWriter, LoggedFrame, Timestamp};

const SENSOR: u16 = 0x080;
const ACTUATOR: u16 = 0x081;
const TICKS: u32 = 1000;
const T: Duration = Duration::from_secs(5);

/// Runs one lockstep session on hub `name`; returns the recorder's candump log.
fn session(name: &str) -> (String, jointlab_can::bus::BusStats) {
    let spec = format!("inproc:{name}");
    let mut recorder = open_bus(&spec).unwrap();
    let mut plant = open_bus(&spec).unwrap();
    let mut card = open_bus(&spec).unwrap();
    let hub = InprocHub::named(name);
    hub.reset_stats();

    let card_thread = std::thread::spawn(move || {
        for _ in 0..TICKS {
            let s = card.recv_timeout(T).unwrap().expect("sensor frame");
            assert_eq!(s.raw_id(), u32::from(SENSOR));
            let counts = i32::from_le_bytes(s.data()[0..4].try_into().unwrap());
            let seq = &s.data()[6..8];
            let torque = (-counts / 4).clamp(-3000, 3000) as i16;
            let t = torque.to_le_bytes();
            card.send(&ClassicFrame::std(ACTUATOR, &[t[0], t[1], seq[0], seq[1]]).unwrap())
                .unwrap();
        }
    });
    let plant_thread = std::thread::spawn(move || {
        let mut pos: i32 = 4000;
        for tick in 0..TICKS {
            let mut d = [0u8; 8];
            d[0..4].copy_from_slice(&pos.to_le_bytes());
            d[6..8].copy_from_slice(&(tick as u16).to_le_bytes());
            plant.send(&ClassicFrame::std(SENSOR, &d).unwrap()).unwrap();
            let a = plant.recv_timeout(T).unwrap().expect("actuator frame");
            assert_eq!(a.raw_id(), u32::from(ACTUATOR));
            assert_eq!(&a.data()[2..4], &d[6..8], "seq echoed");
            let torque = i16::from_le_bytes([a.data()[0], a.data()[1]]);
            pos += i32::from(torque) / 8;
        }
        pos
    });
    card_thread.join().unwrap();
    let final_pos = plant_thread.join().unwrap();
    assert!(final_pos.abs() < 4000, "the loop converged: {final_pos}");

    let stats = hub.stats();
    let mut log = CandumpWriter::new(Vec::new());
    let mut tick = 0u64;
    while let Some(f) = recorder.try_recv().unwrap() {
        if f.raw_id() == u32::from(SENSOR) {
            tick = u64::from(u16::from_le_bytes([f.data()[6], f.data()[7]]));
        }
        let t = Timestamp::from_duration(Duration::from_micros(tick * 1000));
        log.write_frame(t, "inproc", &f).unwrap();
    }
    (String::from_utf8(log.into_inner()).unwrap(), stats)
}

#[test]
fn lockstep_is_deterministic_and_logged() {
    let (log1, stats) = session("lockstep-1");
    let (log2, _) = session("lockstep-2");
    assert_eq!(log1, log2, "bit-identical recordings");
    let recs: Vec<_> = CandumpReader::new(log1.as_bytes())
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(recs.len(), 2 * TICKS as usize);
    assert!(matches!(recs[0].frame, LoggedFrame::Can(f) if f.raw_id() == 0x080));
    assert_eq!(stats.frames, u64::from(2 * TICKS));

    // One joint at 1 kHz on 1 Mbit/s, by simulated time (TICKS ms): design says well < 50 %.
    let sim = Duration::from_millis(u64::from(TICKS));
    let load = stats.load_over(1_000_000, sim);
    let worst = stats.worst_case_load_over(1_000_000, sim);
    assert!(
        load > 0.15 && load <= worst && worst < 0.5,
        "{load} {worst}"
    );
    let _ = std::io::Write::write_all(
        &mut std::io::stderr(),
        format!(
            "bus load, 1 joint at 1 kHz, 1 Mbit/s (sensor 8 B + actuator 4 B): exact {:.1} %, worst case {:.1} %\n",
            load * 100.0,
            worst * 100.0
        )
        .as_bytes(),
    );
}
