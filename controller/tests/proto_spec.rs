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
