//! The supervisor (the thesis's "topside" computer): configures the card, arms it, selects
//! the mode, streams setpoints at 20–400 Hz, keeps the watchdog fed, watches telemetry and
//! reports faults in words.
//!
//! Sans-IO like the card: [`Supervisor::on_tick`] is called once per control tick (the
//! supervisor counts `Sensor` frames on the bus, so in lockstep it runs on the same time base
//! as card and plant and a run is reproducible) and returns the messages to send;
//! [`Supervisor::on_message`] takes what the card says.

use std::collections::BTreeMap;

use controller::proto::params::{self as p};
use controller::proto::scale::{self, MOTOR_TORQUE_NM_PER_LSB, OUTPUT_TORQUE_NM_PER_LSB};
use controller::proto::{
    ControlWord, FaultCode, LimitFlags, Message, Mode, NodeId, ParamCommit, ParamStatus,
    ParamWrite, ReplyTo, SetChecksum, SetpointForce, SetpointMotion, State,
};

use jointlab_can::bus::BusFault;

use super::gains::JointScale;
use super::inject::{BusEvent, Window};
use super::trajectory::Trajectory;

/// Ticks the supervisor waits for the answer to a commit before it sends the set again.
pub const COMMIT_TIMEOUT_TICKS: u64 = 250;

/// Commits of one gain set before the supervisor gives up and says so.
pub const COMMIT_ATTEMPTS: u32 = 3;

/// Recovery mode: ticks after a control word before a heartbeat is taken to show its
/// effect (the card's heartbeat period, 100 ms, and a margin).
pub const RECOVERY_SETTLE_TICKS: u64 = 150;

/// What the supervisor commands with its trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Output position (rad) → `SetpointMotion.position` in motor counts.
    Position,
    /// Output torque (N·m) → `SetpointForce`.
    Force,
    /// Motor torque (N·m) → `SetpointMotion.torque_ff` (torque passthrough).
    Torque,
}

/// Where the supervisor is in its script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Parameter set sent, waiting for the commit reply.
    Configuring,
    /// Commit accepted; arming (Shutdown, then Enable).
    Arming,
    /// Streaming setpoints.
    Running,
    /// Disabled at the end (or after a fault).
    Stopped,
}

/// Latest telemetry, in SI.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// Motor position, motor rad (from counts).
    pub position: f64,
    /// Motor velocity estimate, rad/s.
    pub velocity: f64,
    /// Motor torque command, N·m.
    pub torque_cmd: f64,
    /// Output torque sensor, N·m.
    pub output_torque: f64,
    /// Card state from the last heartbeat.
    pub state: Option<State>,
    /// Limit flags.
    pub limits: LimitFlags,
}

/// Something the supervisor wants a person to know.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// The card accepted the parameter set.
    Committed,
    /// The card refused a parameter write or the commit.
    Refused(String),
    /// The card reported a fault.
    Fault(String),
}

/// A fault code in words, with what to do about it.
pub fn fault_words(code: FaultCode, detail: i32) -> String {
    match code {
        FaultCode::SensorTimeout => {
            format!("no sensor frame for {detail} µs — is the plant node (or encoder ISR) running?")
        }
        FaultCode::SupervisorWatchdog => {
            format!("supervisor silent for {detail} ms — the card stopped the joint (watchdog)")
        }
        FaultCode::BusError => format!(
            "CAN bus error (class {detail:#x}) — check wiring/termination or the interface state"
        ),
        FaultCode::Overflow => {
            "arithmetic saturation in the control path — gains too high for the format".into()
        }
        FaultCode::PositionLimit => format!("position {detail} counts outside the soft limits"),
        FaultCode::VelocityLimit => format!("velocity {detail} counts/s above the velocity limit"),
        FaultCode::OutputTorqueLimit => format!(
            "output torque {:.2} N·m above its limit",
            f64::from(detail) * 0.01
        ),
        FaultCode::ConfigRejected => {
            let name = p::lookup(u16::try_from(detail).unwrap_or(0))
                .map(|d| d.name)
                .unwrap_or("?");
            format!("configuration rejected on arming (parameter `{name}`)")
        }
        FaultCode::SensorInvalid => {
            "a sensor the mode needs is missing or reported an error".into()
        }
        FaultCode::SequenceError => format!("sensor frames lost (expected/got {:#06x})", detail),
        FaultCode::PowerStage => format!("power stage fault (status {detail:#x})"),
        FaultCode::Internal => format!("internal card error at {detail}"),
    }
}

/// The supervisor of one joint.
#[derive(Debug)]
pub struct Supervisor {
    node: NodeId,
    scale: JointScale,
    entries: Vec<(u16, i32)>,
    mode: Mode,
    target: Target,
    trajectory: Trajectory,
    /// Ticks between two setpoint frames (1000 / rate).
    period_ticks: u64,
    set_seq: u8,
    phase: Phase,
    started_at: Option<u64>,
    stop_at: Option<u64>,
    arm_step: u8,
    /// Latest telemetry.
    pub telemetry: Telemetry,
    /// What happened, in order.
    pub events: Vec<Event>,
    /// The last setpoint sent (output units).
    pub last_setpoint: f64,
    silent: bool,
    silent_windows: Vec<Window>,
    tick: u64,
    sent_at: Option<u64>,
    resend: bool,
    attempts: u32,
    bus_faults: BTreeMap<BusEvent, u64>,
    recover: bool,
    recovering: bool,
    recoveries: u32,
    last_command: u64,
    heartbeats: u64,
    acted_on: u64,
    velocity_ff: bool,
}

impl Supervisor {
    /// A supervisor that will commit `entries`, arm `mode`, and stream `trajectory` (for
    /// `target`) at `rate_hz` (clamped to 20–400 Hz, the thesis's range), stopping after
    /// `duration_s` of streaming (`None` = forever).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        node: NodeId,
        scale: JointScale,
        entries: Vec<(u16, i32)>,
        mode: Mode,
        target: Target,
        trajectory: Trajectory,
        rate_hz: f64,
        duration_s: Option<f64>,
    ) -> Self {
        let rate = rate_hz.clamp(20.0, 400.0);
        Supervisor {
            node,
            scale,
            entries,
            mode,
            target,
            trajectory,
            period_ticks: (1000.0 / rate).round().max(1.0) as u64,
            set_seq: 0,
            phase: Phase::Configuring,
            started_at: None,
            stop_at: duration_s.map(|d| (d * 1000.0).round() as u64),
            arm_step: 0,
            telemetry: Telemetry::default(),
            events: vec![],
            last_setpoint: 0.0,
            silent: false,
            silent_windows: vec![],
            tick: 0,
            sent_at: None,
            resend: false,
            attempts: 0,
            bus_faults: BTreeMap::new(),
            recover: false,
            recovering: false,
            recoveries: 0,
            last_command: 0,
            heartbeats: 0,
            acted_on: 0,
            velocity_ff: false,
        }
    }

    /// Send the trajectory's velocity with each position setpoint (the card's velocity
    /// feed-forward, and its friction compensation's input when `friction_source` is 1).
    pub fn set_velocity_ff(&mut self, on: bool) {
        self.velocity_ff = on;
    }

    /// When the trajectory's time 0 was, in the run's seconds (the tick the card was
    /// enabled on; None before). A recording's `time_s` is the run's.
    pub fn trajectory_start_s(&self) -> Option<f64> {
        self.started_at.map(|t| t as f64 * 1e-3)
    }

    /// Current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Stop sending anything (simulates a supervisor crash, for watchdog tests).
    pub fn go_silent(&mut self) {
        self.silent = true;
    }

    /// Ticks in which the supervisor sends and hears nothing (a stalled or killed
    /// supervisor process; `--inject kill-supervisor@T[+D]`).
    pub fn set_silent_windows(&mut self, windows: Vec<Window>) {
        self.silent_windows = windows;
    }

    /// Whether the supervisor is silent at tick `k`.
    pub fn silent_at(&self, k: u64) -> bool {
        self.silent || self.silent_windows.iter().any(|w| w.contains(k))
    }

    /// After a fault, clear it and arm again, then go on streaming (a soak run's operator)
    /// instead of stopping. Off by default.
    pub fn set_recovery(&mut self, on: bool) {
        self.recover = on;
    }

    /// Faults cleared and the card re-armed so far (recovery mode).
    pub fn recoveries(&self) -> u32 {
        self.recoveries
    }

    /// Whether the card accepted the gain set.
    pub fn committed(&self) -> bool {
        self.events.iter().any(|e| matches!(e, Event::Committed))
    }

    /// Commits of the gain set sent so far.
    pub fn commit_attempts(&self) -> u32 {
        self.attempts
    }

    /// Error frames heard, by class.
    pub fn bus_faults(&self) -> &BTreeMap<BusEvent, u64> {
        &self.bus_faults
    }

    /// An error frame reached the supervisor's controller: counted (its frames are sent
    /// again by CAN; what is lost for good shows up as an unanswered commit or a fault).
    pub fn on_bus_fault(&mut self, f: &BusFault) {
        if let Some(c) = BusEvent::classify(f) {
            *self.bus_faults.entry(c).or_default() += 1;
        }
    }

    fn gain_set(&mut self, tick: u64, out: &mut Vec<Message>) {
        self.attempts += 1;
        self.sent_at = Some(tick);
        self.resend = false;
        self.set_seq = self.set_seq.wrapping_add(1);
        for &(id, v) in &self.entries {
            out.push(Message::ParamWrite(ParamWrite {
                param_id: id,
                value: v,
                set_seq: self.set_seq,
            }));
        }
        let sum = SetChecksum::of(&self.entries);
        out.push(Message::ParamCommit(ParamCommit {
            set_seq: self.set_seq,
            count: sum.count(),
            crc: sum.crc(),
        }));
    }

    /// Recovery (see [`Supervisor::set_recovery`]): one step per heartbeat that came after
    /// the last command had time to act ([`RECOVERY_SETTLE_TICKS`]), from what it says —
    /// clear the fault, shut down, enable — until it says `Enabled` (a command lost on the
    /// way is simply sent again).
    fn recover_step(&mut self, tick: u64, out: &mut Vec<Message>) {
        if self.heartbeats == self.acted_on
            || tick.saturating_sub(self.last_command) < RECOVERY_SETTLE_TICKS
        {
            return;
        }
        self.acted_on = self.heartbeats;
        let cw = match self.telemetry.state {
            Some(State::Fault) => ControlWord::ClearFault,
            Some(State::Disabled) => ControlWord::Shutdown,
            Some(State::Ready) => ControlWord::Enable(self.mode),
            Some(State::Enabled) => {
                self.recovering = false;
                self.recoveries += 1;
                return;
            }
            _ => return,
        };
        self.last_command = tick;
        out.push(Message::ControlWord(cw));
    }

    fn setpoint(&mut self, t: f64) -> Message {
        let v = self.trajectory.at(t);
        self.last_setpoint = v;
        match self.target {
            Target::Position => {
                let per_rad = self.scale.counts_per_output_rad(self.mode);
                let counts = (v * per_rad).round();
                // 8 counts/s per LSB
                let vff = if self.velocity_ff {
                    (self.trajectory.velocity(t) * per_rad / 8.0)
                        .round()
                        .clamp(-32767.0, 32767.0) as i16
                } else {
                    0
                };
                Message::SetpointMotion(SetpointMotion {
                    position: counts as i64 as i32,
                    velocity_ff: vff,
                    torque_ff: 0,
                })
            }
            Target::Torque => Message::SetpointMotion(SetpointMotion {
                position: 0,
                velocity_ff: 0,
                torque_ff: (v / MOTOR_TORQUE_NM_PER_LSB)
                    .round()
                    .clamp(-32767.0, 32767.0) as i16,
            }),
            Target::Force => Message::SetpointForce(SetpointForce {
                output_torque: (v / OUTPUT_TORQUE_NM_PER_LSB)
                    .round()
                    .clamp(-32767.0, 32767.0) as i16,
            }),
        }
    }

    /// Messages to send at control tick `tick` (1 ms each).
    pub fn on_tick(&mut self, tick: u64) -> Vec<Message> {
        self.tick = tick;
        if self.silent_at(tick) {
            return vec![];
        }
        let mut out = vec![];
        match self.phase {
            Phase::Configuring => {
                // A set whose commit is not answered (writes or the reply lost on the way)
                // goes again; after COMMIT_ATTEMPTS the supervisor stops and says so.
                let due = self.resend
                    || self
                        .sent_at
                        .is_none_or(|t| tick.saturating_sub(t) >= COMMIT_TIMEOUT_TICKS);
                if due && self.attempts >= COMMIT_ATTEMPTS {
                    self.events.push(Event::Refused(format!(
                        "no answer to {} commits of the gain set, {COMMIT_TIMEOUT_TICKS} ms \
                         apart (frames lost between supervisor and card?)",
                        self.attempts
                    )));
                    self.phase = Phase::Stopped;
                } else if due {
                    self.gain_set(tick, &mut out);
                } else if tick.is_multiple_of(50) {
                    out.push(Message::ControlWord(ControlWord::KeepAlive));
                }
            }
            Phase::Arming => {
                let cw = if self.arm_step == 0 {
                    ControlWord::Shutdown
                } else {
                    ControlWord::Enable(self.mode)
                };
                self.arm_step += 1;
                self.last_command = tick;
                out.push(Message::ControlWord(cw));
                if self.arm_step == 2 {
                    self.phase = Phase::Running;
                    self.started_at = Some(tick);
                    out.push(self.setpoint(0.0));
                }
            }
            Phase::Running => {
                let t0 = self.started_at.unwrap_or(tick);
                let k = tick.saturating_sub(t0);
                if self.stop_at.is_some_and(|s| k >= s) {
                    self.phase = Phase::Stopped;
                    out.push(Message::ControlWord(ControlWord::Disable));
                } else if self.recovering {
                    self.recover_step(tick, &mut out);
                    if !self.recovering {
                        out.push(self.setpoint(k as f64 * 1e-3));
                    }
                } else if k.is_multiple_of(self.period_ticks) {
                    out.push(self.setpoint(k as f64 * 1e-3));
                }
            }
            Phase::Stopped => {
                if tick.is_multiple_of(50) {
                    out.push(Message::ControlWord(ControlWord::KeepAlive));
                }
            }
        }
        out
    }

    /// Takes a message from the bus (only this joint's are used).
    pub fn on_message(&mut self, node: NodeId, m: &Message) {
        if node != self.node || self.silent_at(self.tick) {
            return;
        }
        let per_count = std::f64::consts::TAU / self.scale.motor_cpr();
        match m {
            Message::ParamResponse(r) => match (r.reply_to, r.status) {
                (ReplyTo::Commit, ParamStatus::Ok) if self.phase == Phase::Configuring => {
                    self.events.push(Event::Committed);
                    self.phase = Phase::Arming;
                }
                (_, ParamStatus::Ok) => {}
                // Writes lost on the way: send the set again (counted in the attempts).
                (
                    ReplyTo::Commit,
                    ParamStatus::SequenceMismatch
                    | ParamStatus::CountMismatch
                    | ParamStatus::ChecksumMismatch
                    | ParamStatus::NothingStaged,
                ) if self.phase == Phase::Configuring && self.attempts < COMMIT_ATTEMPTS => {
                    self.resend = true;
                }
                (to, st) => {
                    let name = p::lookup(r.param_id).map(|d| d.name).unwrap_or("-");
                    let lost = matches!(
                        st,
                        ParamStatus::SequenceMismatch
                            | ParamStatus::CountMismatch
                            | ParamStatus::ChecksumMismatch
                            | ParamStatus::NothingStaged
                    );
                    self.events
                        .push(Event::Refused(if to == ReplyTo::Commit && lost {
                            format!(
                            "commit refused {} time(s), last with {} (writes lost on the way to \
                             the card?)",
                            self.attempts,
                            st.name()
                        )
                        } else {
                            format!("{to:?} refused: {} (param `{name}`)", st.name())
                        }));
                    if to == ReplyTo::Commit {
                        self.phase = Phase::Stopped;
                    }
                }
            },
            Message::TelemetryMotion(t) => {
                self.telemetry.position = f64::from(t.position) * per_count;
                self.telemetry.velocity =
                    f64::from(scale::velocity_from_wire(t.velocity)) * per_count;
            }
            Message::TelemetryTorque(t) => {
                self.telemetry.torque_cmd = f64::from(t.torque_cmd) * MOTOR_TORQUE_NM_PER_LSB;
                self.telemetry.output_torque =
                    f64::from(t.output_torque) * OUTPUT_TORQUE_NM_PER_LSB;
                self.telemetry.limits = t.limits;
            }
            Message::Heartbeat(h) => {
                self.telemetry.state = Some(h.state);
                self.heartbeats += 1;
                let faulted = matches!(h.state, State::FaultReaction | State::Fault);
                let settled = self.tick.saturating_sub(self.last_command) >= RECOVERY_SETTLE_TICKS;
                if self.recover
                    && self.phase == Phase::Running
                    && settled
                    && !matches!(h.state, State::Enabled | State::QuickStop)
                {
                    // Not driving although it should (a fault, or an arming command lost).
                    self.recovering = true;
                } else if faulted && self.phase == Phase::Running && !self.recover {
                    // The card is in a fault whose frame this supervisor never heard.
                    let what = h.fault.map_or("?", |c| c.name());
                    self.events.push(Event::Fault(format!(
                        "the card's heartbeat reports {} ({what}); its fault frame was not heard",
                        h.state.name()
                    )));
                    self.phase = Phase::Stopped;
                }
            }
            Message::Fault(f) => {
                self.events
                    .push(Event::Fault(fault_words(f.code, f.detail)));
                if self.recover && matches!(self.phase, Phase::Running | Phase::Arming) {
                    self.phase = Phase::Running;
                    self.started_at.get_or_insert(self.tick);
                    self.recovering = true;
                } else {
                    self.phase = Phase::Stopped;
                }
            }
            _ => {}
        }
    }
}
