//! Card runtime behaviour through its sans-IO interface: frames in, actuator and frames out,
//! time given by the test. The plant is a rigid inertia integrated in f64 here.

use controller::card::si;
use controller::card::{Card, Sensors};
use controller::proto::params as p;
use controller::proto::scale::MOTOR_TORQUE_NM_PER_LSB;
use controller::proto::{
    ControlWord, FaultCode, Message, Mode, NodeId, ParamCommit, ParamStatus, ParamWrite, RawFrame,
    ReplyTo, SetChecksum, SetpointMotion, State,
};
use controller::units::Scale;
use embedded_can::{Frame, StandardId};
use proptest::prelude::*;

const NODE: u8 = 3;

fn node() -> NodeId {
    NodeId::new(NODE).unwrap()
}

fn frame(m: Message) -> RawFrame {
    m.encode(node()).unwrap()
}

/// Rigid rotor I·θ̈ = τ + load − b·θ̇, encoder `cpr`, integrated with 10 substeps per ms.
struct Rotor {
    theta: f64,
    omega: f64,
    inertia: f64,
    b: f64,
    load: f64,
    cpr: f64,
}

impl Rotor {
    fn new() -> Self {
        Rotor {
            theta: 0.0,
            omega: 0.0,
            inertia: 1e-5,
            b: 1e-5,
            load: 0.0,
            cpr: 2304.0,
        }
    }
    fn counts(&self) -> u32 {
        (self.theta / std::f64::consts::TAU * self.cpr).floor() as i64 as i32 as u32
    }
    fn advance(&mut self, tau_nm: f64) {
        let h = 1e-4;
        for _ in 0..10 {
            let acc = (tau_nm + self.load - self.b * self.omega) / self.inertia;
            self.omega += acc * h;
            self.theta += self.omega * h;
        }
    }
}

struct Rig {
    card: Card,
    now: u64,
    seq: u8,
    set_seq: u8,
    rotor: Rotor,
    sent: Vec<Message>,
}

impl Rig {
    fn new() -> Self {
        Rig {
            card: Card::new(node()).unwrap(),
            now: 0,
            seq: 0,
            set_seq: 0,
            rotor: Rotor::new(),
            sent: vec![],
        }
    }
    fn send(&mut self, m: Message) {
        assert!(self.card.handle_frame(self.now, &frame(m)).is_none());
        self.drain();
    }
    fn drain(&mut self) {
        while let Some(m) = self.card.poll_transmit() {
            self.sent.push(m);
        }
    }
    fn last_reply(&self) -> controller::proto::ParamResponse {
        self.sent
            .iter()
            .rev()
            .find_map(|m| match m {
                Message::ParamResponse(r) => Some(*r),
                _ => None,
            })
            .expect("a parameter reply")
    }
    /// Stages and commits `entries`; returns the commit reply status.
    fn commit(&mut self, entries: &[(u16, i32)]) -> ParamStatus {
        self.set_seq = self.set_seq.wrapping_add(1);
        for &(id, v) in entries {
            self.send(Message::ParamWrite(ParamWrite {
                param_id: id,
                value: v,
                set_seq: self.set_seq,
            }));
        }
        let sum = SetChecksum::of(entries);
        self.send(Message::ParamCommit(ParamCommit {
            set_seq: self.set_seq,
            count: sum.count(),
            crc: sum.crc(),
        }));
        let r = self.last_reply();
        assert_eq!(r.reply_to, ReplyTo::Commit);
        r.status
    }
    /// One 1 ms tick: sensor frame → actuator → plant.
    fn tick(&mut self) -> controller::proto::Actuator {
        self.now += 1000;
        self.seq = self.seq.wrapping_add(1);
        let s = controller::proto::Sensor {
            motor_counts: self.rotor.counts(),
            output_torque: Some(0),
            seq: self.seq,
            output_encoder: false,
            encoder_error: false,
        };
        let a = self
            .card
            .handle_frame(self.now, &frame(Message::Sensor(s)))
            .expect("actuator");
        assert_eq!(a.seq, self.seq);
        self.rotor
            .advance(f64::from(a.torque) * MOTOR_TORQUE_NM_PER_LSB);
        self.drain();
        a
    }
    fn keepalive(&mut self) {
        self.send(Message::ControlWord(ControlWord::KeepAlive));
    }
    fn setpoint(&mut self, counts: i32) {
        self.send(Message::SetpointMotion(SetpointMotion {
            position: counts,
            velocity_ff: 0,
            torque_ff: 0,
        }));
    }
    fn faults(&self) -> Vec<FaultCode> {
        self.sent
            .iter()
            .filter_map(|m| match m {
                Message::Fault(f) => Some(f.code),
                _ => None,
            })
            .collect()
    }
}

fn pd_gains(ke: f64, be: f64, limit_nm: f64) -> Vec<(u16, i32)> {
    let s = Scale::thesis(1.0);
    vec![
        (p::KE, si::stiffness(&s, ke).unwrap()),
        (p::BE, si::damping(p::BE, &s, be).unwrap()),
        (
            p::TORQUE_LIMIT,
            si::torque(p::TORQUE_LIMIT, limit_nm).unwrap(),
        ),
        (
            p::QUICK_STOP_DAMPING,
            si::damping(p::QUICK_STOP_DAMPING, &s, be).unwrap(),
        ),
    ]
}

fn armed(mode: Mode, gains: &[(u16, i32)]) -> Rig {
    let mut r = Rig::new();
    assert_eq!(r.commit(gains), ParamStatus::Ok);
    r.tick();
    r.send(Message::ControlWord(ControlWord::Shutdown));
    assert_eq!(r.card.state(), State::Ready);
    r.send(Message::ControlWord(ControlWord::Enable(mode)));
    assert_eq!(r.card.state(), State::Enabled);
    r
}

#[test]
fn defaults_build_and_card_starts_disabled_with_zero_torque() {
    let mut r = Rig::new();
    let a = r.tick();
    assert_eq!(r.card.state(), State::Disabled);
    assert_eq!((a.torque, a.drive, a.fault), (0, false, false));
    // the first heartbeat goes out at once
    assert!(r.sent.iter().any(|m| matches!(m, Message::Heartbeat(_))));
}

#[test]
fn commit_applies_atomically_at_the_next_tick_and_read_back_works() {
    let mut r = Rig::new();
    let g = pd_gains(2.0, 0.008, 1.0);
    assert_eq!(r.commit(&g), ParamStatus::Ok);
    // not yet applied: a read answers the active value
    r.send(Message::ParamRead(controller::proto::ParamRead {
        param_id: p::KE,
    }));
    assert_eq!(r.last_reply().value, 0);
    r.tick();
    r.send(Message::ParamRead(controller::proto::ParamRead {
        param_id: p::KE,
    }));
    assert_eq!(r.last_reply().value, g[0].1);
    assert_eq!(r.card.params().get(p::COMMIT_COUNT), Ok(1));
}

#[test]
fn bad_commits_are_rejected_whole() {
    let mut r = Rig::new();
    // wrong checksum
    r.send(Message::ParamWrite(ParamWrite {
        param_id: p::KE,
        value: 1000,
        set_seq: 7,
    }));
    r.send(Message::ParamCommit(ParamCommit {
        set_seq: 7,
        count: 1,
        crc: 0xDEAD_BEEF,
    }));
    assert_eq!(r.last_reply().status, ParamStatus::ChecksumMismatch);
    // wrong sequence
    r.send(Message::ParamWrite(ParamWrite {
        param_id: p::KE,
        value: 1000,
        set_seq: 8,
    }));
    let sum = SetChecksum::of(&[(p::KE, 1000)]);
    r.send(Message::ParamCommit(ParamCommit {
        set_seq: 9,
        count: 1,
        crc: sum.crc(),
    }));
    assert_eq!(r.last_reply().status, ParamStatus::SequenceMismatch);
    // an out-of-range write is refused at once
    r.send(Message::ParamWrite(ParamWrite {
        param_id: p::TORQUE_LIMIT,
        value: 40_000,
        set_seq: 10,
    }));
    assert_eq!(r.last_reply().status, ParamStatus::OutOfRange);
    // stability guard: a huge Ke with tiny Be
    let s = Scale::thesis(1.0);
    let bad = [
        (p::KE, si::stiffness(&s, 50.0).unwrap()),
        (p::BE, si::damping(p::BE, &s, 0.001).unwrap()),
    ];
    assert_eq!(r.commit(&bad), ParamStatus::InconsistentSet);
    assert_eq!(r.last_reply().param_id, p::KE);
    // Ke without any damping is unstable at any gain (§2.9)
    assert_eq!(r.commit(&[(p::KE, 1000)]), ParamStatus::InconsistentSet);
    r.tick();
    assert_eq!(
        r.card.params().get(p::KE),
        Ok(0),
        "nothing of the bad sets was applied"
    );
    assert!(r.card.counters().refused >= 5);
}

#[test]
fn state_machine_refuses_out_of_order_commands() {
    let mut r = Rig::new();
    r.tick();
    r.send(Message::ControlWord(ControlWord::Enable(
        Mode::PositionPdColocated,
    )));
    assert_eq!(r.card.state(), State::Disabled, "enable needs Ready first");
    r.send(Message::ControlWord(ControlWord::ClearFault));
    assert_eq!(r.card.counters().refused, 2);
    r.send(Message::ControlWord(ControlWord::Shutdown));
    assert_eq!(r.card.state(), State::Ready);
    r.send(Message::ControlWord(ControlWord::Disable));
    assert_eq!(r.card.state(), State::Disabled);
}

#[test]
fn position_pd_reaches_a_step_setpoint() {
    let mut r = armed(Mode::PositionPdColocated, &pd_gains(2.0, 0.008, 1.0));
    r.setpoint(500);
    for k in 0..600 {
        r.tick();
        if k % 20 == 0 {
            r.keepalive();
        }
    }
    let err = r.rotor.counts() as i32 - 500;
    assert!(err.abs() <= 1, "final error {err} counts");
    assert!(r.faults().is_empty());
}

#[test]
fn supervisor_watchdog_reacts_within_timeout_plus_one_cycle() {
    let mut g = pd_gains(2.0, 0.008, 1.0);
    g.push((p::SUPERVISOR_TIMEOUT, 50));
    g.push((p::WATCHDOG_REACTION, p::WatchdogReaction::QuickStop as i32));
    let mut r = armed(Mode::PositionPdColocated, &g);
    let last_feed = r.now;
    let mut fired_at = None;
    for _ in 0..200 {
        r.tick();
        if !r.faults().is_empty() {
            fired_at = Some(r.now);
            break;
        }
    }
    let fired_at = fired_at.expect("watchdog fired");
    assert_eq!(r.faults(), vec![FaultCode::SupervisorWatchdog]);
    let late = fired_at - last_feed;
    assert!(late > 50_000 && late <= 51_000, "reaction after {late} µs");
    assert!(matches!(
        r.card.state(),
        State::FaultReaction | State::Fault
    ));
    // latched: keep-alives do not clear it, ClearFault does (once the reaction is done)
    for _ in 0..50 {
        r.tick();
        r.keepalive();
    }
    assert_eq!(r.card.state(), State::Fault);
    r.send(Message::ControlWord(ControlWord::ClearFault));
    assert_eq!(r.card.state(), State::Disabled);
}

#[test]
fn missing_sensor_frames_fault_the_card() {
    let mut r = armed(Mode::PositionPdColocated, &pd_gains(2.0, 0.008, 1.0));
    r.tick();
    let t0 = r.now;
    r.card.poll(t0 + 2_000);
    assert_eq!(
        r.card.state(),
        State::Enabled,
        "within the 3 ms default timeout"
    );
    r.card.poll(t0 + 3_500);
    r.drain();
    assert_eq!(r.card.state(), State::Fault);
    assert_eq!(r.faults(), vec![FaultCode::SensorTimeout]);
    // and the next actuator frame commands nothing
    let a = r.tick();
    assert_eq!((a.torque, a.drive, a.fault), (0, false, true));
}

#[test]
fn skipped_sequence_numbers_beyond_tolerance_fault() {
    let mut r = armed(Mode::PositionPdColocated, &pd_gains(2.0, 0.008, 1.0));
    r.tick();
    r.seq = r.seq.wrapping_add(3); // 3 lost > default 2
    r.tick();
    assert_eq!(r.faults(), vec![FaultCode::SequenceError]);
}

/// Single lost sensor frames stay within `max_seq_skip` and do not fault the card, but the
/// card counts every one of them.
#[test]
fn tolerated_sequence_gaps_are_counted() {
    let mut r = armed(Mode::PositionPdColocated, &pd_gains(2.0, 0.008, 1.0));
    r.tick();
    for _ in 0..10 {
        r.seq = r.seq.wrapping_add(1); // one lost
        r.tick();
        r.tick();
    }
    assert!(r.faults().is_empty(), "{:?}", r.faults());
    assert_eq!(r.card.sensor_frames_lost(), 10);
    assert_eq!(r.card.state(), State::Enabled);
}

/// Bus-off (or error-passive) is a fault with torque off at the very next tick; a degraded
/// bus (warning level, protocol error, no ACK, overflow) is counted and changes nothing.
#[test]
fn bus_errors_fault_and_bus_warnings_count() {
    let mut r = armed(Mode::PositionPdColocated, &pd_gains(2.0, 0.008, 1.0));
    r.setpoint(400);
    for _ in 0..20 {
        r.tick();
    }
    assert_ne!(r.tick().torque, 0, "driving before the fault");
    r.card.bus_warning();
    r.card.bus_warning();
    assert_eq!(r.card.bus_warnings(), 2);
    assert_eq!(r.card.state(), State::Enabled);
    assert_ne!(r.tick().torque, 0, "a warning changes nothing");
    r.card.bus_error(0x40);
    r.drain();
    assert_eq!(r.faults(), vec![FaultCode::BusError]);
    assert_eq!(r.card.fault(), Some((FaultCode::BusError, 0x40)));
    let a = r.tick();
    assert_eq!((a.torque, a.drive, a.fault), (0, false, true));
    assert_eq!(r.card.state(), State::Fault);
}

#[test]
fn bumpless_gain_commit_with_unchanged_error() {
    let mut g = pd_gains(2.0, 0.008, 1.0);
    g.push((p::KI, si::integral(&Scale::thesis(1.0), 20.0).unwrap()));
    g.push((p::INTEGRATOR_LIMIT, 5000));
    let mut r = armed(Mode::PositionPid, &g);
    r.rotor.load = 0.05; // a constant load the integrator must carry
    r.setpoint(100);
    for k in 0..300 {
        r.tick();
        if k % 20 == 0 {
            r.keepalive();
        }
    }
    let before = r.tick().torque;
    // freeze the rotor so the error is unchanged across the commit
    r.rotor.omega = 0.0;
    r.rotor.load = 0.0;
    r.rotor.inertia = 1e9;
    let new = pd_gains(2.5, 0.009, 1.0);
    assert_eq!(r.commit(&new), ParamStatus::Ok);
    let at = r.tick().torque;
    assert!(
        (i32::from(at) - i32::from(before)).abs() <= 2,
        "{before} -> {at}"
    );
}

#[test]
fn malformed_frames_are_counted_not_acted_upon() {
    let mut r = Rig::new();
    let id = StandardId::new(0x7FF).unwrap(); // kind 15: reserved
    let f = RawFrame::new(id, &[1, 2, 3]).unwrap();
    assert!(r.card.handle_frame(0, &f).is_none());
    let sensor_wrong_dlc =
        RawFrame::new(StandardId::new(3 << 7 | u16::from(NODE)).unwrap(), &[0; 5]).unwrap();
    assert!(r.card.handle_frame(0, &sensor_wrong_dlc).is_none());
    assert_eq!(r.card.counters().unknown_kind, 1);
    assert_eq!(r.card.counters().length, 1);
    assert_eq!(r.card.state(), State::Disabled);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    /// Arbitrary frames never panic the card, and never make a Disabled card drive.
    #[test]
    fn arbitrary_frames_never_panic(frames in prop::collection::vec((0u16..0x800, prop::collection::vec(any::<u8>(), 0..=8)), 1..200)) {
        let mut card = Card::new(node()).unwrap();
        for (k, (id, data)) in frames.iter().enumerate() {
            let f = RawFrame::new(StandardId::new(*id).unwrap(), data).unwrap();
            if let Some(a) = card.handle_frame(k as u64 * 1000, &f) {
                prop_assert!(a.drive || a.torque == 0);
            }
            while card.poll_transmit().is_some() {}
        }
    }

    /// The torque limit is never exceeded, whatever the gains, mode, setpoints and sensors:
    /// 64 cases × 16 000 ticks ≈ 1e6 randomized steps.
    #[test]
    fn torque_limit_is_never_exceeded(
        limit in 1i32..=i16::MAX as i32,
        // (Ke, Be) inside the §2.9 region at the largest inertia the table admits; the force
        // and impedance gains, which the guard does not cover, over their full range.
        ke in 0i32..(1 << 20), be in (1i32 << 24)..i32::MAX, ki in 0i32..1_000_000,
        fk in 0i32..i32::MAX, km in i32::MIN..i32::MAX,
        friction in any::<bool>(), coulomb in 0i32..=i16::MAX as i32,
        mode in prop::sample::select(Mode::ALL.to_vec()),
        seed in 1u64..u64::MAX,
    ) {
        let mut rig = Rig::new();
        // a huge inertia and no margin so that extreme gains pass the guard
        let entries = [
            (p::ROTOR_INERTIA, i32::MAX), (p::STABILITY_MARGIN, 65536),
            (p::KE, ke), (p::BE, be), (p::KI, ki), (p::INTEGRATOR_LIMIT, 30_000),
            (p::FORCE_KP, fk), (p::FORCE_KI, ki), (p::FORCE_KD, be), (p::KM, km),
            (p::TORQUE_LIMIT, limit), (p::FRICTION_ENABLE, i32::from(friction)),
            (p::COULOMB_POS, coulomb), (p::COULOMB_NEG, coulomb), (p::VELOCITY_LIMIT, i32::MAX),
            (p::SUPERVISOR_TIMEOUT, 60_000), (p::OUTPUT_COUNTS_PER_REV, 4096),
        ];
        let st = rig.commit(&entries);
        prop_assert_eq!(st, ParamStatus::Ok, "param {:#x}", rig.last_reply().param_id);
        rig.tick();
        rig.send(Message::ControlWord(ControlWord::Shutdown));
        rig.send(Message::ControlWord(ControlWord::Enable(mode)));
        let mut x = seed;
        let mut driven = 0u32;
        let (mut motor, mut out) = (0u32, 0u32);
        for _ in 0..16_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            rig.now += 1000;
            rig.seq = rig.seq.wrapping_add(1);
            if x % 97 == 0 {
                rig.send(Message::SetpointMotion(SetpointMotion {
                    position: x as i32,
                    velocity_ff: (x >> 8) as i16,
                    torque_ff: (x >> 24) as i16,
                }));
            }
            // random walks with occasional wild jumps
            motor = motor.wrapping_add(((x >> 16) as i32 % 3000) as u32);
            out = out.wrapping_add(((x >> 20) as i32 % 300) as u32);
            if x % 1009 == 0 {
                motor = (x >> 32) as u32;
            }
            let s = Sensors {
                motor_counts: motor,
                output_torque: Some(((x >> 40) as i16).max(-i16::MAX)),
                output_counts: Some(out),
                seq: rig.seq,
                encoder_error: false,
            };
            let a = rig.card.step(rig.now, &s);
            prop_assert!(i32::from(a.torque).abs() <= limit, "{} > {}", a.torque, limit);
            prop_assert!(a.drive || a.torque == 0);
            driven += u32::from(a.drive && a.torque != 0);
            while rig.card.poll_transmit().is_some() {}
        }
        // (with friction FF on, a saturated damper and a saturated FF may cancel exactly)
        prop_assert!(friction || driven > 1000, "the card must actually drive to test the limit: {driven} {:?} {:?}", rig.card.state(), rig.card.fault());
    }
}

#[test]
fn watchdog_hold_position_holds_until_cleared() {
    let mut g = pd_gains(2.0, 0.008, 1.0);
    g.push((p::SUPERVISOR_TIMEOUT, 30));
    g.push((
        p::WATCHDOG_REACTION,
        p::WatchdogReaction::HoldPosition as i32,
    ));
    let mut r = armed(Mode::PositionPdColocated, &g);
    r.setpoint(300);
    for _ in 0..25 {
        r.tick();
        r.keepalive();
    }
    // supervisor silent; a load pushes the rotor while the card holds
    for _ in 0..40 {
        r.tick();
    }
    assert_eq!(r.faults(), vec![FaultCode::SupervisorWatchdog]);
    assert_eq!(r.card.state(), State::FaultReaction, "holding, latched");
    let held = r.rotor.counts() as i32;
    r.rotor.load = 0.2;
    let mut max_dev = 0;
    for _ in 0..500 {
        let a = r.tick();
        assert!(a.drive && a.fault, "drives (holds) and reports the fault");
        max_dev = max_dev.max((r.rotor.counts() as i32 - held).abs());
    }
    // a PD hold under load: deflection load/Ke, at 2 N·m/rad ≈ 0.1 rad ≈ 37 counts
    assert!(max_dev > 5 && max_dev < 60, "held within {max_dev} counts");
    r.send(Message::ControlWord(ControlWord::ClearFault));
    assert_eq!(r.card.state(), State::Disabled);
    assert_eq!(r.tick().torque, 0);
}
