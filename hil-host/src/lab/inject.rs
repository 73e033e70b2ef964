//! Faults a lab run can be given on purpose (`--inject`), so that what a rig would do under
//! them can be watched and tested: error frames on the bus, lossy or slow links, a stalled
//! plant, a silent supervisor, a receive queue too short.
//!
//! Syntax (one `--inject` per fault; times in seconds of run time, `@T+D` = from T for D):
//!
//! | spec | what |
//! |---|---|
//! | `bus-off@T`, `error-passive@T`, `error-warning@T`, `no-ack@T`, `protocol@T`, `rx-overflow@T` | one error frame at T, seen by every node (in-process bus only) |
//! | `drop:NODE=RATE[@T[+D]]` | NODE (`card`, `plant`, `supervisor`) loses each received frame with probability RATE (`0.05` or `5%`) |
//! | `delay:NODE=DUR[@T[+D]]` | NODE receives every frame DUR late (`2ms`, `500us`) |
//! | `jitter:NODE=DUR[@T[+D]]` | NODE receives every frame up to DUR late (uniform) |
//! | `stall-plant@T+D` | the plant node sends nothing for D (its joint frozen, as a stalled process) |
//! | `kill-supervisor@T[+D]` | the supervisor sends and hears nothing from T (for D, else for good) |
//! | `rx-queue=N` | every node's receive queue holds N frames; more are lost with an RX-overflow error frame (in-process bus only) |

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use anyhow::{anyhow, bail, Result};

use jointlab_can::bus::fault::{class, ctrl, prot};
use jointlab_can::bus::{BusFault, FaultCause, LinkFault};

/// Error frames `--inject` can put on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BusEvent {
    /// The controllers went bus-off.
    BusOff,
    /// TX and RX error counters reached error-passive (≥ 128).
    ErrorPassive,
    /// Error counters reached the warning level (≥ 96).
    ErrorWarning,
    /// A transmitted frame was not acknowledged.
    NoAck,
    /// A protocol violation (a stuff error).
    Protocol,
    /// The receive FIFO overflowed.
    RxOverflow,
}

impl BusEvent {
    /// Every kind, in the order of the `--inject` table.
    pub const ALL: [BusEvent; 6] = [
        BusEvent::BusOff,
        BusEvent::ErrorPassive,
        BusEvent::ErrorWarning,
        BusEvent::NoAck,
        BusEvent::Protocol,
        BusEvent::RxOverflow,
    ];

    /// The `--inject` name.
    pub fn name(self) -> &'static str {
        match self {
            BusEvent::BusOff => "bus-off",
            BusEvent::ErrorPassive => "error-passive",
            BusEvent::ErrorWarning => "error-warning",
            BusEvent::NoAck => "no-ack",
            BusEvent::Protocol => "protocol",
            BusEvent::RxOverflow => "rx-overflow",
        }
    }

    /// The error frame a Linux CAN driver would report.
    pub fn fault(self) -> BusFault {
        match self {
            BusEvent::BusOff => BusFault::bus_off(),
            BusEvent::ErrorPassive => {
                BusFault::controller(ctrl::RX_PASSIVE | ctrl::TX_PASSIVE, 128, 128)
            }
            BusEvent::ErrorWarning => {
                BusFault::controller(ctrl::RX_WARNING | ctrl::TX_WARNING, 96, 96)
            }
            BusEvent::NoAck => BusFault::no_ack(),
            BusEvent::Protocol => BusFault::from_raw(class::PROT, &[0, 0, prot::STUFF, 0x0A]),
            BusEvent::RxOverflow => BusFault::controller(ctrl::RX_OVERFLOW, 0, 1),
        }
    }

    /// The class an error frame is counted under (its most severe cause), `None` for
    /// frames that only report recovery or counters.
    pub fn classify(f: &BusFault) -> Option<BusEvent> {
        let causes = f.causes();
        let has = |p: &dyn Fn(&FaultCause) -> bool| causes.iter().any(p);
        if f.is_bus_off() || has(&|c| matches!(c, FaultCause::TxTimeout)) {
            Some(BusEvent::BusOff)
        } else if f.is_error_passive() {
            Some(BusEvent::ErrorPassive)
        } else if has(&|c| matches!(c, FaultCause::Overflow(_))) {
            Some(BusEvent::RxOverflow)
        } else if has(&|c| matches!(c, FaultCause::ErrorWarning(_))) {
            Some(BusEvent::ErrorWarning)
        } else if has(&|c| matches!(c, FaultCause::NoAck)) {
            Some(BusEvent::NoAck)
        } else if has(&|c| {
            matches!(
                c,
                FaultCause::Protocol { .. }
                    | FaultCause::BusError
                    | FaultCause::LostArbitration(_)
                    | FaultCause::Transceiver(_)
                    | FaultCause::ControllerOther(_)
                    | FaultCause::Unknown(_)
            )
        }) {
            Some(BusEvent::Protocol)
        } else {
            None
        }
    }
}

impl fmt::Display for BusEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A node whose receive side can be impaired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Node {
    /// The motor card.
    Card,
    /// The plant node.
    Plant,
    /// The supervisor.
    Supervisor,
}

impl Node {
    /// Every node.
    pub const ALL: [Node; 3] = [Node::Card, Node::Plant, Node::Supervisor];

    /// Its name in `--inject`.
    pub fn name(self) -> &'static str {
        match self {
            Node::Card => "card",
            Node::Plant => "plant",
            Node::Supervisor => "supervisor",
        }
    }
}

/// A time window of the run, in ticks of 1 ms: `[from, until)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// First tick.
    pub from: u64,
    /// First tick after the window (`None` = to the end).
    pub until: Option<u64>,
}

impl Window {
    /// Whether tick `k` is inside.
    pub fn contains(&self, k: u64) -> bool {
        k >= self.from && self.until.is_none_or(|u| k < u)
    }
}

/// One `--inject` fault.
#[derive(Clone, Debug, PartialEq)]
pub enum Injection {
    /// An error frame at a tick.
    Bus {
        /// Which.
        event: BusEvent,
        /// When (tick).
        at: u64,
    },
    /// A lossy or slow receive side.
    Link {
        /// Whose.
        node: Node,
        /// Loss probability.
        drop: f64,
        /// Fixed delay.
        delay: Duration,
        /// Uniform extra delay up to this.
        jitter: Duration,
        /// When.
        window: Window,
    },
    /// The plant node sends nothing.
    StallPlant(Window),
    /// The supervisor sends and hears nothing.
    KillSupervisor(Window),
    /// Receive queues of this many frames.
    RxQueue(usize),
}

fn seconds(s: &str, what: &str) -> Result<f64> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| anyhow!("{what} `{s}` is not a number of seconds"))?;
    if !v.is_finite() || v < 0.0 {
        bail!("{what} `{s}` must be a time of 0 s or more");
    }
    Ok(v)
}

fn ticks(s: f64) -> u64 {
    (s * 1000.0).round() as u64
}

/// `@T` or `@T+D` (after the `@`) → window; `need_duration` refuses a bare `@T`.
fn window(spec: &str, need_duration: bool) -> Result<Window> {
    let (t, d) = match spec.split_once('+') {
        Some((t, d)) => (t, Some(d)),
        None => (spec, None),
    };
    let from = seconds(t, "start time")?;
    let until = match d {
        Some(d) => {
            let d = seconds(d, "duration")?;
            if d <= 0.0 {
                bail!("duration `{d}` must be above 0 s");
            }
            Some(ticks(from + d))
        }
        None if need_duration => bail!("needs a duration: `@START+SECONDS`"),
        None => None,
    };
    Ok(Window {
        from: ticks(from),
        until,
    })
}

fn duration(s: &str) -> Result<Duration> {
    let s = s.trim();
    let (num, scale) = if let Some(n) = s.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = s.strip_suffix("us").or_else(|| s.strip_suffix("µs")) {
        (n, 1e-6)
    } else if let Some(n) = s.strip_suffix('s') {
        (n, 1.0)
    } else {
        bail!("`{s}` needs a unit: ms, us or s (e.g. 2ms)");
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| anyhow!("`{s}` is not a duration (e.g. 2ms, 500us)"))?;
    if !v.is_finite() || v < 0.0 || v * scale > 10.0 {
        bail!("`{s}` must be between 0 and 10 s");
    }
    Ok(Duration::from_secs_f64(v * scale))
}

fn rate(s: &str) -> Result<f64> {
    let s = s.trim();
    let v = match s.strip_suffix('%') {
        Some(p) => p.trim().parse::<f64>().map(|p| p / 100.0),
        None => s.parse::<f64>(),
    }
    .map_err(|_| anyhow!("drop rate `{s}` is not a number (0.05 or 5%)"))?;
    if !(0.0..=1.0).contains(&v) {
        bail!("drop rate `{s}` must be between 0 and 1 (or 0% and 100%)");
    }
    Ok(v)
}

fn node(s: &str) -> Result<Node> {
    Node::ALL
        .into_iter()
        .find(|n| n.name() == s.trim())
        .ok_or_else(|| anyhow!("unknown node `{s}`; one of card, plant, supervisor"))
}

impl FromStr for Injection {
    type Err = anyhow::Error;

    fn from_str(spec: &str) -> Result<Injection> {
        let spec = spec.trim();
        let parse = || -> Result<Injection> {
            if let Some(n) = spec.strip_prefix("rx-queue=") {
                let n: usize = n
                    .trim()
                    .parse()
                    .map_err(|_| anyhow!("`{n}` is not a frame count"))?;
                if n == 0 {
                    bail!("a receive queue holds at least 1 frame");
                }
                return Ok(Injection::RxQueue(n));
            }
            if let Some((kind, rest)) = spec.split_once(':') {
                let (target, when) = match rest.split_once('@') {
                    Some((t, w)) => (t, Some(w)),
                    None => (rest, None),
                };
                let (who, value) = target
                    .split_once('=')
                    .ok_or_else(|| anyhow!("expected `{kind}:NODE=VALUE`"))?;
                let node = node(who)?;
                let window = match when {
                    Some(w) => window(w, false)?,
                    None => Window {
                        from: 0,
                        until: None,
                    },
                };
                let (mut drop, mut delay, mut jitter) = (0.0, Duration::ZERO, Duration::ZERO);
                match kind {
                    "drop" => drop = rate(value)?,
                    "delay" => delay = duration(value)?,
                    "jitter" => jitter = duration(value)?,
                    other => bail!("unknown link fault `{other}`; one of drop, delay, jitter"),
                }
                return Ok(Injection::Link {
                    node,
                    drop,
                    delay,
                    jitter,
                    window,
                });
            }
            let (kind, when) = spec
                .split_once('@')
                .ok_or_else(|| anyhow!("expected KIND@SECONDS"))?;
            match kind {
                "stall-plant" => Ok(Injection::StallPlant(window(when, true)?)),
                "kill-supervisor" => Ok(Injection::KillSupervisor(window(when, false)?)),
                k => {
                    let event = BusEvent::ALL
                        .into_iter()
                        .find(|e| e.name() == k)
                        .ok_or_else(|| anyhow!("unknown fault `{k}`"))?;
                    if when.contains('+') {
                        bail!("an error frame happens at one instant: `{k}@SECONDS`");
                    }
                    Ok(Injection::Bus {
                        event,
                        at: ticks(seconds(when, "time")?),
                    })
                }
            }
        };
        parse().map_err(|e| {
            anyhow!(
                "--inject `{spec}`: {e:#}. Known: bus-off@T, error-passive@T, error-warning@T, \
                 no-ack@T, protocol@T, rx-overflow@T, drop:NODE=RATE[@T[+D]], \
                 delay:NODE=DUR[@T[+D]], jitter:NODE=DUR[@T[+D]], stall-plant@T+D, \
                 kill-supervisor@T[+D], rx-queue=N (see `hil-host run --help`)"
            )
        })
    }
}

impl fmt::Display for Injection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = |w: &Window| match w.until {
            Some(u) => format!(
                "@{}+{}",
                w.from as f64 * 1e-3,
                u.saturating_sub(w.from) as f64 * 1e-3
            ),
            None if w.from == 0 => String::new(),
            None => format!("@{}", w.from as f64 * 1e-3),
        };
        match self {
            Injection::Bus { event, at } => write!(f, "{event}@{}", *at as f64 * 1e-3),
            Injection::Link {
                node,
                drop,
                delay,
                jitter,
                window,
            } => {
                if *drop > 0.0 {
                    write!(f, "drop:{}={drop}{}", node.name(), w(window))
                } else if *delay > Duration::ZERO {
                    write!(f, "delay:{}={:?}{}", node.name(), delay, w(window))
                } else {
                    write!(f, "jitter:{}={:?}{}", node.name(), jitter, w(window))
                }
            }
            Injection::StallPlant(win) => write!(f, "stall-plant{}", w(win)),
            Injection::KillSupervisor(win) => write!(f, "kill-supervisor{}", w(win)),
            Injection::RxQueue(n) => write!(f, "rx-queue={n}"),
        }
    }
}

/// Every fault of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultPlan {
    /// In the order given.
    pub items: Vec<Injection>,
}

impl FaultPlan {
    /// Parses every `--inject` value.
    pub fn parse(specs: &[String]) -> Result<FaultPlan> {
        let items = specs
            .iter()
            .map(|s| s.parse())
            .collect::<Result<Vec<Injection>>>()?;
        let queues = items
            .iter()
            .filter(|i| matches!(i, Injection::RxQueue(_)))
            .count();
        if queues > 1 {
            bail!("--inject rx-queue=N given {queues} times; give it once");
        }
        Ok(FaultPlan { items })
    }

    /// No faults.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Error frames at tick `k`.
    pub fn bus_events_at(&self, k: u64) -> impl Iterator<Item = BusEvent> + '_ {
        self.items.iter().filter_map(move |i| match i {
            Injection::Bus { event, at } if *at == k => Some(*event),
            _ => None,
        })
    }

    /// The impairments of `node`'s receive side.
    pub fn link_faults(&self, who: Node) -> Vec<LinkFault> {
        self.items
            .iter()
            .filter_map(|i| match i {
                Injection::Link {
                    node,
                    drop,
                    delay,
                    jitter,
                    window,
                } if *node == who => Some(LinkFault {
                    drop: *drop,
                    delay: *delay,
                    jitter: *jitter,
                    from_us: window.from.saturating_mul(1000),
                    until_us: window.until.map(|u| u.saturating_mul(1000)),
                }),
                _ => None,
            })
            .collect()
    }

    /// Whether the plant is stalled at tick `k`.
    pub fn plant_stalled(&self, k: u64) -> bool {
        self.items
            .iter()
            .any(|i| matches!(i, Injection::StallPlant(w) if w.contains(k)))
    }

    /// Whether the supervisor is silent at tick `k`.
    pub fn supervisor_silent(&self, k: u64) -> bool {
        self.items
            .iter()
            .any(|i| matches!(i, Injection::KillSupervisor(w) if w.contains(k)))
    }

    /// The receive-queue length, if capped.
    pub fn rx_queue(&self) -> Option<usize> {
        self.items.iter().find_map(|i| match i {
            Injection::RxQueue(n) => Some(*n),
            _ => None,
        })
    }

    /// Faults only the in-process bus can produce (error frames, short queues).
    pub fn needs_inproc(&self) -> Option<&Injection> {
        self.items
            .iter()
            .find(|i| matches!(i, Injection::Bus { .. } | Injection::RxQueue(_)))
    }

    /// A delay or jitter (they need a clock: simulated ticks or real time).
    pub fn has_delay(&self) -> Option<&Injection> {
        self.items.iter().find(|i| {
            matches!(i, Injection::Link { delay, jitter, .. }
                if *delay > Duration::ZERO || *jitter > Duration::ZERO)
        })
    }

    /// One line naming every fault.
    pub fn describe(&self) -> String {
        self.items
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_kind() {
        let p = FaultPlan::parse(
            &[
                "bus-off@2.5",
                "error-passive@1",
                "error-warning@1.2",
                "no-ack@0.5",
                "protocol@0.7",
                "rx-overflow@0.9",
                "drop:card=0.33",
                "drop:plant=5%@1+0.5",
                "delay:supervisor=2ms@3",
                "jitter:card=500us",
                "stall-plant@2+0.05",
                "kill-supervisor@4",
                "rx-queue=2",
            ]
            .map(String::from),
        )
        .unwrap();
        assert_eq!(
            p.items[0],
            Injection::Bus {
                event: BusEvent::BusOff,
                at: 2500
            }
        );
        assert_eq!(
            p.bus_events_at(1000).collect::<Vec<_>>(),
            [BusEvent::ErrorPassive]
        );
        let card = p.link_faults(Node::Card);
        assert_eq!(card.len(), 2);
        assert_eq!(card[0].drop, 0.33);
        assert_eq!(card[1].jitter, Duration::from_micros(500));
        let plant = p.link_faults(Node::Plant);
        assert_eq!(
            (plant[0].drop, plant[0].from_us, plant[0].until_us),
            (0.05, 1_000_000, Some(1_500_000))
        );
        assert!(p.plant_stalled(2000) && p.plant_stalled(2049) && !p.plant_stalled(2050));
        assert!(!p.supervisor_silent(3999) && p.supervisor_silent(100_000));
        assert_eq!(p.rx_queue(), Some(2));
        assert!(p.needs_inproc().is_some());
        assert!(p.has_delay().is_some());
        // round trip through Display
        for i in &p.items {
            let again: Injection = i.to_string().parse().unwrap();
            assert_eq!(&again, i, "{i}");
        }
    }

    #[test]
    fn bad_specs_say_what_and_where() {
        for (spec, want) in [
            ("bus-of@1", "unknown fault `bus-of`"),
            ("drop:crad=0.3", "unknown node `crad`"),
            ("drop:card=1.5", "between 0 and 1"),
            ("delay:card=2", "needs a unit"),
            ("stall-plant@2", "needs a duration"),
            ("bus-off@-1", "0 s or more"),
            ("bus-off@1+2", "one instant"),
            ("rx-queue=0", "at least 1"),
            ("wobble", "expected KIND@SECONDS"),
        ] {
            let e = spec.parse::<Injection>().unwrap_err().to_string();
            assert!(e.contains(want), "{spec}: {e}");
            assert!(e.contains(&format!("--inject `{spec}`")), "{e}");
        }
        let e = FaultPlan::parse(&["rx-queue=2".into(), "rx-queue=3".into()]).unwrap_err();
        assert!(e.to_string().contains("give it once"), "{e}");
    }

    #[test]
    fn error_frames_classify_as_injected() {
        for e in BusEvent::ALL {
            assert_eq!(BusEvent::classify(&e.fault()), Some(e), "{e}");
        }
        assert_eq!(
            BusEvent::classify(&BusFault::controller(ctrl::ACTIVE, 0, 0)),
            None
        );
        // what the critical ones make a node do
        assert!(BusEvent::BusOff.fault().requires_safe_state());
        assert!(BusEvent::ErrorPassive.fault().is_error_passive());
        assert!(!BusEvent::NoAck.fault().requires_safe_state());
    }
}
