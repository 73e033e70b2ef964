//! Bad input and round trips, property-tested: the decoder never panics on any frame, every
//! frame it accepts re-encodes to the identical identifier and bytes, every typed message it
//! can encode decodes back to itself, and each rejection lands in its counter.

use controller::proto::sensor::{count_delta, Unwrap};
use controller::proto::{
    scale, Actuator, ControlWord, Error, Fault, FaultCode, Heartbeat, Kind, LimitFlags, Message,
    Mode, NodeId, OutputEncoder, ParamCommit, ParamRead, ParamResponse, ParamStatus, ParamWrite,
    RawFrame, RejectCounters, ReplyTo, Sensor, SetpointForce, SetpointMotion, State,
    TelemetryMotion, TelemetryTorque,
};
use embedded_can::{ExtendedId, Frame, StandardId};
use proptest::prelude::*;

fn std_frame(id: u16, data: &[u8]) -> RawFrame {
    RawFrame::new(StandardId::new(id).expect("11-bit id"), data).expect("≤ 8 bytes")
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]

    /// Any standard data frame: no panic; if accepted, re-encoding gives the same frame.
    #[test]
    fn arbitrary_frames_never_panic_and_accepted_ones_round_trip(
        id in 0u16..=0x7FF,
        data in proptest::collection::vec(any::<u8>(), 0..=8),
    ) {
        let rx = std_frame(id, &data);
        if let Ok((node, msg)) = Message::decode(&rx) {
            let tx: RawFrame = msg.encode(node).expect("an accepted message must re-encode");
            prop_assert_eq!(tx.standard_id(), Some(id));
            prop_assert_eq!(tx.data(), &data[..]);
        }
    }

    /// Correct id and exact length: any rejection is a field-level error of that kind.
    #[test]
    fn right_length_payloads_fail_only_on_fields(
        k in 1u8..=14,
        node in 1u8..=127,
        bytes in any::<[u8; 8]>(),
    ) {
        let kind = Kind::from_u8(k).expect("kind");
        let id = u16::from(k) << 7 | u16::from(node);
        let data = &bytes[..kind.dlc()];
        match Message::decode(&std_frame(id, data)) {
            Ok((n, m)) => {
                prop_assert_eq!(n.get(), node);
                prop_assert_eq!(m.kind(), kind);
            }
            Err(Error::ReservedBits { kind: ek, .. })
            | Err(Error::OutOfRange { kind: ek, .. })
            | Err(Error::Inconsistent { kind: ek, .. }) => prop_assert_eq!(ek, kind),
            Err(e) => prop_assert!(false, "unexpected {:?}", e),
        }
    }

    /// Any other length is `WrongLength` with the kind's DLC, before any field is looked at.
    #[test]
    fn wrong_lengths_are_rejected(k in 1u8..=14, n in 0usize..8, bytes in any::<[u8; 8]>()) {
        let kind = Kind::from_u8(k).expect("kind");
        // Map 0..8 onto the 8 lengths in 0..=8 other than the kind's DLC.
        let len = if n >= kind.dlc() { n + 1 } else { n };
        let r = Message::decode(&std_frame(u16::from(k) << 7 | 1, &bytes[..len]));
        prop_assert_eq!(r, Err(Error::WrongLength { kind, expected: kind.dlc() as u8, got: len as u8 }));
    }

    /// 29-bit identifiers and remote frames are rejected whatever they carry.
    #[test]
    fn extended_and_remote_frames_are_rejected(
        ext in 0u32..=0x1FFF_FFFF,
        id in 0u16..=0x7FF,
        dlc in 0usize..=8,
        data in proptest::collection::vec(any::<u8>(), 0..=8),
    ) {
        let e = RawFrame::new(ExtendedId::new(ext).expect("29-bit"), &data).expect("frame");
        prop_assert_eq!(Message::decode(&e), Err(Error::ExtendedId));
        let r = RawFrame::new_remote(StandardId::new(id).expect("11-bit"), dlc).expect("frame");
        prop_assert_eq!(Message::decode(&r), Err(Error::RemoteFrame));
    }

    /// Typed messages → frame → the same typed message (for every message the encoder accepts).
    #[test]
    fn typed_messages_round_trip(msg in any_message(), node in 1u8..=127) {
        let node = NodeId::new(node).expect("node");
        match msg.encode::<RawFrame>(node) {
            Ok(f) => prop_assert_eq!(Message::decode(&f), Ok((node, msg))),
            // The only typed values without a wire form are the documented inconsistencies.
            Err(Error::Inconsistent { .. }) => {}
            Err(e) => prop_assert!(false, "unexpected encode error {:?} for {:?}", e, msg),
        }
    }

    /// Multi-turn unwrap recovers any trajectory whose steps stay within ±2³¹ − 1 counts
    /// (modulo 2³², the documented wrap of the i32 position space).
    #[test]
    fn unwrap_recovers_trajectories(start in any::<i64>(), steps in proptest::collection::vec(-(1i64 << 31) + 1..(1i64 << 31), 1..50)) {
        let mut truth = start;
        let mut u = Unwrap::new();
        prop_assert_eq!(u.update(truth as u32), truth as u32 as i32);
        for s in steps {
            truth = truth.wrapping_add(s);
            let pos = u.update(truth as u32);
            prop_assert_eq!(pos, truth as u32 as i32);
        }
    }

    #[test]
    fn velocity_wire_conversion(v in any::<i32>()) {
        let (w, sat) = scale::velocity_to_wire(v);
        let back = scale::velocity_from_wire(w);
        if sat {
            prop_assert!(w == i16::MAX || w == i16::MIN);
            prop_assert!((v > 0) == (w > 0));
        } else {
            prop_assert!((i64::from(back) - i64::from(v)).abs() <= 4, "{} -> {} -> {}", v, w, back);
        }
    }
}

fn pick<T: Copy + std::fmt::Debug + 'static>(all: &'static [T]) -> impl Strategy<Value = T> {
    proptest::sample::select(all)
}

fn limits() -> impl Strategy<Value = LimitFlags> {
    (0u8..64).prop_map(LimitFlags::from_bits_truncate)
}

fn any_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (pick(FaultCode::ALL), limits(), any::<i32>()).prop_map(|(code, limits, detail)| {
            Message::Fault(Fault {
                code,
                limits,
                detail,
            })
        }),
        (any::<u32>(), any::<u8>()).prop_map(|(c, s)| Message::OutputEncoder(OutputEncoder {
            output_counts: c,
            seq: s
        })),
        (
            any::<u32>(),
            any::<Option<i16>>(),
            any::<u8>(),
            any::<bool>(),
            any::<bool>()
        )
            .prop_map(
                |(motor_counts, output_torque, seq, output_encoder, encoder_error)| {
                    Message::Sensor(Sensor {
                        motor_counts,
                        output_torque,
                        seq,
                        output_encoder,
                        encoder_error,
                    })
                }
            ),
        (
            any::<i16>(),
            any::<u8>(),
            limits(),
            any::<bool>(),
            any::<bool>()
        )
            .prop_map(|(torque, seq, limits, drive, fault)| {
                Message::Actuator(Actuator {
                    torque,
                    seq,
                    limits,
                    drive,
                    fault,
                })
            }),
        (any::<i32>(), any::<i16>(), any::<i16>()).prop_map(
            |(position, velocity_ff, torque_ff)| {
                Message::SetpointMotion(SetpointMotion {
                    position,
                    velocity_ff,
                    torque_ff,
                })
            }
        ),
        any::<i16>().prop_map(|t| Message::SetpointForce(SetpointForce { output_torque: t })),
        prop_oneof![
            Just(ControlWord::KeepAlive),
            Just(ControlWord::Shutdown),
            pick(Mode::ALL).prop_map(ControlWord::Enable),
            Just(ControlWord::Disable),
            Just(ControlWord::QuickStop),
            Just(ControlWord::ClearFault),
        ]
        .prop_map(Message::ControlWord),
        (any::<i32>(), any::<i16>(), any::<u8>()).prop_map(|(position, velocity, seq)| {
            Message::TelemetryMotion(TelemetryMotion {
                position,
                velocity,
                seq,
            })
        }),
        (any::<i16>(), any::<i16>(), any::<u8>(), limits()).prop_map(
            |(torque_cmd, output_torque, seq, limits)| {
                Message::TelemetryTorque(TelemetryTorque {
                    torque_cmd,
                    output_torque,
                    seq,
                    limits,
                })
            }
        ),
        (1u16.., any::<i32>(), any::<u8>()).prop_map(|(param_id, value, set_seq)| {
            Message::ParamWrite(ParamWrite {
                param_id,
                value,
                set_seq,
            })
        }),
        (any::<u8>(), any::<u8>(), any::<u32>()).prop_map(|(set_seq, count, crc)| {
            Message::ParamCommit(ParamCommit {
                set_seq,
                count,
                crc,
            })
        }),
        (1u16..).prop_map(|param_id| Message::ParamRead(ParamRead { param_id })),
        (
            pick(ReplyTo::ALL),
            pick(ParamStatus::ALL),
            any::<u8>(),
            any::<u16>(),
            any::<i32>()
        )
            .prop_map(|(reply_to, status, set_seq, param_id, value)| {
                Message::ParamResponse(ParamResponse {
                    reply_to,
                    status,
                    set_seq,
                    param_id,
                    value,
                })
            }),
        (
            pick(State::ALL),
            proptest::option::of(pick(Mode::ALL)),
            proptest::option::of(pick(FaultCode::ALL)),
            limits(),
            any::<u16>(),
            any::<u8>(),
            any::<u8>()
        )
            .prop_map(|(state, mode, fault, limits, m, r, v)| {
                Message::Heartbeat(Heartbeat {
                    state,
                    mode,
                    fault,
                    limits,
                    rejected_malformed: m,
                    rejected_refused: r,
                    protocol_version: v,
                })
            }),
    ]
}

#[test]
fn count_delta_across_the_wrap() {
    assert_eq!(count_delta(0xFFFF_FFF0, 0x0000_0010), 0x20);
    assert_eq!(count_delta(0x0000_0010, 0xFFFF_FFF0), -0x20);
    assert_eq!(count_delta(5, 5), 0);
}

#[test]
fn reject_counters_count_by_category_and_saturate() {
    let mut c = RejectCounters::new();
    let errs = [
        Error::RemoteFrame,
        Error::ExtendedId,
        Error::UnknownKind { kind: 15 },
        Error::BroadcastNotAllowed { kind: Kind::Sensor },
        Error::WrongLength {
            kind: Kind::Sensor,
            expected: 8,
            got: 3,
        },
        Error::ReservedBits {
            kind: Kind::Sensor,
            field: "flags",
        },
        Error::OutOfRange {
            kind: Kind::Fault,
            field: "code",
        },
        Error::Inconsistent {
            kind: Kind::Actuator,
            field: "torque",
        },
    ];
    for e in &errs {
        c.record(e);
    }
    assert_eq!(
        [
            c.remote,
            c.extended,
            c.unknown_kind,
            c.broadcast,
            c.length,
            c.reserved_bits,
            c.out_of_range,
            c.inconsistent
        ],
        [1; 8]
    );
    assert_eq!(c.malformed_total(), 8);
    c.record_refused();
    assert_eq!(c.refused_u8(), 1);
    assert_eq!(c.malformed_total(), 8, "refused frames are not malformed");

    for _ in 0..70_000 {
        c.record(&Error::RemoteFrame);
        c.record_refused();
    }
    assert_eq!(c.remote, u16::MAX);
    assert_eq!(c.malformed_total(), u16::MAX);
    assert_eq!(c.refused_u8(), u8::MAX);
}

#[test]
fn decoder_errors_are_counted_end_to_end() {
    // What a card's receive path does: decode, count the failures.
    let mut c = RejectCounters::new();
    let frames = [
        std_frame(0x181, &[0; 7]),                   // wrong length
        std_frame(0x781, &[0; 8]),                   // kind 15
        std_frame(0x180, &[0, 0, 0, 0, 0, 0, 0, 1]), // broadcast sensor
        std_frame(0x181, &[0, 0, 0, 0, 0, 0, 0, 0]), // fine
    ];
    let mut ok = 0;
    for f in &frames {
        match Message::decode(f) {
            Ok(_) => ok += 1,
            Err(e) => c.record(&e),
        }
    }
    assert_eq!(ok, 1);
    assert_eq!((c.length, c.unknown_kind, c.broadcast), (1, 1, 1));
    assert_eq!(c.malformed_total(), 3);
}

#[test]
fn cards_act_on_to_card_frames_for_their_node_or_broadcast() {
    use controller::proto::Direction;
    let me = NodeId::new(3).expect("node");
    let other = NodeId::new(4).expect("node");
    assert!(Message::is_for(me, Kind::Sensor, me));
    assert!(!Message::is_for(other, Kind::Sensor, me));
    assert!(Message::is_for(NodeId::BROADCAST, Kind::ControlWord, me));
    // Another card's output with our node number is still not for us (e.g. a heartbeat).
    assert!(!Message::is_for(me, Kind::Heartbeat, me));
    let to_card: Vec<_> = Kind::ALL
        .iter()
        .filter(|k| k.direction() == Direction::ToCard)
        .map(|k| k.name())
        .collect();
    assert_eq!(
        to_card,
        [
            "OutputEncoder",
            "Sensor",
            "SetpointMotion",
            "SetpointForce",
            "ControlWord",
            "ParamWrite",
            "ParamCommit",
            "ParamRead"
        ]
    );
}
