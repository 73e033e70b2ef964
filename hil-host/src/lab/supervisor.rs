//! The supervisor (the thesis's "topside" computer): configures the card, arms it, selects
//! the mode, streams setpoints at 20–400 Hz, keeps the watchdog fed, watches telemetry and
//! reports faults in words.
//!
//! Sans-IO like the card: [`Supervisor::on_tick`] is called once per control tick (the
//! supervisor counts `Sensor` frames on the bus, so in lockstep it runs on the same time base
//! as card and plant and a run is reproducible) and returns the messages to send;
//! [`Supervisor::on_message`] takes what the card says.

use controller::proto::params::{self as p};
use controller::proto::{
    ControlWord, FaultCode, LimitFlags, Message, Mode, NodeId, ParamCommit, ParamStatus,
    ParamWrite, ReplyTo, SetChecksum, SetpointForce, SetpointMotion, State,
};

use super::gains::JointScale;
use super::trajectory::Trajectory;

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
        }
    }

    /// Current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Stop sending anything (simulates a supervisor crash, for watchdog tests).
    pub fn go_silent(&mut self) {
        self.silent = true;
    }

    fn setpoint(&mut self, t: f64) -> Message {
        let v = self.trajectory.at(t);
        self.last_setpoint = v;
        match self.target {
            Target::Position => {
                let counts = (v * self.scale.motor_counts_per_output_rad()).round();
                Message::SetpointMotion(SetpointMotion {
                    position: counts as i64 as i32,
                    velocity_ff: 0,
                    torque_ff: 0,
                })
            }
            Target::Torque => Message::SetpointMotion(SetpointMotion {
                position: 0,
                velocity_ff: 0,
                torque_ff: (v / 1e-4).round().clamp(-32767.0, 32767.0) as i16,
            }),
            Target::Force => Message::SetpointForce(SetpointForce {
                output_torque: (v / 0.01).round().clamp(-32767.0, 32767.0) as i16,
            }),
        }
    }

    /// Messages to send at control tick `tick` (1 ms each).
    pub fn on_tick(&mut self, tick: u64) -> Vec<Message> {
        if self.silent {
            return vec![];
        }
        let mut out = vec![];
        match self.phase {
            Phase::Configuring => {
                if tick == 1 || (self.set_seq == 0) {
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
        if node != self.node {
            return;
        }
        let per_count = std::f64::consts::TAU / self.scale.motor_cpr;
        match m {
            Message::ParamResponse(r) => match (r.reply_to, r.status) {
                (ReplyTo::Commit, ParamStatus::Ok) if self.phase == Phase::Configuring => {
                    self.events.push(Event::Committed);
                    self.phase = Phase::Arming;
                }
                (_, ParamStatus::Ok) => {}
                (to, st) => {
                    let name = p::lookup(r.param_id).map(|d| d.name).unwrap_or("-");
                    self.events.push(Event::Refused(format!(
                        "{to:?} refused: {} (param `{name}`)",
                        st.name()
                    )));
                    if to == ReplyTo::Commit {
                        self.phase = Phase::Stopped;
                    }
                }
            },
            Message::TelemetryMotion(t) => {
                self.telemetry.position = f64::from(t.position) * per_count;
                self.telemetry.velocity = f64::from(t.velocity) * 8.0 * per_count;
            }
            Message::TelemetryTorque(t) => {
                self.telemetry.torque_cmd = f64::from(t.torque_cmd) * 1e-4;
                self.telemetry.output_torque = f64::from(t.output_torque) * 0.01;
                self.telemetry.limits = t.limits;
            }
            Message::Heartbeat(h) => self.telemetry.state = Some(h.state),
            Message::Fault(f) => {
                self.events
                    .push(Event::Fault(fault_words(f.code, f.detail)));
                self.phase = Phase::Stopped;
            }
            _ => {}
        }
    }
}
