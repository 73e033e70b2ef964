//! The end of a run in words and numbers: what happened first, then the figures — and only
//! figures that describe what the scenario meant to measure.
//!
//! A [`Report`] is built from what the lab knows at the end ([`Facts`]): the recorder's
//! tally (rows, faulted ticks, missing commands, error frames, the card's fault frames),
//! the nodes that ran in this process (card, supervisor, impaired links), whether the run
//! was interrupted, and in real time how late the plant's ticks were. Its [`Verdict`] sets
//! the exit code: a faulted, incomplete, degraded or interrupted run never exits 0. Figures
//! over faulted, incomplete or interrupted data are withheld; over a degraded run (bus error
//! frames, frames lost above the threshold) they are marked.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use controller::proto::params as p;
use controller::proto::{FaultCode, State};
use serde_json::{json, Value};

use jointlab_can::bus::LinkStats;

use super::inject::{BusEvent, Node};
use super::recorder::{SeenFault, Tally};
use super::summary::Summary;
use super::supervisor::{fault_words, Event, Phase};

/// How a run ended. A report takes the worst that applies: interrupted, faulted, incomplete,
/// degraded, ok.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Ran to the end; no fault, no bus error frame, losses under the threshold.
    Ok,
    /// Ran to the end without a card fault, but the bus reported errors or frames were
    /// lost above the threshold.
    Degraded,
    /// The card latched a fault.
    Faulted,
    /// The scenario did not run to its end (gain set not committed, refused, not armed,
    /// the run ended early).
    Incomplete,
    /// Stopped by Ctrl-C.
    Interrupted,
}

impl Verdict {
    /// The process exit code: 0 only for [`Verdict::Ok`]; 130 (128 + SIGINT) when
    /// interrupted; 1 otherwise (2 is a usage or I/O error).
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Ok => 0,
            Verdict::Interrupted => 130,
            Verdict::Degraded | Verdict::Faulted | Verdict::Incomplete => 1,
        }
    }

    /// The word the report opens with.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Ok => "OK",
            Verdict::Degraded => "DEGRADED",
            Verdict::Faulted => "FAULTED",
            Verdict::Incomplete => "INCOMPLETE",
            Verdict::Interrupted => "INTERRUPTED",
        }
    }
}

/// Frames lost above this share of ticks make a run [`Verdict::Degraded`] (the default of
/// `--max-loss`).
pub const MAX_LOSS: f64 = 0.01;

/// The card's default sensor timeout, µs (the parameter table's).
pub fn default_sensor_timeout_us() -> u64 {
    p::lookup(p::SENSOR_TIMEOUT).map_or(3000, |d| d.default.unsigned_abs().into())
}

/// The card, when it ran in this process.
#[derive(Clone, Debug, PartialEq)]
pub struct CardFacts {
    /// Its state at the end.
    pub state: State,
    /// Its latched fault.
    pub fault: Option<(FaultCode, i32)>,
    /// Degraded-bus reports it counted.
    pub bus_warnings: u32,
    /// Own sensor frames it never got.
    pub sensor_frames_lost: u32,
}

/// The supervisor, when it ran in this process.
#[derive(Clone, Debug, PartialEq)]
pub struct SupervisorFacts {
    /// Its phase at the end.
    pub phase: Phase,
    /// The card accepted the gain set.
    pub committed: bool,
    /// Commits sent.
    pub commit_attempts: u32,
    /// What it reported.
    pub events: Vec<Event>,
    /// Error frames it heard.
    pub bus_faults: BTreeMap<BusEvent, u64>,
    /// Faults it cleared (recovery mode).
    pub recoveries: u32,
}

/// How late the plant's ticks started (real time), from a bounded histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct Lateness {
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// The worst, µs.
    pub max_us: f64,
    /// When the worst came, s of run time.
    pub worst_at_s: f64,
    /// Ticks that started more than half a period late.
    pub late_ticks: u64,
    /// Ticks measured.
    pub ticks: u64,
}

impl Lateness {
    /// Whether the machine held 1 kHz: no stall the card's sensor timeout would catch, and
    /// 99 % of the ticks within half a period.
    pub fn holds(&self, sensor_timeout_us: u64) -> bool {
        self.max_us + 1000.0 < sensor_timeout_us as f64 && self.p99_us <= 500.0
    }
}

/// Everything the lab knows at the end of a run.
#[derive(Clone, Debug)]
pub struct Facts {
    /// First line: scenario, plant, bus, clock.
    pub title: String,
    /// Ticks the run was meant to have.
    pub ticks_planned: u64,
    /// Ticks it ran (the lab's clock; a stalled plant records fewer rows).
    pub ticks_run: u64,
    /// Ctrl-C.
    pub interrupted: bool,
    /// The recorder's counts.
    pub tally: Tally,
    /// The plant's counts of actuator frames that never came / answered an older tick.
    pub missing_actuator: u64,
    /// Stale actuator frames.
    pub stale_actuator: u64,
    /// Error frames the plant node heard.
    pub plant_bus_faults: BTreeMap<BusEvent, u64>,
    /// The card, if it ran here.
    pub card: Option<CardFacts>,
    /// The supervisor, if it ran here.
    pub supervisor: Option<SupervisorFacts>,
    /// Impaired receive sides.
    pub links: Vec<(Node, LinkStats)>,
    /// The `--inject` faults, one line.
    pub injected: Vec<String>,
    /// Real time only.
    pub lateness: Option<Lateness>,
    /// The card's sensor timeout, µs.
    pub sensor_timeout_us: u64,
    /// Loss threshold (share of ticks).
    pub max_loss: f64,
}

/// The report of one run. See the module docs.
#[derive(Clone, Debug)]
pub struct Report {
    /// The facts it was built from.
    pub facts: Facts,
    /// How the run ended.
    pub verdict: Verdict,
    /// One sentence: what happened.
    pub headline: String,
    /// Further lines: every fault, loss and count, in order of importance.
    pub details: Vec<String>,
    /// Why the scenario's figures are not given, if they are not.
    pub withheld: Option<String>,
    /// Why the figures must be read with care, if they must.
    pub caution: Option<String>,
    /// The figures (only peak torque and bus load when withheld).
    pub figures: Summary,
    /// Files written.
    pub files: Vec<String>,
}

/// `k` of `n` as a percentage with the decimals a small share needs.
fn share(k: u64, n: u64) -> String {
    let p = pct(k, n);
    if p > 0.0 && p < 0.1 {
        format!("{p:.3} %")
    } else {
        format!("{p:.1} %")
    }
}

fn pct(k: u64, n: u64) -> f64 {
    if n == 0 {
        0.0
    } else {
        k as f64 * 100.0 / n as f64
    }
}

fn counts(m: &BTreeMap<BusEvent, u64>) -> String {
    m.iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The first card fault: from its fault frames, else from the card itself.
fn first_fault(f: &Facts) -> Option<SeenFault> {
    f.tally.card_faults.first().copied().or_else(|| {
        f.card
            .as_ref()
            .and_then(|c| c.fault)
            .map(|(code, detail)| SeenFault {
                time_s: f.tally.first_faulted_s.unwrap_or(f.tally.last_time_s),
                code,
                detail,
            })
    })
}

impl Report {
    /// Judges the facts. Call [`Report::withholds`] to know whether to compute the figures,
    /// then [`Report::with_figures`].
    pub fn judge(facts: Facts) -> Report {
        let f = &facts;
        let t = &f.tally;
        let mut details = Vec::new();
        let rows = t.rows.max(1);
        let fault = first_fault(f);
        let faulted = fault.is_some() || t.faulted_rows > 0;
        // incomplete: why
        let mut unfinished = None;
        if let Some(s) = &f.supervisor {
            let refused = s.events.iter().find_map(|e| match e {
                Event::Refused(w) => Some(w.clone()),
                _ => None,
            });
            if !s.committed {
                unfinished = Some(match &refused {
                    Some(w) => format!("the gain set was never committed: {w}; the card never ran the scenario"),
                    None => format!(
                        "the gain set was never committed ({} commit(s) sent, none answered); the card never ran the scenario",
                        s.commit_attempts
                    ),
                });
            } else if let Some(w) = refused {
                unfinished = Some(format!("the card refused what the supervisor sent: {w}"));
            } else if matches!(s.phase, Phase::Configuring | Phase::Arming) {
                unfinished = Some("the card was never armed".to_string());
            }
        }
        if unfinished.is_none() && !f.interrupted && f.ticks_run < f.ticks_planned {
            unfinished = Some(format!(
                "the run ended after {} of {} ticks",
                f.ticks_run, f.ticks_planned
            ));
        }
        let lost = t.missing_rows;
        let loss_share = lost as f64 / rows as f64;
        let bus_errors: u64 = t.error_frames.values().sum();
        let card_warnings = f.card.as_ref().map_or(0, |c| c.bus_warnings);
        let verdict = if f.interrupted {
            Verdict::Interrupted
        } else if faulted {
            Verdict::Faulted
        } else if unfinished.is_some() {
            Verdict::Incomplete
        } else if bus_errors > 0 || card_warnings > 0 || loss_share > f.max_loss {
            Verdict::Degraded
        } else {
            Verdict::Ok
        };
        let fault_line = fault.map(|x| {
            format!(
                "the card latched {} at {:.3} s ({})",
                x.code.name(),
                x.time_s,
                fault_words(x.code, x.detail)
            )
        });
        let faulted_line = format!(
            "{} of {} ticks ({}) ran faulted{}",
            t.faulted_rows,
            t.rows,
            share(t.faulted_rows, t.rows),
            t.first_faulted_s
                .map(|s| format!(", from {s:.3} s"))
                .unwrap_or_default()
        );
        let headline = match verdict {
            Verdict::Interrupted => format!(
                "stopped by Ctrl-C at {:.3} s, after {} of {} ticks ({:.0} %)",
                f.ticks_run as f64 * 1e-3,
                f.ticks_run,
                f.ticks_planned,
                pct(f.ticks_run, f.ticks_planned)
            ),
            Verdict::Faulted => format!(
                "{}; {faulted_line}",
                fault_line
                    .clone()
                    .unwrap_or_else(|| "the card's actuator frames carried its fault bit".into())
            ),
            Verdict::Incomplete => unfinished.clone().unwrap_or_default(),
            Verdict::Degraded => {
                let mut why = vec![];
                if bus_errors > 0 {
                    why.push(format!(
                        "{bus_errors} bus error frame(s) ({})",
                        counts(&t.error_frames)
                    ));
                }
                if card_warnings > 0 && bus_errors == 0 {
                    why.push(format!("the card counted {card_warnings} bus warning(s)"));
                }
                if loss_share > f.max_loss {
                    why.push(format!(
                        "{lost} of {} ticks ({:.2} %) had no actuator frame, above the {:.2} % threshold",
                        t.rows,
                        loss_share * 100.0,
                        f.max_loss * 100.0
                    ));
                }
                format!(
                    "ran all {} ticks without a card fault, but {}",
                    f.ticks_run,
                    why.join("; ")
                )
            }
            Verdict::Ok => format!(
                "ran all {} ticks; no card fault, no bus error frame, {}{}",
                f.ticks_run,
                if lost == 0 {
                    "no actuator frame lost".to_string()
                } else {
                    format!(
                        "{lost} tick(s) without an actuator frame ({:.3} %, under the {:.2} % threshold)",
                        loss_share * 100.0,
                        f.max_loss * 100.0
                    )
                },
                // Losses on other links do not fail the run, but the headline must not
                // read as if nothing was lost.
                match f.links.iter().map(|(_, l)| l.dropped).sum::<u64>() {
                    0 => String::new(),
                    n => format!("; {n} frame(s) dropped on injected links (below)"),
                }
            ),
        };
        // details, every one that applies
        if verdict != Verdict::Faulted {
            if let Some(l) = &fault_line {
                details.push(format!("{l}; {faulted_line}"));
            }
        }
        if t.card_fault_frames > 1 {
            let list: Vec<String> = t
                .card_faults
                .iter()
                .map(|x| format!("{} at {:.3} s", x.code.name(), x.time_s))
                .collect();
            details.push(format!(
                "card fault frames: {} ({}{})",
                t.card_fault_frames,
                list.join(", "),
                if t.card_fault_frames as usize > list.len() {
                    ", …"
                } else {
                    ""
                }
            ));
        }
        if let Some(c) = &f.card {
            if c.fault.is_some() || matches!(c.state, State::FaultReaction | State::Fault) {
                details.push(format!(
                    "card at the end: {}{}",
                    c.state.name(),
                    c.fault
                        .map(|(k, _)| format!(", fault {}", k.name()))
                        .unwrap_or_default()
                ));
            }
        }
        if verdict != Verdict::Incomplete {
            if let Some(u) = &unfinished {
                details.push(format!("incomplete: {u}"));
            }
        }
        if let Some(s) = &f.supervisor {
            for e in &s.events {
                if let Event::Fault(w) = e {
                    details.push(format!("supervisor heard: {w}"));
                }
            }
            if s.commit_attempts > 1 && s.committed {
                details.push(format!(
                    "the gain set was sent {} times before a commit was answered",
                    s.commit_attempts
                ));
            }
            if s.recoveries > 0 {
                details.push(format!(
                    "the supervisor cleared the fault and re-armed the card {} time(s)",
                    s.recoveries
                ));
            }
        }
        if !f.injected.is_empty() {
            details.push(format!("injected: {}", f.injected.join(", ")));
        }
        let sup_heard = f
            .supervisor
            .as_ref()
            .map_or(0, |s| s.bus_faults.values().sum::<u64>());
        let plant_heard = f.plant_bus_faults.values().sum::<u64>();
        if t.error_frames_total() > 0 {
            let mut line = format!(
                "bus error frames: {}{}",
                t.error_frames_total(),
                if t.error_frames.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", counts(&t.error_frames))
                }
            );
            if t.info_frames > 0 {
                let _ = write!(line, ", {} recovery/counter report(s)", t.info_frames);
            }
            details.push(line);
        }
        if t.error_frames_total() > 0 || card_warnings > 0 || sup_heard > 0 || plant_heard > 0 {
            // Each controller reports its own errors too (an overflow is the receiver's).
            let mut heard = vec![];
            if let Some(c) = &f.card {
                heard.push(format!(
                    "the card counted {} bus warning(s)",
                    c.bus_warnings
                ));
            }
            if let Some(s) = &f.supervisor {
                heard.push(format!(
                    "the supervisor heard {sup_heard}{}",
                    if s.bus_faults.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", counts(&s.bus_faults))
                    }
                ));
            }
            heard.push(format!(
                "the plant {plant_heard}{}",
                if f.plant_bus_faults.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", counts(&f.plant_bus_faults))
                }
            ));
            details.push(format!(
                "error frames heard by the nodes: {}",
                heard.join("; ")
            ));
        }
        let drops: Vec<String> = f
            .links
            .iter()
            .filter(|(_, s)| s.dropped > 0 || s.delayed > 0)
            .map(|(n, s)| {
                format!(
                    "{}: {} of {} received frames dropped, {} delayed",
                    n.name(),
                    s.dropped,
                    s.received,
                    s.delayed
                )
            })
            .collect();
        if !drops.is_empty() {
            details.push(format!("injected losses: {}", drops.join("; ")));
        }
        if lost > 0
            || f.stale_actuator > 0
            || f.card.as_ref().is_some_and(|c| c.sensor_frames_lost > 0)
        {
            let mut line = format!(
                "frames lost: {lost} tick(s) ({:.2} %) without an actuator frame at the plant, {} stale",
                loss_share * 100.0,
                f.stale_actuator
            );
            if let Some(c) = &f.card {
                let _ = write!(
                    line,
                    "; the card missed {} of its sensor frames",
                    c.sensor_frames_lost
                );
            }
            details.push(line);
        }
        if let Some(l) = &f.lateness {
            let holds = l.holds(f.sensor_timeout_us);
            let timeout_ms = f.sensor_timeout_us as f64 * 1e-3;
            if holds {
                details.push(format!(
                    "this machine held 1 kHz: tick lateness p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs (at {:.3} s)",
                    l.p50_us, l.p99_us, l.max_us, l.worst_at_s
                ));
            } else {
                details.push(format!(
                    "this machine did NOT hold 1 kHz: the worst stall was {:.2} ms at {:.3} s \
                     (the card's sensor timeout, {timeout_ms:.1} ms, allows {:.1} ms of lateness); \
                     {} of {} ticks started more than 0.5 ms late; lateness p50 {:.0} µs, p99 {:.0} µs \
                     (--sensor-timeout-us raises the card's timeout; lockstep needs no clock)",
                    l.max_us * 1e-3,
                    l.worst_at_s,
                    timeout_ms - 1.0,
                    l.late_ticks,
                    l.ticks,
                    l.p50_us,
                    l.p99_us
                ));
            }
        }
        let withheld = match verdict {
            Verdict::Faulted => Some(format!(
                "they would describe faulted data ({} of the ticks ran faulted)",
                share(t.faulted_rows, rows)
            )),
            Verdict::Incomplete => Some("the scenario did not run to its end".into()),
            Verdict::Interrupted => Some(format!(
                "the scenario was interrupted after {:.0} % of its ticks",
                pct(f.ticks_run, f.ticks_planned)
            )),
            Verdict::Degraded | Verdict::Ok => None,
        };
        let caution = (verdict == Verdict::Degraded)
            .then(|| "over a degraded run (see above): read them with care".to_string());
        Report {
            facts,
            verdict,
            headline,
            details,
            withheld,
            caution,
            figures: Summary::default(),
            files: vec![],
        }
    }

    /// Why the scenario's figures are not computed, if they are not.
    pub fn withholds(&self) -> Option<&str> {
        self.withheld.as_deref()
    }

    /// Adds the figures (computed with [`Report::withholds`] in mind).
    pub fn with_figures(mut self, figures: Summary) -> Report {
        self.figures = figures;
        self
    }

    /// The plain-text report: title, verdict and headline, details, figures.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{}", self.facts.title);
        let _ = writeln!(s, "  {}: {}", self.verdict.word(), self.headline);
        for d in &self.details {
            let _ = writeln!(s, "  - {d}");
        }
        if let Some(w) = &self.withheld {
            let _ = writeln!(
                s,
                "  figures withheld: {w}; peak torque and bus load are over the whole run"
            );
        }
        if let Some(c) = &self.caution {
            let _ = writeln!(s, "  figures {c}");
        }
        for w in &self.figures.warnings {
            let _ = writeln!(s, "  WARNING: {w}");
        }
        s.push_str(&self.figures.table());
        for f in &self.files {
            let _ = writeln!(s, "  wrote {f}");
        }
        s
    }

    /// The same report as JSON.
    pub fn json(&self) -> Value {
        let f = &self.facts;
        let t = &f.tally;
        let map = |m: &BTreeMap<BusEvent, u64>| {
            m.iter()
                .map(|(k, v)| (k.name().to_string(), json!(v)))
                .collect::<serde_json::Map<_, _>>()
        };
        let num = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
        json!({
            "schema_version": SCHEMA_VERSION,
            "title": f.title,
            "verdict": self.verdict.word().to_lowercase(),
            "exit_code": self.verdict.exit_code(),
            "headline": self.headline,
            "details": self.details,
            "ticks": {
                "planned": f.ticks_planned,
                "run": f.ticks_run,
                "recorded": t.rows,
                "faulted": t.faulted_rows,
                "faulted_share": t.faulted_rows as f64 / t.rows.max(1) as f64,
                "first_faulted_s": t.first_faulted_s,
                "cmd_missing": t.missing_rows,
                "stale_actuator": f.stale_actuator,
            },
            "interrupted": f.interrupted,
            "card_faults": t.card_faults.iter().map(|x| json!({
                "time_s": x.time_s,
                "code": x.code.name(),
                "detail": x.detail,
                "words": fault_words(x.code, x.detail),
            })).collect::<Vec<_>>(),
            "card_fault_frames": t.card_fault_frames,
            "card": f.card.as_ref().map(|c| json!({
                "state": c.state.name(),
                "fault": c.fault.map(|(k, _)| k.name()),
                "bus_warnings": c.bus_warnings,
                "sensor_frames_lost": c.sensor_frames_lost,
            })),
            "bus_error_frames": map(&t.error_frames),
            "bus_error_frames_total": t.error_frames_total(),
            "bus_info_frames": t.info_frames,
            "data_frames": t.frames,
            "plant_bus_faults": map(&f.plant_bus_faults),
            "supervisor": f.supervisor.as_ref().map(|s| json!({
                "phase": format!("{:?}", s.phase),
                "committed": s.committed,
                "commit_attempts": s.commit_attempts,
                "events": s.events.iter().map(|e| format!("{e:?}")).collect::<Vec<_>>(),
                "bus_faults": map(&s.bus_faults),
                "recoveries": s.recoveries,
            })),
            "links": f.links.iter().map(|(n, s)| (n.name().to_string(), json!({
                "received": s.received, "dropped": s.dropped, "delayed": s.delayed,
            }))).collect::<serde_json::Map<_, _>>(),
            "injected": f.injected,
            "lateness_us": f.lateness.as_ref().map(|l| json!({
                "p50": l.p50_us, "p99": l.p99_us, "max": l.max_us,
                "worst_at_s": l.worst_at_s, "late_ticks": l.late_ticks, "ticks": l.ticks,
                "holds_1khz": l.holds(f.sensor_timeout_us),
            })),
            "sensor_timeout_us": f.sensor_timeout_us,
            "max_loss": f.max_loss,
            "figures_withheld": self.withheld,
            "figures_caution": self.caution,
            "warnings": self.figures.warnings,
            "figures": self.figures.rows.iter().map(|(n, v, u)| json!({
                "name": n, "value": num(*v), "unit": u,
            })).collect::<Vec<_>>(),
            "files": self.files,
        })
    }
}

/// The layout of [`Report::json`]: raised when a key changes meaning or goes away (a new key
/// does not raise it). Durations and times carry their unit in the key (`_s`, `_us`),
/// figures in their `unit`.
pub const SCHEMA_VERSION: u32 = 1;

/// A run that did not end [`Verdict::Ok`]: the error a command returns after printing its
/// report, carrying the exit code.
#[derive(Debug, thiserror::Error)]
#[error("{}: {headline}", verdict.word())]
pub struct RunFailed {
    /// How it ended.
    pub verdict: Verdict,
    /// What happened.
    pub headline: String,
}

impl RunFailed {
    /// `Err(RunFailed)` unless the report is [`Verdict::Ok`].
    pub fn check(r: &Report) -> Result<(), RunFailed> {
        if r.verdict == Verdict::Ok {
            Ok(())
        } else {
            Err(RunFailed {
                verdict: r.verdict,
                headline: r.headline.clone(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn facts() -> Facts {
        Facts {
            title: "t".into(),
            ticks_planned: 1000,
            ticks_run: 1000,
            interrupted: false,
            tally: Tally {
                rows: 1000,
                last_time_s: 1.0,
                ..Tally::default()
            },
            missing_actuator: 0,
            stale_actuator: 0,
            plant_bus_faults: BTreeMap::new(),
            card: None,
            supervisor: Some(SupervisorFacts {
                phase: Phase::Running,
                committed: true,
                commit_attempts: 1,
                events: vec![Event::Committed],
                bus_faults: BTreeMap::new(),
                recoveries: 0,
            }),
            links: vec![],
            injected: vec![],
            lateness: None,
            sensor_timeout_us: 3000,
            max_loss: MAX_LOSS,
        }
    }

    #[test]
    fn verdicts_and_exit_codes() {
        let r = Report::judge(facts());
        assert_eq!((r.verdict, r.verdict.exit_code()), (Verdict::Ok, 0));
        assert!(r.withholds().is_none());

        let mut f = facts();
        f.tally.faulted_rows = 250;
        f.tally.first_faulted_s = Some(0.75);
        f.tally.card_faults.push(SeenFault {
            time_s: 0.75,
            code: FaultCode::SensorTimeout,
            detail: 4100,
        });
        f.tally.card_fault_frames = 1;
        let r = Report::judge(f);
        assert_eq!((r.verdict, r.verdict.exit_code()), (Verdict::Faulted, 1));
        assert!(
            r.headline.contains("SensorTimeout at 0.750 s"),
            "{}",
            r.headline
        );
        assert!(
            r.headline.contains("250 of 1000 ticks (25.0 %)"),
            "{}",
            r.headline
        );
        assert!(r.withholds().is_some());
        let text = r.text();
        assert!(
            text.lines().nth(1).unwrap().starts_with("  FAULTED: "),
            "{text}"
        );

        let mut f = facts();
        f.interrupted = true;
        f.ticks_run = 400;
        let r = Report::judge(f);
        assert_eq!(
            (r.verdict, r.verdict.exit_code()),
            (Verdict::Interrupted, 130)
        );
        assert!(r.headline.contains("400 of 1000"), "{}", r.headline);

        let mut f = facts();
        if let Some(s) = &mut f.supervisor {
            s.committed = false;
            s.commit_attempts = 3;
            s.phase = Phase::Stopped;
            s.events = vec![Event::Refused("gain set not committed: …".into())];
        }
        let r = Report::judge(f);
        assert_eq!(r.verdict, Verdict::Incomplete);
        assert!(r.headline.contains("never committed"), "{}", r.headline);

        let mut f = facts();
        f.tally.error_frames.insert(BusEvent::NoAck, 1);
        let r = Report::judge(f);
        assert_eq!(r.verdict, Verdict::Degraded);
        assert!(r.headline.contains("no-ack 1"), "{}", r.headline);
        assert!(r.caution.is_some() && r.withholds().is_none());

        let mut f = facts();
        f.tally.missing_rows = 5;
        assert_eq!(Report::judge(f.clone()).verdict, Verdict::Ok, "0.5 % < 1 %");
        f.tally.missing_rows = 50;
        assert_eq!(Report::judge(f).verdict, Verdict::Degraded, "5 % > 1 %");
    }

    /// A clean run whose supervisor lost telemetry on an injected link still passes, but its
    /// headline says frames were dropped rather than "nothing lost".
    #[test]
    fn an_ok_headline_mentions_frames_dropped_on_injected_links() {
        let r = Report::judge(facts());
        assert!(!r.headline.contains("dropped"), "{}", r.headline);
        let mut f = facts();
        f.links.push((
            Node::Supervisor,
            LinkStats {
                received: 300,
                dropped: 90,
                delayed: 0,
            },
        ));
        let r = Report::judge(f);
        assert_eq!(r.verdict, Verdict::Ok);
        assert!(
            r.headline.contains("90 frame(s) dropped on injected links"),
            "{}",
            r.headline
        );
    }

    #[test]
    fn json_carries_the_verdict_and_the_counts() {
        let mut f = facts();
        f.tally.error_frames.insert(BusEvent::BusOff, 1);
        f.tally.faulted_rows = 10;
        let r = Report::judge(f);
        let j = r.json();
        assert_eq!(j["verdict"], "faulted");
        assert_eq!(j["exit_code"], 1);
        assert_eq!(j["bus_error_frames"]["bus-off"], 1);
        assert_eq!(j["ticks"]["faulted"], 10);
        assert!(j["figures_withheld"].is_string());
    }

    #[test]
    fn a_machine_that_stalls_past_the_sensor_timeout_does_not_hold_1khz() {
        let l = Lateness {
            p50_us: 20.0,
            p99_us: 120.0,
            max_us: 4100.0,
            worst_at_s: 5.1,
            late_ticks: 3,
            ticks: 60_000,
        };
        assert!(!l.holds(3000));
        assert!(l.holds(6000));
        let mut f = facts();
        f.lateness = Some(l);
        let r = Report::judge(f);
        let d = r.details.join("\n");
        assert!(
            d.contains("did NOT hold 1 kHz") && d.contains("4.10 ms at 5.100 s"),
            "{d}"
        );
    }
}
