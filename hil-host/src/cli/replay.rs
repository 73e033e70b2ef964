//! `hil-host replay`: a candump `-L` log decoded through the protocol's DBC (signals with
//! units, value names), filtered like candump (`181:7FF`), with candump's timestamp modes;
//! converted to a workbench recording (`--csv`: one row per tick); or put back on a bus.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::PathBuf;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use controller::proto::params;
use jointlab_can::bus::open_bus;
use jointlab_can::candump::{read_log_skipping, LogRecord, LoggedFrame};
use jointlab_can::signals::{Database, Decoded, Undecoded, Value};

/// `replay` examples.
pub const REPLAY_EXAMPLES: &str = "Examples:
  hil-host replay run.log                        # every frame, decoded with units
  hil-host replay run.log --filter 181:7FF,201:7FF --timestamp delta   # Sensor and Actuator of node 1
  hil-host replay run.log --csv run.csv --motor-cpr 2304   # a workbench recording, one row per tick
  hil-host diagnose run.csv --input actuator_torque_Nm --output motor_pos_rad
  hil-host replay run.log --bus vcan0            # put it back on a bus with its original timing";

/// How timestamps print (candump's `-t`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Timestamps {
    /// As logged.
    Absolute,
    /// Since the previous printed frame.
    Delta,
    /// Since the first frame of the log.
    Zero,
}

/// `hil-host replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A candump -L log (from `demo`, `run`, `plant --candump`, or can-utils).
    pub log: PathBuf,
    /// Send the frames to this bus with their original spacing instead of printing them.
    #[arg(long, conflicts_with = "csv")]
    pub bus: Option<String>,
    /// candump filters, comma-separated or repeated: `ID:MASK` keeps a frame whose id matches
    /// ID on MASK's bits, `ID~MASK` one that does not (hex). A frame passes if any filter does.
    #[arg(long, value_delimiter = ',', value_parser = filter)]
    pub filter: Vec<Filter>,
    /// Timestamps as logged, since the previous frame, or since the first.
    #[arg(long, value_enum, default_value = "absolute")]
    pub timestamp: Timestamps,
    /// Print each frame's signals raw (id#data and the decoded values), not one signal list.
    #[arg(long)]
    pub raw: bool,
    /// Write one row per Sensor tick (the Sensor, OutputEncoder and Actuator signals of that
    /// tick, matched by their seq; time since the first tick) to this CSV, with units in the
    /// column names: a recording the workbench loads.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Node whose ticks `--csv` writes (default: the only node that sent Sensor frames).
    #[arg(long)]
    pub node: Option<u8>,
    /// Motor encoder counts per revolution: `--csv` adds `motor_pos_rad`, the count unwrapped
    /// across its 32-bit wrap (the first count read as signed). Default: the value the log's
    /// ParamWrite of `motor_counts_per_rev` set, if it has one.
    #[arg(long)]
    pub motor_cpr: Option<f64>,
    /// Output encoder counts per revolution: `--csv` adds `output_pos_rad` (default: the log's
    /// `output_counts_per_rev`).
    #[arg(long)]
    pub output_cpr: Option<f64>,
}

/// One candump filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Filter {
    id: u32,
    mask: u32,
    invert: bool,
}

impl Filter {
    fn passes(&self, id: u32) -> bool {
        ((id & self.mask) == (self.id & self.mask)) != self.invert
    }
}

/// `ID:MASK` or `ID~MASK`, hex.
fn filter(s: &str) -> Result<Filter, String> {
    let (sep, invert) = if s.contains('~') {
        ('~', true)
    } else {
        (':', false)
    };
    let (id, mask) = s
        .split_once(sep)
        .ok_or_else(|| format!("`{s}`: a filter is ID:MASK or ID~MASK (hex), e.g. 181:7FF"))?;
    let hex =
        |t: &str| u32::from_str_radix(t, 16).map_err(|e| format!("`{s}`: `{t}` is not hex ({e})"));
    Ok(Filter {
        id: hex(id)?,
        mask: hex(mask)?,
        invert,
    })
}

/// Runs `replay`.
pub fn replay(a: ReplayArgs) -> Result<()> {
    let log = read_log_skipping(&a.log)?;
    if let Some(note) = log.skipped_note(&a.log) {
        eprintln!("{note}");
    }
    let recs: Vec<&LogRecord> = log
        .records
        .iter()
        .filter(|r| {
            a.filter.is_empty()
                || match &r.frame {
                    LoggedFrame::Can(f) => a.filter.iter().any(|x| x.passes(f.raw_id())),
                    LoggedFrame::Error(_) => false,
                }
        })
        .collect();
    if let Some(spec) = &a.bus {
        return resend(spec, &recs);
    }
    let db = Database::jointlab()?;
    if let Some(out) = &a.csv {
        return write_ticks(&a, &db, &recs, out);
    }
    let first = recs.first().map(|r| r.time.as_duration().as_secs_f64());
    let mut prev = first;
    let stdout = std::io::stdout();
    let mut o = stdout.lock();
    for r in &recs {
        let t = r.time.as_duration().as_secs_f64();
        let shown = match a.timestamp {
            Timestamps::Absolute => t,
            Timestamps::Delta => t - prev.unwrap_or(t),
            Timestamps::Zero => t - first.unwrap_or(t),
        };
        prev = Some(t);
        let line = match &r.frame {
            LoggedFrame::Can(f) => {
                let head = format!("({shown:.6}) {} {f}", r.iface);
                match db.decode(f) {
                    Ok(d) if a.raw => format!("{head:<46} {}", d.message.name),
                    Ok(d) => format!("{head:<46} {}", describe(&d)),
                    Err(e) => format!("{head:<46} {}", undecoded(e)),
                }
            }
            LoggedFrame::Error(e) => format!("({shown:.6}) {} error frame: {e:?}", r.iface),
        };
        // A closed pipe (`| head`) ends the listing quietly.
        if writeln!(o, "{line}").is_err() {
            return Ok(());
        }
    }
    Ok(())
}

/// `Sensor[1] motor_counts=… seq=…`, with a parameter's name after its id.
fn describe(d: &Decoded<'_>) -> String {
    let mut s = format!("{}[{}]", d.message.name, d.node);
    for v in &d.values {
        s.push(' ');
        s.push_str(&v.text());
        if v.def.name == "param_id" {
            if let Ok(p) = u16::try_from(v.raw)
                .map_err(|_| ())
                .and_then(|id| params::lookup(id).map_err(|_| ()))
            {
                s.push_str(&format!(" ({}, {})", p.name, p.unit));
            }
        }
    }
    s
}

fn undecoded(e: Undecoded) -> String {
    match e {
        Undecoded::NotProtocol => "(extended or remote: not jointlab)".into(),
        Undecoded::UnknownKind => "(no jointlab message has this id)".into(),
        Undecoded::Short { got, want } => format!("(too short: {got} of {want} bytes)"),
    }
}

fn resend(spec: &str, recs: &[&LogRecord]) -> Result<()> {
    let mut bus = open_bus(spec).map_err(|e| anyhow!("{e}"))?;
    let t0 = std::time::Instant::now();
    let first = recs
        .first()
        .map(|r| r.time.as_duration())
        .unwrap_or_default();
    let mut sent = 0;
    for r in recs {
        if let LoggedFrame::Can(f) = &r.frame {
            let due = r.time.as_duration().saturating_sub(first);
            if let Some(wait) = due.checked_sub(t0.elapsed()) {
                std::thread::sleep(wait);
            }
            bus.send(f).map_err(|e| anyhow!("{e}"))?;
            sent += 1;
        }
    }
    println!("replayed {sent} frames to {spec}");
    Ok(())
}

/// A DBC unit as the workbench's column suffix (`N.m` → `_Nm`), or none.
fn suffix(unit: &str) -> &'static str {
    match unit {
        "N.m" => "_Nm",
        "N" => "_N",
        "rad" => "_rad",
        "m" => "_m",
        "s" => "_s",
        "V" => "_V",
        "A" => "_A",
        _ => "",
    }
}

fn snake(name: &str) -> String {
    let mut s = String::new();
    for (k, c) in name.chars().enumerate() {
        if c.is_ascii_uppercase() && k > 0 {
            s.push('_');
        }
        s.push(c.to_ascii_lowercase());
    }
    s
}

/// The tick messages in row order, and whether a tick needs one to be written.
const TICK: [(&str, bool); 3] = [
    ("Sensor", true),
    ("OutputEncoder", false),
    ("Actuator", true),
];

/// One tick being assembled: its time, seq, and the signals of each tick message.
struct Row {
    time: f64,
    seq: i64,
    parts: [Option<Vec<f64>>; 3],
}

fn seq_of(vals: &[Value<'_>]) -> Option<i64> {
    vals.iter().find(|v| v.def.name == "seq").map(|v| v.raw)
}

fn write_ticks(a: &ReplayArgs, db: &Database, recs: &[&LogRecord], out: &PathBuf) -> Result<()> {
    let defs: Vec<_> = TICK
        .iter()
        .map(|(n, _)| {
            db.message(n)
                .ok_or_else(|| anyhow!("the protocol's DBC has no {n} message"))
        })
        .collect::<Result<_>>()?;
    let decoded: Vec<(f64, Decoded<'_>)> = recs
        .iter()
        .filter_map(|r| match &r.frame {
            LoggedFrame::Can(f) => db
                .decode(f)
                .ok()
                .map(|d| (r.time.as_duration().as_secs_f64(), d)),
            LoggedFrame::Error(_) => None,
        })
        .collect();
    let senders: BTreeSet<u8> = decoded
        .iter()
        .filter(|(_, d)| d.message.name == "Sensor")
        .map(|(_, d)| d.node)
        .collect();
    let node = match (a.node, senders.len()) {
        (Some(n), _) if senders.contains(&n) => n,
        (Some(n), _) => bail!(
            "{}: node {n} sent no Sensor frame (nodes with Sensor frames: {senders:?})",
            a.log.display()
        ),
        (None, 1) => senders.first().copied().unwrap_or(1),
        (None, 0) => bail!(
            "{}: no Sensor frame (after --filter): a recording has one row per Sensor tick",
            a.log.display()
        ),
        (None, _) => bail!(
            "{}: Sensor frames from nodes {senders:?}: choose one with --node",
            a.log.display()
        ),
    };
    let mut rows: Vec<Row> = Vec::new();
    let mut pending_encoder: Option<(i64, Vec<f64>)> = None;
    for (t, d) in decoded.iter().filter(|(_, d)| d.node == node) {
        let vals: Vec<f64> = d.values.iter().map(|v| v.value).collect();
        let seq = seq_of(&d.values);
        match d.message.name.as_str() {
            // The output encoder's sample precedes its tick's Sensor frame.
            "OutputEncoder" => pending_encoder = seq.map(|s| (s, vals)),
            "Sensor" => {
                let Some(seq) = seq else { continue };
                let enc = pending_encoder
                    .take()
                    .filter(|(s, _)| *s == seq)
                    .map(|(_, v)| v);
                rows.push(Row {
                    time: *t,
                    seq,
                    parts: [Some(vals), enc, None],
                });
            }
            // The card answers a tick with its seq; look back a few ticks for it.
            "Actuator" => {
                if let Some(r) = rows
                    .iter_mut()
                    .rev()
                    .take(4)
                    .find(|r| Some(r.seq) == seq && r.parts[2].is_none())
                {
                    r.parts[2] = Some(vals);
                }
            }
            _ => {}
        }
    }
    let has_encoder = rows.iter().any(|r| r.parts[1].is_some());
    let total = rows.len();
    rows.retain(|r| {
        TICK.iter()
            .zip(&r.parts)
            .all(|((_, needed), p)| !needed || p.is_some())
            && (!has_encoder || r.parts[1].is_some())
    });
    if rows.is_empty() {
        bail!(
            "{}: none of node {node}'s {total} Sensor ticks has its Actuator answer: a \
             recording needs both (is the card's side in the log?)",
            a.log.display()
        );
    }
    let mut header = vec!["time_s".to_string()];
    for ((def, _), used) in defs.iter().zip(TICK).zip([true, has_encoder, true]) {
        if used {
            for s in &def.signals {
                header.push(format!(
                    "{}_{}{}",
                    snake(&def.name),
                    s.name,
                    suffix(&s.unit)
                ));
            }
        }
    }
    let col = |msg: &str, sig: &str| {
        let m = TICK.iter().position(|(n, _)| *n == msg)?;
        let k = defs.get(m)?.signals.iter().position(|s| s.name == sig)?;
        Some((m, k))
    };
    // Counts per revolution: the flag, else what the supervisor wrote to this node in the log.
    let written = |param: u16| {
        decoded
            .iter()
            .filter(|(_, d)| d.node == node && d.message.name == "ParamWrite")
            .filter(|(_, d)| {
                d.values
                    .iter()
                    .any(|v| v.def.name == "param_id" && v.raw == i64::from(param))
            })
            .filter_map(|(_, d)| d.values.iter().find(|v| v.def.name == "value"))
            .map(|v| v.value)
            .next_back()
            .filter(|c| *c > 0.0)
    };
    let motor_cpr = a.motor_cpr.or_else(|| {
        let c = written(params::MOTOR_COUNTS_PER_REV)?;
        eprintln!("note: motor_pos_rad at {c} counts/rev, as the log's ParamWrite motor_counts_per_rev says (--motor-cpr overrides)");
        Some(c)
    });
    let output_cpr = a.output_cpr.or_else(|| {
        let c = written(params::OUTPUT_COUNTS_PER_REV).filter(|_| has_encoder)?;
        eprintln!("note: output_pos_rad at {c} counts/rev, as the log's ParamWrite output_counts_per_rev says (--output-cpr overrides)");
        Some(c)
    });
    let motor = motor_cpr.and_then(|c| col("Sensor", "motor_counts").map(|p| (p, c)));
    let output = match (output_cpr, has_encoder) {
        (Some(_), false) => bail!("--output-cpr: the log has no OutputEncoder frames"),
        (Some(c), true) => col("OutputEncoder", "output_counts").map(|p| (p, c)),
        (None, _) => None,
    };
    for (name, on) in [("motor_pos_rad", motor), ("output_pos_rad", output)] {
        if let Some((_, cpr)) = on {
            if !(cpr.is_finite() && cpr > 0.0) {
                bail!("counts per revolution must be a finite number above 0, not {cpr}");
            }
            header.push(name.to_string());
        }
    }
    let mut w = csv::Writer::from_path(out).with_context(|| format!("{}", out.display()))?;
    w.write_record(&header)?;
    let t0 = rows.first().map_or(0.0, |r| r.time);
    let mut unwrap = [Unwrap::default(), Unwrap::default()];
    for r in &rows {
        let mut rec = vec![format!("{:.6}", r.time - t0)];
        for p in r.parts.iter().flatten() {
            rec.extend(p.iter().map(|v| format!("{v}")));
        }
        for (u, on) in unwrap.iter_mut().zip([motor, output]) {
            if let Some(((m, k), cpr)) = on {
                let counts = r
                    .parts
                    .get(m)
                    .and_then(|p| p.as_ref())
                    .and_then(|p| p.get(k))
                    .copied()
                    .unwrap_or(0.0);
                let turns = u.step(counts as u32) as f64 / cpr;
                rec.push(format!("{:.9}", turns * std::f64::consts::TAU));
            }
        }
        w.write_record(&rec)?;
    }
    w.flush()?;
    let dropped = total - rows.len();
    eprintln!(
        "{}: {} ticks of node {node}{}",
        out.display(),
        rows.len(),
        if dropped > 0 {
            format!(" ({dropped} without their Actuator answer or encoder sample left out)")
        } else {
            String::new()
        }
    );
    Ok(())
}

/// A 32-bit free-running count made multi-turn: each step moves by the signed difference.
#[derive(Debug, Default)]
struct Unwrap {
    last: Option<u32>,
    total: i64,
}

impl Unwrap {
    fn step(&mut self, c: u32) -> i64 {
        match self.last {
            None => self.total = i64::from(c as i32),
            Some(l) => self.total += i64::from(c.wrapping_sub(l) as i32),
        }
        self.last = Some(c);
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_read_as_candump_reads_them() {
        let f = filter("181:7FF").unwrap();
        assert!(f.passes(0x181) && !f.passes(0x182));
        let g = filter("180:780").unwrap();
        assert!(g.passes(0x181) && g.passes(0x1FF) && !g.passes(0x201));
        let n = filter("181~7FF").unwrap();
        assert!(!n.passes(0x181) && n.passes(0x182));
        assert!(filter("181").unwrap_err().contains("ID:MASK"));
        assert!(filter("18g:7FF").unwrap_err().contains("not hex"));
    }

    #[test]
    fn counts_unwrap_across_the_32_bit_wrap() {
        let mut u = Unwrap::default();
        assert_eq!(u.step(u32::MAX - 1), -2);
        assert_eq!(u.step(1), 1);
        assert_eq!(u.step(u32::MAX), -1);
        assert_eq!(snake("OutputEncoder"), "output_encoder");
    }
}
