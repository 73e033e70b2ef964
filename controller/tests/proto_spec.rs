//! `docs/protocol.md` and the codec must state the same facts. These tests read the spec and
//! compare it with the tables the codec is built from (parameter table, message kinds, enum
//! values), so a change on one side without the other fails CI.

use controller::proto::params::{self, ParamDef};
use controller::proto::{Command, FaultCode, Kind, LimitFlags, Mode, ParamStatus, ReplyTo, State};
use std::collections::BTreeSet;

fn spec() -> String {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("reading {p}: {e}"))
}

/// The lines of the section starting at heading `title` (up to the next heading of the same
/// or higher level).
fn section(doc: &str, title: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut level = None;
    for line in doc.lines() {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if hashes > 0 && line[hashes..].starts_with(' ') {
            if let Some(l) = level {
                if hashes <= l {
                    break;
                }
            } else if line[hashes..].trim() == title {
                level = Some(hashes);
                continue;
            }
        }
        if level.is_some() {
            out.push(line.to_string());
        }
    }
    assert!(
        level.is_some(),
        "section `{title}` not found in docs/protocol.md"
    );
    out
}

fn cells(line: &str) -> Vec<String> {
    line.trim()
        .trim_matches('|')
        .split('|')
        .map(|c| c.trim().trim_matches('`').to_string())
        .collect()
}

pub fn param_row(d: &ParamDef) -> String {
    let id = if d.count == 1 {
        format!("0x{:04X}", d.id)
    } else {
        format!("0x{:04X}–0x{:04X}", d.id, d.id + d.count - 1)
    };
    format!(
        "| {id} | {} | {} | {} | {} | {} | {} |",
        d.name,
        d.access.name(),
        d.unit,
        d.min,
        d.max,
        d.default
    )
}

#[test]
fn parameter_table_in_spec_matches_codec() {
    let doc = spec();
    let lines = section(&doc, "Parameter table");
    let in_doc: BTreeSet<Vec<String>> = lines
        .iter()
        .filter(|l| l.trim_start().starts_with("| 0x"))
        .map(|l| cells(l))
        // The group overview table has 2 columns; parameter rows have 7.
        .filter(|c| c.len() == 7)
        .collect();
    let in_code: BTreeSet<Vec<String>> =
        params::TABLE.iter().map(|d| cells(&param_row(d))).collect();
    let missing: Vec<_> = in_code.difference(&in_doc).collect();
    let extra: Vec<_> = in_doc.difference(&in_code).collect();
    if !missing.is_empty() || !extra.is_empty() {
        let all: Vec<String> = params::TABLE.iter().map(param_row).collect();
        panic!(
            "parameter table differs.\nrows in the codec but not the spec: {missing:#?}\n\
             rows in the spec but not the codec: {extra:#?}\nexpected rows:\n{}",
            all.join("\n")
        );
    }
}

#[test]
fn message_table_in_spec_matches_kinds() {
    // Rows like `| 3 | Sensor | 0x180 | ...` in the "Message kinds" section.
    let doc = spec();
    let mut seen = BTreeSet::new();
    for l in section(&doc, "Message kinds") {
        let c = cells(&l);
        if c.len() < 3 {
            continue;
        }
        let Ok(k) = c[0].parse::<u8>() else { continue };
        let Some(kind) = Kind::from_u8(k) else {
            assert!(
                c[1].starts_with("reserved"),
                "kind {k} in spec is not a codec kind: {l}"
            );
            continue;
        };
        assert_eq!(c[1], kind.name(), "kind {k} name");
        let base = u16::from(k) << 7;
        assert_eq!(c[2], format!("0x{base:03X}"), "kind {k} base id");
        seen.insert(k);
    }
    let all: BTreeSet<u8> = Kind::ALL.iter().map(|k| k.as_u8()).collect();
    assert_eq!(seen, all, "every kind must have a row in the spec");
}

/// Rows `| value | Name | ...` in section `title` must list exactly `expected`.
fn check_enum(title: &str, expected: &[(u8, &str)]) {
    let doc = spec();
    let mut got = Vec::new();
    for l in section(&doc, title) {
        let c = cells(&l);
        if c.len() >= 2 {
            if let Ok(v) = c[0].parse::<u8>() {
                got.push((v, c[1].clone()));
            }
        }
    }
    let want: Vec<(u8, String)> = expected.iter().map(|(v, n)| (*v, n.to_string())).collect();
    assert_eq!(got, want, "enum table `{title}` in docs/protocol.md");
}

#[test]
fn enum_tables_in_spec_match_codec() {
    let st: Vec<_> = State::ALL.iter().map(|s| (s.as_u8(), s.name())).collect();
    check_enum("State", &st);
    let mut m = vec![(0u8, "None")];
    m.extend(Mode::ALL.iter().map(|s| (s.as_u8(), s.name())));
    check_enum("Mode", &m);
    let mut f = vec![(0u8, "None")];
    f.extend(FaultCode::ALL.iter().map(|s| (s.as_u8(), s.name())));
    check_enum("FaultCode", &f);
    let c: Vec<_> = Command::ALL.iter().map(|s| (s.as_u8(), s.name())).collect();
    check_enum("Command", &c);
    let r: Vec<_> = ReplyTo::ALL.iter().map(|s| (s.as_u8(), s.name())).collect();
    check_enum("ReplyTo", &r);
    let p: Vec<_> = ParamStatus::ALL
        .iter()
        .map(|s| (s.as_u8(), s.name()))
        .collect();
    check_enum("ParamStatus", &p);
    let l: Vec<_> = LimitFlags::NAMED
        .iter()
        .map(|(n, f)| (f.bits().trailing_zeros() as u8, *n))
        .collect();
    check_enum("LimitFlags", &l);
}

fn dbc() -> String {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/jointlab.dbc");
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("reading {p}: {e}"))
}

#[test]
fn dbc_messages_match_kinds_ids_and_lengths() {
    let mut seen = BTreeSet::new();
    for line in dbc().lines() {
        let Some(rest) = line.strip_prefix("BO_ ") else {
            continue;
        };
        // BO_ <id> <Name>: <dlc> <sender>
        let t: Vec<&str> = rest.split_whitespace().collect();
        let id: u16 = t[0].parse().expect("BO_ id");
        let name = t[1].trim_end_matches(':');
        let dlc: usize = t[2].parse().expect("BO_ dlc");
        let kind = Kind::from_name(name).unwrap_or_else(|| panic!("DBC message {name} is no kind"));
        assert_eq!(
            id,
            controller::proto::id::compose(kind, controller::proto::NodeId::new(1).unwrap()),
            "{name} id"
        );
        assert_eq!(dlc, kind.dlc(), "{name} length");
        seen.insert(kind);
    }
    assert_eq!(seen.len(), Kind::ALL.len(), "every kind must be in the DBC");
}

#[test]
fn dbc_value_tables_match_enums() {
    let id_of = |k: Kind| u16::from(k.as_u8()) << 7 | 1;
    let mut tables = std::collections::BTreeMap::new();
    for line in dbc().lines() {
        let Some(rest) = line.strip_prefix("VAL_ ") else {
            continue;
        };
        let rest = rest.trim_end_matches(';').trim();
        let mut it = rest.splitn(3, ' ');
        let id: u16 = it.next().unwrap().parse().unwrap();
        let sig = it.next().unwrap().to_string();
        let body = it.next().unwrap();
        // pairs: <n> "<name>"
        let mut pairs = Vec::new();
        let mut s = body.trim();
        while !s.is_empty() {
            let (num, r) = s.split_once(' ').unwrap();
            let r = r.trim_start().strip_prefix('"').unwrap();
            let (name, r) = r.split_once('"').unwrap();
            pairs.push((num.parse::<u8>().unwrap(), name.to_string()));
            s = r.trim();
        }
        pairs.sort();
        tables.insert((id, sig), pairs);
    }
    let with_none = |v: Vec<(u8, &str)>| {
        let mut out = vec![(0u8, "None".to_string())];
        out.extend(v.into_iter().map(|(a, b)| (a, b.to_string())));
        out
    };
    let plain = |v: Vec<(u8, &str)>| {
        v.into_iter()
            .map(|(a, b)| (a, b.to_string()))
            .collect::<Vec<_>>()
    };
    let modes: Vec<_> = Mode::ALL.iter().map(|m| (m.as_u8(), m.name())).collect();
    let faults: Vec<_> = FaultCode::ALL
        .iter()
        .map(|m| (m.as_u8(), m.name()))
        .collect();
    let expect = [
        ((Kind::Fault, "code"), plain(faults.clone())),
        (
            (Kind::ControlWord, "command"),
            plain(Command::ALL.iter().map(|m| (m.as_u8(), m.name())).collect()),
        ),
        ((Kind::ControlWord, "mode"), with_none(modes.clone())),
        (
            (Kind::ParamResponse, "reply_to"),
            plain(ReplyTo::ALL.iter().map(|m| (m.as_u8(), m.name())).collect()),
        ),
        (
            (Kind::ParamResponse, "status"),
            plain(
                ParamStatus::ALL
                    .iter()
                    .map(|m| (m.as_u8(), m.name()))
                    .collect(),
            ),
        ),
        (
            (Kind::Heartbeat, "state"),
            plain(State::ALL.iter().map(|m| (m.as_u8(), m.name())).collect()),
        ),
        ((Kind::Heartbeat, "mode"), with_none(modes)),
        ((Kind::Heartbeat, "fault"), with_none(faults)),
    ];
    assert_eq!(
        tables.len(),
        expect.len(),
        "unexpected VAL_ tables: {:?}",
        tables.keys()
    );
    for ((kind, sig), want) in expect {
        let got = tables
            .get(&(id_of(kind), sig.to_string()))
            .unwrap_or_else(|| panic!("no VAL_ table for {}.{sig}", kind.name()));
        assert_eq!(got, &want, "VAL_ {}.{sig}", kind.name());
    }
}

#[test]
fn bus_load_figures_in_spec_hold() {
    // The 40 % budget: Sensor + Actuator + one telemetry frame (worst page) per 1 ms tick.
    let telemetry = Kind::TelemetryMotion
        .worst_case_bits()
        .max(Kind::TelemetryTorque.worst_case_bits());
    let per_ms = Kind::Sensor.worst_case_bits() + Kind::Actuator.worst_case_bits() + telemetry;
    assert_eq!(per_ms, 355);
    assert!(
        per_ms * 100 <= 40 * 1000,
        "{per_ms} bits/ms exceeds 40 % of 1 Mbit/s"
    );
    // With the output encoder, divider 2 (telemetry every other tick) stays under 40 %.
    let with_enc_x2 = 2 * (per_ms - telemetry + Kind::OutputEncoder.worst_case_bits()) + telemetry;
    assert_eq!(with_enc_x2, 795); // per 2 ms: 397.5 bits/ms
    assert!(with_enc_x2 * 100 <= 40 * 2000);
    let doc = spec();
    assert!(
        doc.contains("**355 → 35.5 %**"),
        "protocol.md bus-load figure out of date"
    );
    assert_eq!(Kind::Sensor.worst_case_bits(), 135);
    // Three 8-byte frames would not fit: the reason telemetry alternates.
    let three_full = 3 * Kind::Heartbeat.worst_case_bits();
    assert_eq!(three_full, 405);
}
