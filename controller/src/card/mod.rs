//! The card runtime: what turns the control laws into a motor card.
//!
//! Sans-IO (design.md): [`Card::step`] takes the time and the sensor values of one tick and
//! returns the actuator command; [`Card::handle_frame`] takes a received frame;
//! [`Card::poll`] checks the timeouts when nothing arrives; [`Card::poll_transmit`] hands
//! out the frames the card wants to send (fault, telemetry, heartbeat, parameter replies).
//! It never reads a clock or a bus, so the same code runs in an MCU's CAN ISR, in the HIL
//! lab's card thread, and in unit tests with a simulated clock.
//!
//! ```text
//!  frame ─► proto::Message::decode ─► handle_message ─┬─ ControlWord ─► state machine
//!                                                     ├─ Setpoint*   ─► latched setpoint
//!                                                     ├─ ParamWrite  ─► Staging (checked)
//!                                                     ├─ ParamCommit ─► build CardConfig ─► pending
//!                                                     └─ Sensor      ─► step():
//!      apply pending (cycle boundary, bumpless) ─► unwrap + observer ─► checks (seq, sensors,
//!      watchdog, limits) ─► law (mode/state) ─► torque limit (always last) ─► Actuator
//! ```
//!
//! A firmware whose control loop runs in an interrupt switches on deferred builds
//! ([`Card::set_deferred_builds`]): the f64 configuration build of a commit or an `Enable`
//! is handed out as a [`BuildRequest`] to run outside the interrupt, and its result is
//! swapped in at a cycle boundary as above. [`node`] is the card as a bus node (its clock
//! rule and transmit order), shared by every host of the card.
//!
//! State machine (CiA-402 shaped, see `proto::state::State`): `Disabled –Shutdown→ Ready
//! –Enable(mode)→ Enabled(mode) –QuickStop→ QuickStop → Disabled`; any fault while driving →
//! `FaultReaction` (configured reaction) → `Fault`, latched until `ClearFault`.

pub mod config;
pub mod node;
pub mod si;
pub mod store;

use embedded_can::Frame;

use crate::fixed_math::{clamp_sym, Counts, Flags, Torque, Vel};
use crate::laws::{FrictionComp, JointState, Measurements, PositionLaw, Setpoint};
use crate::proto::params::{self as p, WatchdogReaction};
use crate::proto::{
    self, Actuator, ControlWord, Fault, FaultCode, Heartbeat, LimitFlags, Message, Mode, NodeId,
    ParamCommit, ParamResponse, ParamStatus, RejectCounters, ReplyTo, State, TelemetryMotion,
    TelemetryTorque,
};
use crate::sensing::{TrackingObserver, Unwrapper};

pub use config::{CardConfig, ConfigError};
pub use store::ParamStore;

/// The card's staging area (the protocol's commit rules, `proto::staging`).
pub type Staging = crate::proto::staging::Staging<{ p::STAGING_CAPACITY }>;

/// Frames the card can queue between two `poll_transmit` drains. A tick queues at most a
/// fault, a telemetry frame and a heartbeat; parameter replies come one per received frame.
pub const OUTBOX_CAPACITY: usize = 16;

/// One tick's sensor values, as carried by the `Sensor` (and `OutputEncoder`) frames or read
/// by an MCU's sensor ISR.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sensors {
    /// Free-running motor encoder count (wraps mod 2³²).
    pub motor_counts: u32,
    /// Output torque sensor, 0.01 N·m, if valid this tick.
    pub output_torque: Option<i16>,
    /// Output encoder count, if the joint has one and it was read this tick.
    pub output_counts: Option<u32>,
    /// Tick sequence number (increments by one per tick, wraps).
    pub seq: u8,
    /// The encoder reported an error.
    pub encoder_error: bool,
}

/// How a running fault reaction drives the motor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum Reaction {
    /// Hold the position where the fault happened (PD with the active Ke/Be), latched.
    Hold,
    /// Torque zero at once.
    ZeroTorque,
    /// Quick-stop damping to standstill.
    Damp,
}

/// A commit or a mode switch waiting for the next cycle boundary.
#[derive(Clone, Debug)]
struct Pending {
    store: Option<ParamStore>,
    config: CardConfig,
}

/// The motor card. See the module docs.
#[derive(Debug)]
pub struct Card {
    node: NodeId,
    state: State,
    mode: Option<Mode>,
    fault: Option<(FaultCode, i32)>,
    reaction: Reaction,
    store: ParamStore,
    staging: Staging,
    pending: Option<Pending>,
    cfg: CardConfig,
    joint: JointState,
    ref_friction: FrictionComp,
    motor: Unwrapper,
    observer: TrackingObserver,
    output: Unwrapper,
    output_observer: TrackingObserver,
    /// `OutputEncoder` frame of the current tick (seq, counts), waiting for its `Sensor`.
    output_frame: Option<(u8, u32)>,
    x_d: i32,
    velocity_ff: i16,
    torque_ff: i16,
    tau_d_out: i16,
    last_cmd: Torque,
    last_meas: Measurements,
    last_seq: Option<u8>,
    last_sensor_us: Option<u64>,
    last_supervisor_us: Option<u64>,
    last_heartbeat_us: Option<u64>,
    telemetry_tick: u16,
    telemetry_torque_next: bool,
    limits: LimitFlags,
    counters: RejectCounters,
    outbox: heapless::Deque<Message, OUTBOX_CAPACITY>,
    commits: u32,
    /// Position-hold reaction: where, and its law state.
    hold_at: Counts,
    hold: PositionLaw,
    /// Deferred builds: see [`Card::set_deferred_builds`].
    deferred: bool,
    /// The build waiting to be taken by the caller.
    request: Option<BuildRequest>,
    /// A build was requested and not yet finished.
    outstanding: bool,
    /// Supervisor messages that arrived while a build was outstanding, in arrival order.
    held: heapless::Deque<(u64, NodeId, Message), HELD_CAPACITY>,
    /// Faults entered since boot (a build started before a fault is stale).
    fault_count: u32,
    /// Degraded-bus reports since boot ([`Card::bus_warning`]), saturating.
    bus_warnings: u32,
    /// Own `Sensor` frames missing from the sequence since boot, saturating.
    sensor_frames_lost: u32,
}

/// Supervisor messages a card in deferred-build mode keeps while a build runs.
pub const HELD_CAPACITY: usize = 8;

/// What a deferred build is for.
#[derive(Clone, Copy, Debug)]
enum BuildFor {
    /// A commit whose writes passed every check; the response waits for the build.
    Commit(ParamResponse),
    /// `Shutdown` (Disabled → Ready) checks that the parameters build.
    Shutdown,
    /// `Enable(mode)`.
    Enable(Mode),
}

/// A configuration build the card hands out instead of running it inside a frame handler
/// (deferred mode, [`Card::set_deferred_builds`]): `config::build` does f64 arithmetic,
/// soft-float on a Cortex-M, and takes longer than a control period, so a firmware runs it
/// outside the control interrupt and hands the result back with [`Card::finish_build`].
#[derive(Clone, Debug)]
pub struct BuildRequest {
    store: ParamStore,
    mode: Option<Mode>,
    what: BuildFor,
    fault_count: u32,
}

impl BuildRequest {
    /// Runs the build. Pure: touches nothing but the request.
    pub fn build(&self) -> Result<CardConfig, ConfigError> {
        config::build(&self.store, self.mode)
    }
}

/// Law flags → wire limit flags.
fn limit_flags(f: Flags) -> LimitFlags {
    let mut l = LimitFlags::NONE;
    l.set(LimitFlags::TORQUE, f.contains(Flags::OUTPUT_SATURATED));
    l.set(
        LimitFlags::INTEGRATOR,
        f.contains(Flags::INTEGRATOR_LIMITED),
    );
    l.set(
        LimitFlags::OVERFLOW,
        f.contains(Flags::OVERFLOW) || f.contains(Flags::INPUT_CLAMPED),
    );
    l
}

/// Velocity in law units (1/16 count/s) → wire units (8 counts/s per LSB), saturated.
fn velocity_to_wire(v: Vel) -> (i16, bool) {
    let w = v.to_bits().wrapping_shr(7); // /16 /8 = /128
    match i16::try_from(w) {
        Ok(x) => (x, false),
        Err(_) => (if w < 0 { i16::MIN } else { i16::MAX }, true),
    }
}

impl Card {
    /// A card for `node` with every parameter at its default, `Disabled`. Fails only if the
    /// parameter table's defaults do not build a configuration (a table bug; tested).
    pub fn new(node: NodeId) -> Result<Card, ConfigError> {
        let mut store = ParamStore::new();
        store.set_unchecked(p::NODE_ID, i32::from(node.get()));
        let cfg = config::build(&store, None)?;
        Ok(Card {
            node,
            state: State::Disabled,
            mode: None,
            fault: None,
            reaction: Reaction::ZeroTorque,
            store,
            staging: Staging::new(),
            pending: None,
            cfg,
            joint: JointState::new(),
            ref_friction: FrictionComp::NEW,
            motor: Unwrapper::new(),
            observer: TrackingObserver::new(),
            output: Unwrapper::new(),
            output_observer: TrackingObserver::new(),
            output_frame: None,
            x_d: 0,
            velocity_ff: 0,
            torque_ff: 0,
            tau_d_out: 0,
            last_cmd: 0,
            last_meas: Measurements::default(),
            last_seq: None,
            last_sensor_us: None,
            last_supervisor_us: None,
            last_heartbeat_us: None,
            telemetry_tick: 0,
            telemetry_torque_next: false,
            limits: LimitFlags::NONE,
            counters: RejectCounters::new(),
            outbox: heapless::Deque::new(),
            commits: 0,
            hold_at: 0,
            hold: PositionLaw::default(),
            deferred: false,
            request: None,
            outstanding: false,
            held: heapless::Deque::new(),
            fault_count: 0,
            bus_warnings: 0,
            sensor_frames_lost: 0,
        })
    }

    // ---------------------------------------------------------------- accessors

    /// This card's node number.
    pub fn node(&self) -> NodeId {
        self.node
    }
    /// Current state.
    pub fn state(&self) -> State {
        self.state
    }
    /// Selected mode (while `Enabled`, the running one).
    pub fn mode(&self) -> Option<Mode> {
        self.mode
    }
    /// Latched fault and its detail.
    pub fn fault(&self) -> Option<(FaultCode, i32)> {
        self.fault
    }
    /// Rejected-frame counters.
    pub fn counters(&self) -> &RejectCounters {
        &self.counters
    }
    /// Active parameters.
    pub fn params(&self) -> &ParamStore {
        &self.store
    }
    /// Active derived configuration.
    pub fn config(&self) -> &CardConfig {
        &self.cfg
    }
    /// Last measurements the laws saw (unwrapped positions, velocity estimates).
    pub fn measurements(&self) -> &Measurements {
        &self.last_meas
    }
    /// Limit flags of the last tick.
    pub fn limits(&self) -> LimitFlags {
        self.limits
    }
    /// Degraded-bus reports since boot (see [`Card::bus_warning`]), saturating.
    pub fn bus_warnings(&self) -> u32 {
        self.bus_warnings
    }
    /// Own `Sensor` frames that never arrived (gaps in their sequence numbers) since boot,
    /// saturating. Single gaps within `max_seq_skip` do not fault the card; this count is
    /// how a host still sees them.
    pub fn sensor_frames_lost(&self) -> u32 {
        self.sensor_frames_lost
    }

    fn driving(&self) -> bool {
        matches!(
            self.state,
            State::Enabled | State::QuickStop | State::FaultReaction
        )
    }

    // ---------------------------------------------------------------- frames in

    /// Handles one received frame. Returns the actuator command when the frame was this
    /// card's `Sensor` frame (the tick). Malformed frames are counted, never acted upon.
    pub fn handle_frame<F: Frame>(&mut self, now_us: u64, frame: &F) -> Option<Actuator> {
        match Message::decode(frame) {
            Ok((node, msg)) => self.handle_message(now_us, node, msg),
            Err(e) => {
                self.counters.record(&e);
                None
            }
        }
    }

    /// Handles one decoded message addressed to `node`.
    pub fn handle_message(&mut self, now_us: u64, node: NodeId, msg: Message) -> Option<Actuator> {
        if node != self.node && !node.is_broadcast() {
            return None; // another joint's traffic
        }
        if self.outstanding
            && matches!(
                msg,
                Message::ControlWord(_)
                    | Message::ParamWrite(_)
                    | Message::ParamCommit(_)
                    | Message::ParamRead(_)
            )
        {
            // Order matters (a Disable after an Enable, writes after a commit): everything
            // of the supervisor's but setpoints waits until the build is finished.
            self.feed_watchdog(now_us);
            if self.held.push_back((now_us, node, msg)).is_err() {
                self.counters.record_refused();
            }
            return None;
        }
        match msg {
            Message::Sensor(s) => {
                let output_counts = match self.output_frame.take() {
                    Some((seq, c)) if seq == s.seq && s.output_encoder => Some(c),
                    _ => None,
                };
                if s.output_encoder && output_counts.is_none() && self.driving() {
                    let detail = i32::from(s.seq);
                    self.enter_fault(FaultCode::SequenceError, detail);
                }
                let sensors = Sensors {
                    motor_counts: s.motor_counts,
                    output_torque: s.output_torque,
                    output_counts,
                    seq: s.seq,
                    encoder_error: s.encoder_error,
                };
                return Some(self.step(now_us, &sensors));
            }
            Message::OutputEncoder(o) => self.output_frame = Some((o.seq, o.output_counts)),
            Message::SetpointMotion(sp) => {
                self.feed_watchdog(now_us);
                self.x_d = sp.position;
                self.velocity_ff = sp.velocity_ff;
                self.torque_ff = sp.torque_ff;
            }
            Message::SetpointForce(sp) => {
                self.feed_watchdog(now_us);
                self.tau_d_out = sp.output_torque;
            }
            Message::ControlWord(cw) => {
                self.feed_watchdog(now_us);
                self.control(cw);
            }
            Message::ParamWrite(w) => {
                self.feed_watchdog(now_us);
                let status = self.staging.write(&w, self.driving());
                self.reply(ReplyTo::Write, status, w.set_seq, w.param_id, w.value);
            }
            Message::ParamCommit(c) => {
                self.feed_watchdog(now_us);
                if let Some(resp) = self.commit(&c) {
                    self.answer_commit(resp);
                }
            }
            Message::ParamRead(r) => {
                self.feed_watchdog(now_us);
                let (status, value) = match self.store.get(r.param_id) {
                    Ok(v) => (Ok(()), v),
                    Err(e) => (Err(e), 0),
                };
                self.reply(ReplyTo::Read, status, 0, r.param_id, value);
            }
            // Frames the card itself sends (or another card's, with our node number): not
            // for us to act upon.
            Message::Actuator(_)
            | Message::TelemetryMotion(_)
            | Message::TelemetryTorque(_)
            | Message::ParamResponse(_)
            | Message::Heartbeat(_)
            | Message::Fault(_) => {}
        }
        None
    }

    fn feed_watchdog(&mut self, now_us: u64) {
        self.last_supervisor_us = Some(now_us);
    }

    fn reply(
        &mut self,
        to: ReplyTo,
        status: Result<(), ParamStatus>,
        seq: u8,
        id: u16,
        value: i32,
    ) {
        let status = match status {
            Ok(()) => ParamStatus::Ok,
            Err(s) => {
                self.counters.record_refused();
                s
            }
        };
        self.push(Message::ParamResponse(ParamResponse {
            reply_to: to,
            status,
            set_seq: seq,
            param_id: id,
            value,
        }));
    }

    fn push(&mut self, m: Message) {
        if self.outbox.push_back(m).is_err() {
            // Full: drop the oldest non-fault frame so the newest state gets out.
            let _ = self.outbox.pop_front();
            let _ = self.outbox.push_back(m);
        }
    }

    /// Validates a commit against the staged set (`proto::staging` rules), re-checks access
    /// in the current state, and builds the configuration; the result is applied at the next
    /// cycle boundary. Nothing changes unless every check passes. In deferred mode a commit
    /// whose writes pass is handed out as a [`BuildRequest`] and answered when it finishes
    /// (`None` here).
    fn commit(&mut self, c: &ParamCommit) -> Option<ParamResponse> {
        let driving = self.driving();
        let base = self.pending_store().clone();
        let mode = if self.state == State::Enabled {
            self.mode
        } else {
            None
        };
        let mut checked = None;
        let resp = self.staging.commit(c, |entries| {
            for &(id, v) in entries {
                store::check_write(id, v, driving).map_err(|s| (s, id))?;
            }
            let mut next = base;
            next.apply(entries);
            next.set_unchecked(p::LAST_SET_SEQ, i32::from(c.set_seq));
            checked = Some(next);
            Ok(())
        });
        let Some(next) = checked.filter(|_| resp.status == ParamStatus::Ok) else {
            return Some(resp);
        };
        if self.deferred {
            self.request(next, mode, BuildFor::Commit(resp));
            return None;
        }
        let result = config::build(&next, mode);
        Some(self.commit_built(resp, next, result))
    }

    /// The second half of a commit: the build's result decides.
    fn commit_built(
        &mut self,
        mut resp: ParamResponse,
        next: ParamStore,
        result: Result<CardConfig, ConfigError>,
    ) -> ParamResponse {
        match result {
            Ok(config) => {
                self.pending = Some(Pending {
                    store: Some(next),
                    config,
                });
            }
            Err(e) => {
                resp.status = ParamStatus::InconsistentSet;
                resp.param_id = e.param();
            }
        }
        resp
    }

    fn answer_commit(&mut self, resp: ParamResponse) {
        if resp.status != ParamStatus::Ok {
            self.counters.record_refused();
        }
        self.push(Message::ParamResponse(resp));
    }

    fn request(&mut self, store: ParamStore, mode: Option<Mode>, what: BuildFor) {
        self.request = Some(BuildRequest {
            store,
            mode,
            what,
            fault_count: self.fault_count,
        });
        self.outstanding = true;
    }

    // ---------------------------------------------------------------- deferred builds

    /// Deferred builds (off by default): commits, `Shutdown` and `Enable` no longer build
    /// their configuration inside [`Card::handle_frame`]; they leave a [`BuildRequest`] for
    /// [`Card::take_build_request`], and the card goes on stepping with its active
    /// configuration until [`Card::finish_build`] swaps the result in — still at a cycle
    /// boundary, as a synchronous commit would. Supervisor messages (but setpoints) that
    /// arrive meanwhile wait, in order, and run after it. The frames the card sends are those
    /// of the synchronous card, only later.
    pub fn set_deferred_builds(&mut self, on: bool) {
        self.deferred = on;
    }

    /// True while a build request waits to be taken.
    pub fn build_requested(&self) -> bool {
        self.request.is_some()
    }

    /// The build waiting to run, if any (take it, run [`BuildRequest::build`] outside the
    /// control interrupt, then call [`Card::finish_build`]).
    pub fn take_build_request(&mut self) -> Option<BuildRequest> {
        self.request.take()
    }

    /// Hands back a finished build. If a fault came in between, the build is stale: a commit
    /// is answered `NotAllowedInState`, a `Shutdown`/`Enable` is refused. Then the messages
    /// that waited behind it run.
    pub fn finish_build(&mut self, req: BuildRequest, result: Result<CardConfig, ConfigError>) {
        self.outstanding = false;
        let stale = req.fault_count != self.fault_count;
        match req.what {
            BuildFor::Commit(mut resp) => {
                let resp = if stale {
                    resp.status = ParamStatus::NotAllowedInState;
                    resp
                } else {
                    self.commit_built(resp, req.store, result)
                };
                self.answer_commit(resp);
            }
            BuildFor::Shutdown if !stale && self.state == State::Disabled => {
                self.shutdown_built(result);
            }
            BuildFor::Enable(mode)
                if !stale && matches!(self.state, State::Ready | State::Enabled) =>
            {
                self.enable_built(mode, result);
            }
            BuildFor::Shutdown | BuildFor::Enable(_) => self.counters.record_refused(),
        }
        while !self.outstanding {
            let Some((t, node, m)) = self.held.pop_front() else {
                break;
            };
            self.handle_message(t, node, m);
        }
    }

    fn control(&mut self, cw: ControlWord) {
        let ok = match (cw, self.state) {
            (ControlWord::KeepAlive, _) => true,
            (ControlWord::Shutdown, State::Disabled) => {
                let store = self.pending_store().clone();
                if self.deferred {
                    self.request(store, None, BuildFor::Shutdown);
                } else {
                    self.shutdown_built(config::build(&store, None));
                }
                true
            }
            (ControlWord::Enable(mode), State::Ready | State::Enabled) => {
                let store = self.pending_store().clone();
                if self.deferred {
                    self.request(store, Some(mode), BuildFor::Enable(mode));
                } else {
                    self.enable_built(mode, config::build(&store, Some(mode)));
                }
                true
            }
            (ControlWord::Disable, s) if !matches!(s, State::FaultReaction | State::Fault) => {
                self.state = State::Disabled;
                self.joint.reset();
                true
            }
            (ControlWord::QuickStop, State::Enabled) => {
                self.state = State::QuickStop;
                true
            }
            (ControlWord::ClearFault, State::FaultReaction) if self.reaction == Reaction::Hold => {
                self.state = State::Disabled;
                self.fault = None;
                self.joint.reset();
                true
            }
            (ControlWord::ClearFault, State::Fault) => {
                self.state = State::Disabled;
                self.fault = None;
                self.joint.reset();
                true
            }
            _ => false,
        };
        if !ok {
            self.counters.record_refused();
        }
    }

    fn shutdown_built(&mut self, result: Result<CardConfig, ConfigError>) {
        match result {
            Ok(_) => self.state = State::Ready,
            Err(e) => self.enter_fault(FaultCode::ConfigRejected, i32::from(e.param())),
        }
    }

    fn enable_built(&mut self, mode: Mode, result: Result<CardConfig, ConfigError>) {
        match result {
            Ok(config) => {
                self.pending = Some(Pending {
                    store: self.pending.take().and_then(|p| p.store),
                    config,
                });
                if self.state == State::Ready {
                    // Aim where we are: no jump on arming.
                    self.x_d = self.current_position_i32(mode);
                    self.velocity_ff = 0;
                    self.torque_ff = 0;
                }
                self.state = State::Enabled;
                self.mode = Some(mode);
            }
            Err(e) => self.enter_fault(FaultCode::ConfigRejected, i32::from(e.param())),
        }
    }

    fn pending_store(&self) -> &ParamStore {
        match &self.pending {
            Some(Pending { store: Some(s), .. }) => s,
            _ => &self.store,
        }
    }

    fn current_position_i32(&self, mode: Mode) -> i32 {
        let x = if mode.needs_output_encoder() {
            self.last_meas.x2
        } else {
            self.last_meas.x1
        };
        // Truncation to the wire's i32 count space is the documented wrap.
        x as i32
    }

    /// Enters `FaultReaction` (first fault wins; later ones are not latched over it) and
    /// queues the `Fault` frame.
    fn enter_fault(&mut self, code: FaultCode, detail: i32) {
        if matches!(self.state, State::FaultReaction | State::Fault) {
            return;
        }
        let was_driving = self.driving();
        self.fault_count = self.fault_count.wrapping_add(1);
        self.fault = Some((code, detail));
        self.reaction = match code {
            FaultCode::SupervisorWatchdog => match self.cfg.watchdog_reaction {
                WatchdogReaction::ZeroTorque => Reaction::ZeroTorque,
                WatchdogReaction::QuickStop => Reaction::Damp,
                WatchdogReaction::HoldPosition => Reaction::Hold,
            },
            FaultCode::PositionLimit
            | FaultCode::VelocityLimit
            | FaultCode::OutputTorqueLimit
            | FaultCode::Overflow => Reaction::Damp,
            _ => Reaction::ZeroTorque,
        };
        self.hold_at = self.last_meas.x1;
        self.hold = PositionLaw::default();
        self.state = if was_driving && self.reaction != Reaction::ZeroTorque {
            State::FaultReaction
        } else {
            State::Fault
        };
        self.pending = None;
        // The fault frame goes first: it is the most urgent thing the card has to say.
        let f = Message::Fault(Fault {
            code,
            limits: self.limits,
            detail,
        });
        if self.outbox.push_front(f).is_err() {
            let _ = self.outbox.pop_back();
            let _ = self.outbox.push_front(f);
        }
    }

    /// Reports that the card's own bus failed (bus-off, error-passive): the card goes to
    /// its safe state, as it would on any other fault.
    pub fn bus_error(&mut self, code: i32) {
        self.enter_fault(FaultCode::BusError, code);
    }

    /// Reports a degraded bus that still carries frames (error-warning level, a protocol
    /// error, a missing ACK, a receive overflow): counted, nothing else. CAN retransmits
    /// what failed; what was lost for good shows up where it matters — a sequence gap, a
    /// silent supervisor, a commit whose checksum no longer matches — and those checks
    /// fault the card on their own terms.
    pub fn bus_warning(&mut self) {
        self.bus_warnings = self.bus_warnings.saturating_add(1);
    }

    /// Reports that the power stage (amplifier) signalled a fault — its fault output, an
    /// over-current, a failed write: the card goes to its safe state and latches it.
    pub fn power_stage_fault(&mut self, status: i32) {
        self.enter_fault(FaultCode::PowerStage, status);
    }

    // ---------------------------------------------------------------- time

    /// Checks the timeouts when no sensor frame arrived: the sensor timeout while driving,
    /// and the heartbeat. Call it whenever the bus is idle (or from a timer on an MCU).
    pub fn poll(&mut self, now_us: u64) {
        if self.driving() {
            if let Some(t) = self.last_sensor_us {
                let since = now_us.saturating_sub(t);
                if since > self.cfg.sensor_timeout_us {
                    let detail = i32::try_from(since).unwrap_or(i32::MAX);
                    // No sensors: no damping possible, torque off.
                    self.reaction = Reaction::ZeroTorque;
                    self.enter_fault(FaultCode::SensorTimeout, detail);
                    self.state = State::Fault;
                }
            }
            self.check_watchdog(now_us);
        }
        self.heartbeat(now_us);
    }

    fn check_watchdog(&mut self, now_us: u64) {
        if !matches!(self.state, State::Enabled | State::QuickStop) {
            return;
        }
        let last = self.last_supervisor_us.unwrap_or(now_us);
        let since = now_us.saturating_sub(last);
        if since > self.cfg.supervisor_timeout_us {
            let ms = i32::try_from(since / 1000).unwrap_or(i32::MAX);
            self.enter_fault(FaultCode::SupervisorWatchdog, ms);
        }
    }

    fn heartbeat(&mut self, now_us: u64) {
        let due = match self.last_heartbeat_us {
            None => true,
            Some(t) => now_us.saturating_sub(t) >= self.cfg.heartbeat_period_us,
        };
        if due {
            self.last_heartbeat_us = Some(now_us);
            let hb = self.heartbeat_message();
            self.push(hb);
        }
    }

    /// The heartbeat this card would send now.
    pub fn heartbeat_message(&self) -> Message {
        Message::Heartbeat(Heartbeat {
            state: self.state,
            mode: self.mode,
            fault: self.fault.map(|(c, _)| c),
            limits: self.limits,
            rejected_malformed: self.counters.malformed_total(),
            rejected_refused: self.counters.refused_u8(),
            protocol_version: proto::PROTOCOL_VERSION,
        })
    }

    /// Next frame the card wants to send (faults first), if any.
    pub fn poll_transmit(&mut self) -> Option<Message> {
        self.outbox.pop_front()
    }

    // ---------------------------------------------------------------- the tick

    fn apply_pending(&mut self) {
        let Some(pend) = self.pending.take() else {
            return;
        };
        if let Some(s) = pend.store {
            self.store = s;
            self.commits = self.commits.saturating_add(1);
            self.store.set_unchecked(
                p::COMMIT_COUNT,
                i32::try_from(self.commits).unwrap_or(i32::MAX),
            );
        }
        self.cfg = pend.config;
        if self.state == State::Enabled {
            // Bumpless: the first output with the new laws equals the last one commanded.
            let sp = self.setpoint();
            self.joint
                .init_bumpless(&self.cfg.joint, self.last_cmd, &sp, &self.last_meas);
        }
    }

    fn setpoint(&self) -> Setpoint {
        let here = if self.mode.is_some_and(|m| m.needs_output_encoder()) {
            self.last_meas.x2
        } else {
            self.last_meas.x1
        };
        // Nearest multi-turn position whose low 32 bits are the setpoint (wire wrap).
        let delta = i64::from(self.x_d.wrapping_sub(here as i32));
        Setpoint {
            x_d: here.saturating_add(delta),
            tau_d: i32::from(self.tau_d_out)
                .saturating_mul(crate::proto::scale::OUTPUT_TORQUE_IN_MOTOR_LSB),
            v_d: self.velocity_setpoint(),
        }
    }

    /// The setpoint's velocity_ff (8 counts/s per LSB) as a Q28.4 counts/s velocity.
    fn velocity_setpoint(&self) -> Vel {
        Vel::from_bits(i32::from(self.velocity_ff).saturating_mul(128))
    }

    /// One control period: the `Sensor` frame of tick `seq` arrived at `now_us`.
    pub fn step(&mut self, now_us: u64, s: &Sensors) -> Actuator {
        self.last_sensor_us = Some(now_us);
        // Sequence: lost frames in a row beyond the tolerance are a fault.
        if let Some(last) = self.last_seq {
            let lost = s.seq.wrapping_sub(last).wrapping_sub(1);
            if lost != u8::MAX {
                self.sensor_frames_lost = self.sensor_frames_lost.saturating_add(u32::from(lost));
            }
            if lost > self.cfg.max_seq_skip && lost != u8::MAX && self.driving() {
                let detail = i32::from(u16::from(last.wrapping_add(1)) << 8 | u16::from(s.seq));
                self.enter_fault(FaultCode::SequenceError, detail);
            }
        }
        self.last_seq = Some(s.seq);

        // Sensing (always, so positions are current when the card is armed).
        let x1: Counts = self.motor.update(s.motor_counts);
        let (v1, mut flags) = self.observer.step(&self.cfg.observer, x1);
        let (x2, v2) = match s.output_counts {
            Some(c) => {
                let x2 = self.output.update(c);
                let (v2, f2) = self.output_observer.step(&self.cfg.output_observer, x2);
                flags |= f2;
                (x2, v2)
            }
            None => (self.last_meas.x2, Vel::ZERO),
        };
        let tau_env = s
            .output_torque
            .map(|t| i32::from(t).saturating_mul(crate::proto::scale::OUTPUT_TORQUE_IN_MOTOR_LSB))
            .unwrap_or(0);
        self.last_meas = Measurements {
            x1,
            v1,
            x2,
            v2,
            tau_env,
        };

        // Cycle boundary: a commit or mode switch takes effect now, bumplessly.
        self.apply_pending();

        // Checks that only matter while the card drives the motor.
        let mut limits = LimitFlags::NONE;
        if self.driving() {
            if s.encoder_error {
                self.enter_fault(FaultCode::SensorInvalid, i32::from(s.seq));
            }
            if let Some(m) = self.mode {
                let missing_torque = m.needs_torque_sensor() && s.output_torque.is_none();
                let missing_output = m.needs_output_encoder() && s.output_counts.is_none();
                if self.state == State::Enabled && (missing_torque || missing_output) {
                    self.enter_fault(FaultCode::SensorInvalid, i32::from(s.seq));
                }
            }
            self.check_watchdog(now_us);
            let v = i64::from(v1.to_bits());
            if v.saturating_abs() > self.cfg.velocity_limit {
                limits.insert(LimitFlags::VELOCITY);
                self.enter_fault(FaultCode::VelocityLimit, (v / 16) as i32);
            }
            if let Some((lo, hi)) = self.cfg.position_limits {
                if x1 < lo || x1 > hi {
                    limits.insert(LimitFlags::POSITION);
                    self.enter_fault(FaultCode::PositionLimit, x1 as i32);
                }
            }
            if let Some(t) = s.output_torque {
                if i32::from(t).saturating_abs() > self.cfg.output_torque_limit {
                    self.enter_fault(FaultCode::OutputTorqueLimit, i32::from(t));
                }
            }
        }

        // The law for this state.
        let raw: i64 = match self.state {
            State::Enabled => {
                let mut sp = self.setpoint();
                if let Some((lo, hi)) = self.cfg.position_limits {
                    if !self.mode.is_some_and(|m| m.needs_output_encoder()) {
                        let c = sp.x_d.clamp(lo, hi);
                        if c != sp.x_d {
                            limits.insert(LimitFlags::POSITION);
                            sp.x_d = c;
                        }
                    }
                }
                let out = self.joint.step(&self.cfg.joint, &sp, &self.last_meas);
                flags |= out.out.flags;
                let vff = self.velocity_setpoint();
                // The modes that follow a motion setpoint take its torque feed-forward and
                // the friction law on its velocity; the position-type ones also take the
                // velocity through their damping gain (the velocity law has it in its error).
                let follows = matches!(
                    self.mode,
                    Some(
                        Mode::PositionPdColocated
                            | Mode::PositionPdNonColocated
                            | Mode::PositionPid
                            | Mode::ImpedanceColocated
                            | Mode::ImpedanceNonColocated
                            | Mode::Velocity
                    )
                );
                let ff = match self.mode {
                    Some(Mode::TorquePassthrough) => i64::from(self.torque_ff),
                    _ if follows => {
                        let friction = match &self.cfg.joint.friction {
                            Some(f) if self.cfg.joint.friction_on_setpoint => {
                                let o = self.ref_friction.step(f, vff);
                                flags |= o.flags;
                                i64::from(o.tau)
                            }
                            _ => 0,
                        };
                        let damping_ff = if self.mode == Some(Mode::Velocity) {
                            0
                        } else {
                            self.cfg.velocity_ff_gain.apply(vff.to_bits())
                        };
                        i64::from(self.torque_ff)
                            .saturating_add(damping_ff)
                            .saturating_add(friction)
                    }
                    _ => 0,
                };
                i64::from(out.out.tau).saturating_add(ff)
            }
            State::FaultReaction if self.reaction == Reaction::Hold => {
                let out = self.hold.step(&self.cfg.hold, self.hold_at, x1, v1);
                flags |= out.flags;
                i64::from(out.tau)
            }
            State::QuickStop | State::FaultReaction => {
                let damp = self
                    .cfg
                    .quick_stop_damping
                    .apply(v1.to_bits())
                    .saturating_neg();
                let still =
                    i64::from(v1.to_bits()).saturating_abs() <= self.cfg.standstill_velocity;
                let zero =
                    self.state == State::FaultReaction && self.reaction == Reaction::ZeroTorque;
                if still || zero {
                    self.state = if self.state == State::QuickStop {
                        State::Disabled
                    } else {
                        State::Fault
                    };
                    self.joint.reset();
                    0
                } else {
                    damp
                }
            }
            State::Disabled | State::Ready | State::Fault => 0,
        };

        // The torque limit is always the last thing applied.
        let (tau, clamped) = clamp_sym(raw, self.cfg.torque_limit);
        if clamped {
            flags |= Flags::OUTPUT_SATURATED;
        }
        let drive = self.driving();
        let torque = if drive {
            i16::try_from(tau).unwrap_or(0)
        } else {
            0
        };
        self.last_cmd = Torque::from(torque);
        let mut l = limit_flags(flags);
        l.insert(limits);
        self.limits = l;

        self.telemetry(s.seq);
        self.heartbeat(now_us);

        Actuator {
            torque,
            seq: s.seq,
            limits: self.limits,
            drive,
            fault: matches!(self.state, State::FaultReaction | State::Fault),
        }
    }

    fn telemetry(&mut self, seq: u8) {
        let div = self.cfg.telemetry_divider;
        if div == 0 {
            return;
        }
        self.telemetry_tick = self.telemetry_tick.saturating_add(1);
        if self.telemetry_tick < div {
            return;
        }
        self.telemetry_tick = 0;
        let m = if self.telemetry_torque_next {
            Message::TelemetryTorque(TelemetryTorque {
                torque_cmd: i16::try_from(self.last_cmd).unwrap_or(0),
                output_torque: i16::try_from(
                    self.last_meas.tau_env / crate::proto::scale::OUTPUT_TORQUE_IN_MOTOR_LSB,
                )
                .unwrap_or(0),
                seq,
                limits: self.limits,
            })
        } else {
            let (v, sat) = velocity_to_wire(self.last_meas.v1);
            if sat {
                self.limits.insert(LimitFlags::WIRE_SATURATED);
            }
            Message::TelemetryMotion(TelemetryMotion {
                position: self.last_meas.x1 as i32,
                velocity: v,
                seq,
            })
        };
        self.telemetry_torque_next = !self.telemetry_torque_next;
        self.push(m);
    }
}
