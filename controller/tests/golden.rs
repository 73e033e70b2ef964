//! Golden vectors (`docs/golden-vectors.toml`) against the codec, and the worked examples of
//! `docs/protocol.md` against the golden vectors.
//!
//! For every vector: the typed message built from its field values must encode to exactly its
//! id and bytes, and its bytes must decode to exactly that message. Field values are physical
//! (N·m, counts/s) and must be exact multiples of the wire LSB, so the vectors say the same
//! thing to this test and to `docs/check_dbc.py` (which compares them through the DBC).

use controller::proto::{
    id, scale, Actuator, Command, ControlWord, Error, Fault, FaultCode, Heartbeat, Kind,
    LimitFlags, Message, Mode, NodeId, OutputEncoder, ParamCommit, ParamRead, ParamResponse,
    ParamStatus, ParamWrite, RawFrame, ReplyTo, Sensor, SetChecksum, SetpointForce, SetpointMotion,
    State, TelemetryMotion, TelemetryTorque,
};
use embedded_can::{ExtendedId, Frame, StandardId};
use serde::Deserialize;
use std::collections::{BTreeMap, BTreeSet};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GoldenFile {
    vector: Vec<Vector>,
    reject: Vec<Reject>,
    checksum: Vec<Checksum>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Vector {
    name: String,
    message: String,
    node: u8,
    id: String,
    data: String,
    fields: toml::Table,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Reject {
    name: String,
    id: String,
    data: String,
    #[serde(default)]
    extended: bool,
    #[serde(default)]
    remote: bool,
    dlc: Option<usize>,
    error: String,
    kind: Option<String>,
    field: Option<String>,
    expected: Option<u8>,
    got: Option<u8>,
    unknown_kind: Option<u8>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Checksum {
    name: String,
    entries: Vec<(u16, i32)>,
    count: u8,
    crc: u32,
}

fn load() -> GoldenFile {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/golden-vectors.toml");
    let s = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("reading {p}: {e}"));
    toml::from_str(&s).unwrap_or_else(|e| panic!("parsing {p}: {e}"))
}

fn hex_u32(s: &str) -> u32 {
    u32::from_str_radix(s.trim_start_matches("0x"), 16).unwrap_or_else(|e| panic!("id {s}: {e}"))
}

fn hex_bytes(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap_or_else(|e| panic!("byte {b}: {e}")))
        .collect()
}

/// Typed access to one vector's fields; every key must be used exactly by the message's
/// constructor (a typo or a stale field fails the test).
struct Fields<'a> {
    vector: &'a str,
    t: &'a toml::Table,
    used: BTreeSet<String>,
}

impl<'a> Fields<'a> {
    fn get(&mut self, k: &str) -> &'a toml::Value {
        self.used.insert(k.to_string());
        self.t
            .get(k)
            .unwrap_or_else(|| panic!("vector {}: missing field `{k}`", self.vector))
    }
    fn int<T: TryFrom<i64>>(&mut self, k: &str) -> T {
        let v = self
            .get(k)
            .as_integer()
            .unwrap_or_else(|| panic!("{}: `{k}` not an integer", self.vector));
        T::try_from(v).unwrap_or_else(|_| panic!("{}: `{k}` = {v} out of range", self.vector))
    }
    /// A physical value converted to its raw field with LSB `lsb`; must be an exact multiple.
    fn phys<T: TryFrom<i64>>(&mut self, k: &str, lsb: f64) -> T {
        let v = self.get(k);
        let x = v
            .as_float()
            .or_else(|| v.as_integer().map(|i| i as f64))
            .unwrap_or_else(|| panic!("{}: `{k}` not a number", self.vector));
        let raw = (x / lsb).round();
        assert!(
            (raw * lsb - x).abs() <= lsb * 1e-6,
            "{}: `{k}` = {x} is not a multiple of its LSB {lsb}",
            self.vector
        );
        T::try_from(raw as i64)
            .unwrap_or_else(|_| panic!("{}: `{k}` = {x} out of range", self.vector))
    }
    fn boolean(&mut self, k: &str) -> bool {
        self.get(k)
            .as_bool()
            .unwrap_or_else(|| panic!("{}: `{k}` not a bool", self.vector))
    }
    fn name(&mut self, k: &str) -> &'a str {
        self.get(k)
            .as_str()
            .unwrap_or_else(|| panic!("{}: `{k}` not a string", self.vector))
    }
    fn en<T>(&mut self, k: &str, from: fn(&str) -> Option<T>) -> T {
        let n = self.name(k);
        from(n).unwrap_or_else(|| panic!("{}: `{k}` = {n:?} is not a known name", self.vector))
    }
    fn opt_en<T>(&mut self, k: &str, from: fn(&str) -> Option<T>) -> Option<T> {
        let n = self.name(k);
        if n == "None" {
            None
        } else {
            Some(from(n).unwrap_or_else(|| panic!("{}: `{k}` = {n:?} unknown", self.vector)))
        }
    }
    fn limits(&mut self, k: &str) -> LimitFlags {
        let arr = self
            .get(k)
            .as_array()
            .unwrap_or_else(|| panic!("{}: `{k}` not a list", self.vector));
        let mut f = LimitFlags::NONE;
        for v in arr {
            let n = v.as_str().unwrap_or_default();
            let (_, flag) = LimitFlags::NAMED
                .iter()
                .find(|(name, _)| *name == n)
                .unwrap_or_else(|| panic!("{}: unknown limit flag {n:?}", self.vector));
            f |= *flag;
        }
        f
    }
    fn finish(self) {
        let keys: BTreeSet<String> = self.t.keys().cloned().collect();
        let unused: Vec<_> = keys.difference(&self.used).collect();
        assert!(
            unused.is_empty(),
            "vector {}: unused fields {unused:?}",
            self.vector
        );
    }
}

const MT: f64 = scale::MOTOR_TORQUE_NM_PER_LSB;
const OT: f64 = scale::OUTPUT_TORQUE_NM_PER_LSB;
const VEL: f64 = scale::VELOCITY_COUNTS_PER_S_PER_LSB as f64;

fn message_from_fields(v: &Vector) -> Message {
    let mut f = Fields {
        vector: &v.name,
        t: &v.fields,
        used: BTreeSet::new(),
    };
    let m = match v.message.as_str() {
        "Fault" => Message::Fault(Fault {
            code: f.en("code", FaultCode::from_name),
            limits: f.limits("limits"),
            detail: f.int("detail"),
        }),
        "OutputEncoder" => Message::OutputEncoder(OutputEncoder {
            output_counts: f.int("output_counts"),
            seq: f.int("seq"),
        }),
        "Sensor" => {
            let valid = f.boolean("torque_valid");
            let torque: i16 = f.phys("output_torque", OT);
            if !valid {
                assert_eq!(torque, 0, "{}: invalid torque must be 0", v.name);
            }
            Message::Sensor(Sensor {
                motor_counts: f.int("motor_counts"),
                output_torque: valid.then_some(torque),
                seq: f.int("seq"),
                output_encoder: f.boolean("output_encoder"),
                encoder_error: f.boolean("encoder_error"),
            })
        }
        "Actuator" => Message::Actuator(Actuator {
            torque: f.phys("torque", MT),
            seq: f.int("seq"),
            limits: f.limits("limits"),
            drive: f.boolean("drive"),
            fault: f.boolean("fault"),
        }),
        "SetpointMotion" => Message::SetpointMotion(SetpointMotion {
            position: f.int("position"),
            velocity_ff: f.phys("velocity_ff", VEL),
            torque_ff: f.phys("torque_ff", MT),
        }),
        "SetpointForce" => Message::SetpointForce(SetpointForce {
            output_torque: f.phys("output_torque", OT),
        }),
        "ControlWord" => {
            let cmd = f.en("command", Command::from_name);
            let mode = f.opt_en("mode", Mode::from_name);
            Message::ControlWord(match (cmd, mode) {
                (Command::Enable, Some(m)) => ControlWord::Enable(m),
                (Command::KeepAlive, None) => ControlWord::KeepAlive,
                (Command::Shutdown, None) => ControlWord::Shutdown,
                (Command::Disable, None) => ControlWord::Disable,
                (Command::QuickStop, None) => ControlWord::QuickStop,
                (Command::ClearFault, None) => ControlWord::ClearFault,
                other => panic!(
                    "{}: command/mode combination {other:?} is not a message",
                    v.name
                ),
            })
        }
        "TelemetryMotion" => Message::TelemetryMotion(TelemetryMotion {
            position: f.int("position"),
            velocity: f.phys("velocity", VEL),
            seq: f.int("seq"),
        }),
        "TelemetryTorque" => Message::TelemetryTorque(TelemetryTorque {
            torque_cmd: f.phys("torque_cmd", MT),
            output_torque: f.phys("output_torque", OT),
            seq: f.int("seq"),
            limits: f.limits("limits"),
        }),
        "ParamWrite" => Message::ParamWrite(ParamWrite {
            param_id: f.int("param_id"),
            value: f.int("value"),
            set_seq: f.int("set_seq"),
        }),
        "ParamCommit" => Message::ParamCommit(ParamCommit {
            set_seq: f.int("set_seq"),
            count: f.int("count"),
            crc: f.int("crc"),
        }),
        "ParamRead" => Message::ParamRead(ParamRead {
            param_id: f.int("param_id"),
        }),
        "ParamResponse" => Message::ParamResponse(ParamResponse {
            reply_to: f.en("reply_to", ReplyTo::from_name),
            status: f.en("status", ParamStatus::from_name),
            set_seq: f.int("set_seq"),
            param_id: f.int("param_id"),
            value: f.int("value"),
        }),
        "Heartbeat" => Message::Heartbeat(Heartbeat {
            state: f.en("state", State::from_name),
            mode: f.opt_en("mode", Mode::from_name),
            fault: f.opt_en("fault", FaultCode::from_name),
            limits: f.limits("limits"),
            rejected_malformed: f.int("rejected_malformed"),
            rejected_refused: f.int("rejected_refused"),
            protocol_version: f.int("protocol_version"),
        }),
        other => panic!("vector {}: unknown message {other:?}", v.name),
    };
    f.finish();
    assert_eq!(m.kind().name(), v.message, "{}", v.name);
    m
}

#[test]
fn every_vector_encodes_to_its_bytes_and_decodes_to_its_values() {
    let g = load();
    for v in &g.vector {
        let msg = message_from_fields(v);
        let node = NodeId::new(v.node).unwrap_or_else(|| panic!("{}: bad node", v.name));
        let want_id = hex_u32(&v.id);
        let want_data = hex_bytes(&v.data);

        // Values → bytes.
        let frame: RawFrame = msg
            .encode(node)
            .unwrap_or_else(|e| panic!("{}: encode failed: {e:?}", v.name));
        assert_eq!(
            frame.standard_id().map(u32::from),
            Some(want_id),
            "{}: id",
            v.name
        );
        assert_eq!(frame.data(), &want_data[..], "{}: bytes", v.name);
        assert_eq!(
            u32::from(id::compose(msg.kind(), node)),
            want_id,
            "{}",
            v.name
        );

        // Bytes → values.
        let sid = StandardId::new(want_id as u16).unwrap_or_else(|| panic!("{}: id", v.name));
        let rx = RawFrame::new(sid, &want_data).unwrap_or_else(|| panic!("{}: frame", v.name));
        let (n, back) =
            Message::decode(&rx).unwrap_or_else(|e| panic!("{}: decode failed: {e:?}", v.name));
        assert_eq!(n, node, "{}: node", v.name);
        assert_eq!(back, msg, "{}: decoded values", v.name);
    }
}

#[test]
fn several_vectors_per_message_kind() {
    let g = load();
    let mut per: BTreeMap<String, usize> = BTreeMap::new();
    for v in &g.vector {
        *per.entry(v.message.clone()).or_default() += 1;
    }
    for k in Kind::ALL {
        let n = per.get(k.name()).copied().unwrap_or(0);
        assert!(n >= 2, "only {n} golden vector(s) for {}", k.name());
    }
    let names: BTreeSet<_> = g.vector.iter().map(|v| &v.name).collect();
    assert_eq!(names.len(), g.vector.len(), "vector names must be unique");
}

fn expected_error(r: &Reject) -> String {
    let kind = || {
        r.kind
            .clone()
            .unwrap_or_else(|| panic!("{}: needs `kind`", r.name))
    };
    let field = || {
        r.field
            .clone()
            .unwrap_or_else(|| panic!("{}: needs `field`", r.name))
    };
    match r.error.as_str() {
        "ExtendedId" | "RemoteFrame" => r.error.clone(),
        "UnknownKind" => format!("UnknownKind {{ kind: {} }}", r.unknown_kind.unwrap_or(255)),
        "BroadcastNotAllowed" => format!("BroadcastNotAllowed {{ kind: {} }}", kind()),
        "WrongLength" => format!(
            "WrongLength {{ kind: {}, expected: {}, got: {} }}",
            kind(),
            r.expected.unwrap_or(255),
            r.got.unwrap_or(255)
        ),
        "ReservedBits" | "OutOfRange" | "Inconsistent" => {
            format!("{} {{ kind: {}, field: {:?} }}", r.error, kind(), field())
        }
        other => panic!("{}: unknown error {other:?}", r.name),
    }
}

#[test]
fn every_reject_vector_is_rejected_with_its_error() {
    let g = load();
    let mut variants = BTreeSet::new();
    for r in &g.reject {
        let raw = hex_u32(&r.id);
        let data = hex_bytes(&r.data);
        let frame: RawFrame = match (r.extended, r.remote) {
            (true, false) => RawFrame::new(ExtendedId::new(raw).expect("extended id"), &data),
            (false, true) => RawFrame::new_remote(
                StandardId::new(raw as u16).expect("standard id"),
                r.dlc.unwrap_or(0),
            ),
            (false, false) => {
                RawFrame::new(StandardId::new(raw as u16).expect("standard id"), &data)
            }
            (true, true) => panic!("{}: pick extended or remote", r.name),
        }
        .unwrap_or_else(|| panic!("{}: cannot build frame", r.name));
        let err = Message::decode(&frame).expect_err(&r.name);
        assert_eq!(format!("{err:?}"), expected_error(r), "{}", r.name);
        variants.insert(r.error.clone());
    }
    // Every decode-side error variant has at least one spec-level reject vector.
    for v in [
        "ExtendedId",
        "RemoteFrame",
        "UnknownKind",
        "BroadcastNotAllowed",
        "WrongLength",
        "ReservedBits",
        "OutOfRange",
        "Inconsistent",
    ] {
        assert!(variants.contains(v), "no reject vector for {v}");
    }
}

#[test]
fn checksum_vectors() {
    let g = load();
    for c in &g.checksum {
        let s = SetChecksum::of(&c.entries);
        assert_eq!(s.crc(), c.crc, "{}: crc", c.name);
        assert_eq!(s.count(), c.count, "{}: count", c.name);
    }
    // The ParamCommit vectors carry checksums of sets listed here.
    let crcs: BTreeSet<u32> = g.checksum.iter().map(|c| c.crc).collect();
    let commits = g
        .vector
        .iter()
        .filter(|v| v.message == "ParamCommit")
        .filter(|v| v.fields.get("count").and_then(|c| c.as_integer()) != Some(255));
    for v in commits {
        let crc = v
            .fields
            .get("crc")
            .and_then(|c| c.as_integer())
            .unwrap_or(-1);
        assert!(
            crcs.contains(&(crc as u32)),
            "{}: commit crc is not one of the [[checksum]] sets",
            v.name
        );
    }
}

#[test]
fn every_spec_example_is_a_golden_vector() {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    let doc = std::fs::read_to_string(p).expect("reading docs/protocol.md");
    let g = load();
    let vectors: BTreeSet<(String, u32, Vec<u8>)> = g
        .vector
        .iter()
        .map(|v| (v.message.clone(), hex_u32(&v.id), hex_bytes(&v.data)))
        .collect();
    let mut n = 0;
    for (lineno, line) in doc.lines().enumerate() {
        let Some(rest) = line.trim().strip_prefix("example:") else {
            continue;
        };
        let mut toks = rest.split_whitespace();
        let msg = toks.next().unwrap_or_default().to_string();
        let id = toks
            .next()
            .and_then(|t| t.strip_prefix("id="))
            .unwrap_or_else(|| panic!("protocol.md:{}: expected id=0x…", lineno + 1));
        let first = toks
            .next()
            .and_then(|t| t.strip_prefix("data="))
            .unwrap_or_else(|| panic!("protocol.md:{}: expected data=…", lineno + 1));
        let data: Vec<u8> = std::iter::once(first)
            .chain(toks)
            .map(|b| {
                u8::from_str_radix(b, 16)
                    .unwrap_or_else(|e| panic!("protocol.md:{}: {b}: {e}", lineno + 1))
            })
            .collect();
        let key = (msg, hex_u32(id), data);
        assert!(
            vectors.contains(&key),
            "protocol.md:{}: example {key:?} is not in golden-vectors.toml",
            lineno + 1
        );
        n += 1;
    }
    assert!(
        n >= Kind::ALL.len(),
        "only {n} examples found in protocol.md"
    );
}

#[test]
fn example_markers_cover_every_kind() {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    let doc = std::fs::read_to_string(p).expect("reading docs/protocol.md");
    for k in Kind::ALL {
        let marker = format!("example: {} ", k.name());
        assert!(
            doc.contains(&marker),
            "protocol.md has no worked example for {}",
            k.name()
        );
    }
}

/// Guard for `Error::Unencodable`: a frame type that refuses data must give a typed error.
#[derive(Debug)]
struct RefusingFrame;
impl Frame for RefusingFrame {
    fn new(_: impl Into<embedded_can::Id>, _: &[u8]) -> Option<Self> {
        None
    }
    fn new_remote(_: impl Into<embedded_can::Id>, _: usize) -> Option<Self> {
        None
    }
    fn is_extended(&self) -> bool {
        false
    }
    fn is_remote_frame(&self) -> bool {
        false
    }
    fn id(&self) -> embedded_can::Id {
        embedded_can::Id::Standard(StandardId::ZERO)
    }
    fn dlc(&self) -> usize {
        0
    }
    fn data(&self) -> &[u8] {
        &[]
    }
}

#[test]
fn encoder_refuses_what_a_receiver_would_reject() {
    let n1 = NodeId::new(1).expect("node");
    let sensor = Message::Sensor(Sensor {
        motor_counts: 1,
        output_torque: None,
        seq: 0,
        output_encoder: false,
        encoder_error: false,
    });
    assert_eq!(
        sensor.encode::<RawFrame>(NodeId::BROADCAST),
        Err(Error::BroadcastNotAllowed { kind: Kind::Sensor })
    );
    let act = Message::Actuator(Actuator {
        torque: 5,
        seq: 0,
        limits: LimitFlags::NONE,
        drive: false,
        fault: false,
    });
    assert_eq!(
        act.encode::<RawFrame>(n1),
        Err(Error::Inconsistent {
            kind: Kind::Actuator,
            field: "torque"
        })
    );
    let hb = Message::Heartbeat(Heartbeat {
        state: State::Fault,
        mode: None,
        fault: None,
        limits: LimitFlags::NONE,
        rejected_malformed: 0,
        rejected_refused: 0,
        protocol_version: 1,
    });
    assert_eq!(
        hb.encode::<RawFrame>(n1),
        Err(Error::Inconsistent {
            kind: Kind::Heartbeat,
            field: "fault"
        })
    );
    assert_eq!(
        sensor.encode::<RefusingFrame>(n1).map(|_| ()),
        Err(Error::Unencodable { kind: Kind::Sensor })
    );
    // Broadcast is fine for the control word.
    let qs: RawFrame = Message::ControlWord(ControlWord::QuickStop)
        .encode(NodeId::BROADCAST)
        .expect("broadcast quick stop");
    assert_eq!(qs.standard_id(), Some(0x380));
}
