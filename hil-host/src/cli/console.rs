//! A card console, as moteus_tool is for a moteus: the parameter table (`param list`), a
//! card's active values (`param get`), a staged write committed atomically (`param set`), and
//! its health (`status`: the heartbeat decoded, frame rates and bus load), over any bus the lab
//! speaks (SocketCAN, SLCAN, or a named in-process hub).
//!
//! The exchanges are [`Console`] methods on a [`CanBus`], so the tests drive a real card the
//! same way the command line does.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use controller::proto::params::{self, ParamDef};
use controller::proto::{
    Heartbeat, Message, NodeId, ParamCommit, ParamRead, ParamResponse, ParamStatus, ParamWrite,
    RawFrame, ReplyTo, SetChecksum,
};
use jointlab_can::bus::{bits, open_bus, CanBus, CanBusExt};

/// `param` examples.
pub const PARAM_EXAMPLES: &str = "Examples:
  hil-host param list                                   # every parameter: id, unit, range, default
  hil-host param get torque_limit velocity_limit --bus vcan0 --node 1
  hil-host param set torque_limit=15000 --bus vcan0 --node 1   # staged, then committed atomically";

/// `status` examples.
pub const STATUS_EXAMPLES: &str = "Examples:
  hil-host status --bus vcan0 --node 1            # state, mode, fault, limits, frames/s, bus load
  hil-host status --bus can0 --node 1 --seconds 5";

/// `hil-host param`.
#[derive(Debug, Args)]
pub struct ParamArgs {
    #[command(subcommand)]
    pub what: ParamCommand,
}

/// Bus and node of a console command.
#[derive(Debug, Clone, Args)]
pub struct Target {
    /// Bus: a SocketCAN interface (vcan0, can0), slcan:/dev/ttyACM0, or inproc:NAME.
    #[arg(long, default_value = "vcan0")]
    pub bus: String,
    /// Card node id (1..=127).
    #[arg(long, default_value_t = 1)]
    pub node: u8,
    /// How long to wait for each answer, ms.
    #[arg(long, default_value_t = 500)]
    pub timeout_ms: u64,
}

impl Target {
    /// Opens the bus and runs `f` with a console on it.
    fn with_console<T>(&self, f: impl FnOnce(&mut Console<'_>) -> Result<T>) -> Result<T> {
        let mut bus = open_bus(&self.bus).map_err(|e| anyhow!("{e}"))?;
        let mut c = Console::new(
            bus.as_mut(),
            self.node,
            Duration::from_millis(self.timeout_ms),
        )?;
        f(&mut c)
    }
}

/// What `param` does.
#[derive(Debug, Subcommand)]
pub enum ParamCommand {
    /// The parameter table: id, name, access, unit, range, default (no bus needed).
    List,
    /// Read active values.
    Get {
        /// Parameter names or ids (hex `0x0902` or decimal).
        #[arg(required = true)]
        names: Vec<String>,
        #[command(flatten)]
        target: Target,
    },
    /// Stage values and commit them as one set (all or nothing).
    Set {
        /// NAME=VALUE pairs, raw integers in the parameter's unit (see `param list`).
        #[arg(required = true)]
        pairs: Vec<String>,
        #[command(flatten)]
        target: Target,
    },
}

/// `hil-host status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    #[command(flatten)]
    pub target: Target,
    /// Seconds to listen (default 1; with --follow, until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Stream the card's telemetry as a table, a row every --every-ms: state, mode, fault,
    /// position, velocity, torque command, output torque, limit flags (decoded through the
    /// protocol's DBC, with units).
    #[arg(long)]
    pub follow: bool,
    /// Row interval of --follow, ms.
    #[arg(long, default_value_t = 100, requires = "follow")]
    pub every_ms: u64,
}

/// The parameter `s` names: a name from the table, or an id.
pub fn lookup(s: &str) -> Result<(u16, &'static ParamDef)> {
    let id = if let Some(h) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(u16::from_str_radix(h, 16).with_context(|| format!("`{s}`: not a hex id"))?)
    } else if s.chars().all(|c| c.is_ascii_digit()) {
        Some(
            s.parse::<u16>()
                .with_context(|| format!("`{s}`: not an id"))?,
        )
    } else {
        None
    };
    if let Some(id) = id {
        let d = params::lookup(id).map_err(|_| anyhow!("no parameter has id {id:#06x}"))?;
        return Ok((id, d));
    }
    // A table row (the ripple table) is addressed by name[k].
    let (base, index) = match s.split_once('[') {
        Some((b, rest)) => {
            let k = rest
                .strip_suffix(']')
                .and_then(|k| k.parse::<u16>().ok())
                .ok_or_else(|| anyhow!("`{s}`: an index is name[k]"))?;
            (b, k)
        }
        None => (s, 0),
    };
    let d = params::TABLE
        .iter()
        .find(|d| d.name == base)
        .ok_or_else(|| {
            anyhow!(
                "unknown parameter `{base}`{}; `hil-host param list` names them all",
                jointlab_workbench::names::did_you_mean(base, params::TABLE.iter().map(|d| d.name))
            )
        })?;
    if index >= d.count {
        bail!("`{s}`: {} has {} entries", d.name, d.count);
    }
    Ok((d.id + index, d))
}

/// One card, reached over a bus.
pub struct Console<'a> {
    bus: &'a mut dyn CanBus,
    node: NodeId,
    timeout: Duration,
}

impl std::fmt::Debug for Console<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Console(node {} on {})",
            self.node.get(),
            self.bus.name()
        )
    }
}

impl<'a> Console<'a> {
    /// A console for `node` on `bus`.
    pub fn new(bus: &'a mut dyn CanBus, node: u8, timeout: Duration) -> Result<Self> {
        let node = NodeId::new(node)
            .filter(|n| !n.is_broadcast())
            .ok_or_else(|| anyhow!("--node must be 1..=127, got {node}"))?;
        Ok(Console { bus, node, timeout })
    }

    fn send(&mut self, m: Message) -> Result<()> {
        let f: RawFrame = m
            .encode(self.node)
            .map_err(|e| anyhow!("encoding {m:?}: {e:?}"))?;
        self.bus.send_frame(&f).map_err(|e| anyhow!("{e}"))?;
        Ok(())
    }

    /// The next ParamResponse from this card that `want` accepts, within the timeout.
    fn answer(&mut self, want: impl Fn(&ParamResponse) -> bool) -> Result<ParamResponse> {
        let t0 = Instant::now();
        while let Some(left) = self.timeout.checked_sub(t0.elapsed()) {
            let Some(f) = self.bus.recv_timeout(left).map_err(|e| anyhow!("{e}"))? else {
                break;
            };
            if let Ok((n, Message::ParamResponse(r))) = Message::decode(&f) {
                if n == self.node && want(&r) {
                    return Ok(r);
                }
            }
        }
        bail!(
            "node {} on {} did not answer within {} ms (is a card running there?)",
            self.node.get(),
            self.bus.name(),
            self.timeout.as_millis()
        )
    }

    /// The active value of parameter `id`.
    pub fn get(&mut self, id: u16) -> Result<i32> {
        self.send(Message::ParamRead(ParamRead { param_id: id }))?;
        let r = self.answer(|r| r.reply_to == ReplyTo::Read && r.param_id == id)?;
        match r.status {
            ParamStatus::Ok => Ok(r.value),
            s => bail!("reading {id:#06x}: the card answers {s:?}"),
        }
    }

    /// Stages `values` and commits them as one set; the card's refusal names the parameter.
    pub fn set(&mut self, values: &[(u16, i32)], set_seq: u8) -> Result<()> {
        for &(param_id, value) in values {
            self.send(Message::ParamWrite(ParamWrite {
                param_id,
                value,
                set_seq,
            }))?;
        }
        let sum = SetChecksum::of(values);
        self.send(Message::ParamCommit(ParamCommit {
            set_seq,
            count: sum.count(),
            crc: sum.crc(),
        }))?;
        // A write the card refuses is answered at once; the commit's answer ends the exchange.
        let r = self.answer(|r| {
            r.set_seq == set_seq
                && (r.reply_to == ReplyTo::Commit
                    || (r.reply_to == ReplyTo::Write && r.status != ParamStatus::Ok))
        })?;
        match r.status {
            // Accepted; applied at the card's next tick boundary: wait for that, so a read
            // right after a set sees it.
            ParamStatus::Ok => {
                let t0 = Instant::now();
                while self.get(params::LAST_SET_SEQ)? != i32::from(set_seq) {
                    if t0.elapsed() > self.timeout {
                        bail!(
                            "node {} accepted the set but did not apply it within {} ms (is it \
                             ticking? a set is applied at a tick boundary)",
                            self.node.get(),
                            self.timeout.as_millis()
                        );
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
                Ok(())
            }
            s => {
                let name = params::lookup(r.param_id).map_or("?", |d| d.name);
                bail!(
                    "the card refused the set ({:?} of {}): {s:?} (parameter `{name}`, {:#06x})",
                    r.reply_to,
                    values.len(),
                    r.param_id
                )
            }
        }
    }

    /// Listens for `window`: the last heartbeat of this card, and frames per kind with the
    /// bus load they make (exact bit count, stuffing included).
    pub fn listen(&mut self, window: Duration) -> Result<Listened> {
        let t0 = Instant::now();
        let mut l = Listened::default();
        while let Some(left) = window.checked_sub(t0.elapsed()) {
            let Some(f) = self.bus.recv_timeout(left).map_err(|e| anyhow!("{e}"))? else {
                continue;
            };
            l.bits += bits::frame_bits_unstuffed(&f).len() as u64;
            let name = match Message::decode(&f) {
                Ok((n, m)) => {
                    if let (true, Message::Heartbeat(h)) = (n == self.node, &m) {
                        l.heartbeat = Some(*h);
                    }
                    kind_name(&m)
                }
                Err(_) => "other",
            };
            *l.frames.entry(name).or_default() += 1;
        }
        l.seconds = window.as_secs_f64();
        Ok(l)
    }
}

fn kind_name(m: &Message) -> &'static str {
    match m {
        Message::Fault(_) => "Fault",
        Message::OutputEncoder(_) => "OutputEncoder",
        Message::Sensor(_) => "Sensor",
        Message::Actuator(_) => "Actuator",
        Message::SetpointMotion(_) => "SetpointMotion",
        Message::SetpointForce(_) => "SetpointForce",
        Message::ControlWord(_) => "ControlWord",
        Message::TelemetryMotion(_) => "TelemetryMotion",
        Message::TelemetryTorque(_) => "TelemetryTorque",
        Message::ParamWrite(_) => "ParamWrite",
        Message::ParamCommit(_) => "ParamCommit",
        Message::ParamRead(_) => "ParamRead",
        Message::ParamResponse(_) => "ParamResponse",
        Message::Heartbeat(_) => "Heartbeat",
    }
}

/// What [`Console::listen`] heard.
#[derive(Debug, Default)]
pub struct Listened {
    /// The card's last heartbeat.
    pub heartbeat: Option<Heartbeat>,
    /// Frames per message kind (`other` for frames that are not the protocol's).
    pub frames: BTreeMap<&'static str, u64>,
    /// Bits on the wire (unstuffed).
    pub bits: u64,
    /// Seconds listened.
    pub seconds: f64,
}

/// Runs `param`.
pub fn param(a: ParamArgs) -> Result<()> {
    match a.what {
        ParamCommand::List => {
            println!(
                "{:<8} {:<26} {:<9} {:>12} {:>12} {:>12}  unit",
                "id", "name", "access", "min", "max", "default"
            );
            for d in params::TABLE {
                let name = if d.count > 1 {
                    format!("{}[{}]", d.name, d.count)
                } else {
                    d.name.to_string()
                };
                println!(
                    "{:#06x}   {name:<26} {:<9} {:>12} {:>12} {:>12}  {}",
                    d.id,
                    format!("{:?}", d.access),
                    d.min,
                    d.max,
                    d.default,
                    d.unit
                );
            }
            Ok(())
        }
        ParamCommand::Get { names, target } => {
            let ids = names
                .iter()
                .map(|n| lookup(n))
                .collect::<Result<Vec<_>>>()?;
            target.with_console(|c| {
                for ((id, d), n) in ids.iter().zip(&names) {
                    let v = c.get(*id)?;
                    println!("{n} = {v}  ({})", d.unit);
                }
                Ok(())
            })
        }
        ParamCommand::Set { pairs, target } => {
            let mut values = Vec::new();
            for p in &pairs {
                let (n, v) = p
                    .split_once('=')
                    .ok_or_else(|| anyhow!("`{p}`: a pair is NAME=VALUE"))?;
                let (id, d) = lookup(n.trim())?;
                let v: i32 = v
                    .trim()
                    .parse()
                    .with_context(|| format!("`{p}`: the value is a raw integer ({})", d.unit))?;
                if d.check(v).is_err() {
                    bail!("`{p}`: {} takes {}..={} ({})", d.name, d.min, d.max, d.unit);
                }
                values.push((id, v));
            }
            // A set sequence number the card has not just seen from a supervisor.
            let seq = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0x80, |d| (d.subsec_micros() as u8) | 0x80);
            target.with_console(|c| c.set(&values, seq))?;
            println!(
                "committed {} parameter(s) to node {}",
                values.len(),
                target.node
            );
            Ok(())
        }
    }
}

/// Runs `status`.
pub fn status(a: StatusArgs) -> Result<()> {
    if let Some(s) = a
        .seconds
        .filter(|s| !(s.is_finite() && *s > 0.0 && *s <= 86_400.0))
    {
        bail!("--seconds must be in (0, 86400], not {s}");
    }
    if a.follow {
        return follow(&a);
    }
    let seconds = a.seconds.unwrap_or(1.0);
    let mut bus = open_bus(&a.target.bus).map_err(|e| anyhow!("{e}"))?;
    let name = bus.name().to_string();
    let mut c = Console::new(
        bus.as_mut(),
        a.target.node,
        Duration::from_millis(a.target.timeout_ms),
    )?;
    let l = c.listen(Duration::from_secs_f64(seconds))?;
    println!("node {} on {name}, {:.1} s", a.target.node, l.seconds);
    match &l.heartbeat {
        Some(h) => {
            println!("  state      {:?}", h.state);
            println!("  mode       {:?}", h.mode);
            println!("  fault      {:?}", h.fault);
            println!("  limits     {:?}", h.limits);
            println!(
                "  rejected   {} malformed, {} refused frames",
                h.rejected_malformed, h.rejected_refused
            );
            println!("  protocol   v{}", h.protocol_version);
        }
        None => println!(
            "  no heartbeat from node {} (is a card running there?)",
            a.target.node
        ),
    }
    let total: u64 = l.frames.values().sum();
    println!(
        "  frames     {total} ({:.0}/s); bus load {:.1} % of 1 Mbit/s (unstuffed bits)",
        total as f64 / l.seconds,
        100.0 * l.bits as f64 / l.seconds / 1e6
    );
    for (k, n) in &l.frames {
        println!("    {k:<16} {:>8.0}/s", *n as f64 / l.seconds);
    }
    if l.heartbeat.is_none() {
        bail!("no heartbeat from node {} on {name}", a.target.node);
    }
    Ok(())
}

/// The signals `status --follow` shows, by message: (message, signal, column title).
const FOLLOW: [(&str, &str, &str); 7] = [
    ("Heartbeat", "state", "state"),
    ("Heartbeat", "mode", "mode"),
    ("Heartbeat", "fault", "fault"),
    ("TelemetryMotion", "position", "position"),
    ("TelemetryMotion", "velocity", "velocity"),
    ("TelemetryTorque", "torque_cmd", "torque_cmd"),
    ("TelemetryTorque", "output_torque", "output_torque"),
];

/// `status --follow`: the card's latest telemetry as a streaming table.
fn follow(a: &StatusArgs) -> Result<()> {
    let db = jointlab_can::signals::Database::jointlab()?;
    let mut bus = open_bus(&a.target.bus).map_err(|e| anyhow!("{e}"))?;
    let node = a.target.node;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let s = stop.clone();
    let _ = ctrlc::set_handler(move || s.store(true, std::sync::atomic::Ordering::SeqCst));
    let every = Duration::from_millis(a.every_ms.max(10));
    let end = a.seconds.map(Duration::from_secs_f64);
    let mut latest: Vec<String> = vec!["-".into(); FOLLOW.len()];
    let units: Vec<String> = FOLLOW
        .iter()
        .map(|(m, sig, title)| {
            let unit = db
                .message(m)
                .and_then(|d| d.signals.iter().find(|x| x.name == *sig))
                .map_or("", |x| x.unit.as_str());
            if unit.is_empty() {
                (*title).to_string()
            } else {
                format!("{title} [{unit}]")
            }
        })
        .collect();
    let widths: Vec<usize> = units.iter().map(|u| u.chars().count().max(9) + 2).collect();
    let row = |cells: &[String]| -> String {
        cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:>w$}"))
            .collect()
    };
    println!("{:>8}{}", "t [s]", row(&units));
    let t0 = Instant::now();
    let mut next = every;
    let mut heard = false;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) && end.is_none_or(|e| t0.elapsed() < e) {
        if let Some(f) = bus
            .recv_timeout(Duration::from_millis(5))
            .map_err(|e| anyhow!("{e}"))?
        {
            if let Ok(d) = db.decode(&f) {
                if d.node == node {
                    for (k, (m, sig, _)) in FOLLOW.iter().enumerate() {
                        if d.message.name == *m {
                            if let Some(v) = d.values.iter().find(|v| v.def.name == *sig) {
                                heard = true;
                                let text = v.text();
                                let value = text.split_once('=').map_or("", |x| x.1);
                                let value = value.split(' ').next().unwrap_or(value);
                                if let Some(slot) = latest.get_mut(k) {
                                    *slot = value.to_string();
                                }
                            }
                        }
                    }
                }
            }
        }
        if t0.elapsed() >= next {
            next += every;
            println!("{:>8.2}{}", t0.elapsed().as_secs_f64(), row(&latest));
        }
    }
    if !heard {
        bail!(
            "no telemetry or heartbeat from node {node} on {}",
            bus.name()
        );
    }
    Ok(())
}
