//! The HIL lab: card, plant and supervisor nodes on a CAN bus, recordings, the thesis's
//! scenarios and their figures.
//!
//! ```text
//!  Supervisor ──ParamWrite/Commit, ControlWord, Setpoint*──►┐
//!      ▲ ◄────────Telemetry*, Heartbeat, Fault, ParamResponse─┤ bus (in-process hub or SocketCAN)
//!  CardNode (controller::card::Card) ◄──Sensor/OutputEncoder──┤
//!      └────────────────Actuator───────────────────────────►PlantNode (sim_plant::Plant)
//!                                                             └─► Recorder (CSV + candump)
//! ```
//!
//! [`Lab`] runs all three nodes in one thread in lockstep on the in-process bus (the
//! zero-setup demo and the deterministic tests); [`threaded`] runs each node on its own bus
//! handle — threads in one process or separate processes on `vcan0`/`can0`. With
//! [`Lab::use_qemu_card`] the card is the firmware image under QEMU ([`qemu_card`]) and the
//! lab's card handle only relays frames to it: processor-in-the-loop, still in lockstep.
//!
//! Faults can be injected on purpose ([`inject`]); every run ends in a [`report::Report`]
//! whose verdict (ok, degraded, faulted, incomplete, interrupted) sets the exit code, and
//! whose figures are computed from the recording on disk ([`recorder`], [`summary`]).

pub mod backlash_cycle;
pub mod card_node;
pub mod close_loop;
pub mod compensate;
pub mod coulomb_ff;
pub mod fidelity;
pub mod gains;
pub mod inject;
pub mod mem;
pub mod plant_node;
pub mod plot;
#[cfg(unix)]
pub mod qemu_card;
pub mod recorder;
pub mod report;
pub mod scenario;
pub mod stability;
pub mod summary;
pub mod supervisor;
pub mod threaded;
pub mod trajectory;
pub mod velocity_pulse;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use controller::proto::{Message, NodeId};
use sim_plant::{Model, Plant, PlantOptions};

use jointlab_can::bus::{
    BusError, CanBus, ClassicFrame, Impaired, InprocBus, InprocHub, LinkClock,
};

use card_node::CardNode;
use inject::{BusEvent, FaultPlan, Node};
use plant_node::PlantNode;
use recorder::Recorder;
use report::{CardFacts, Facts, Report, SupervisorFacts};
use scenario::Scenario;
use summary::Summary;
use supervisor::Supervisor;

/// CAN bit rate the bus-load figures refer to.
pub const BITRATE: u32 = 1_000_000;

/// Options of a lab run.
#[derive(Clone, Debug)]
pub struct LabOptions {
    /// Node (joint) number.
    pub node: NodeId,
    /// Seed of the plant's sensor noise (and of injected frame losses).
    pub seed: u64,
    /// Internal substep rate of the plant, Hz.
    pub substep_rate: f64,
    /// Faults to inject (`--inject`).
    pub faults: FaultPlan,
    /// Frames lost above this share of ticks make the run degraded.
    pub max_loss: f64,
}

impl Default for LabOptions {
    fn default() -> Self {
        LabOptions {
            node: NodeId::new(1).unwrap_or(NodeId::BROADCAST),
            seed: 1,
            substep_rate: 10_000.0,
            faults: FaultPlan::default(),
            max_loss: report::MAX_LOSS,
        }
    }
}

/// Card + plant + supervisor on one in-process bus, stepped in lockstep in one thread:
/// bit-reproducible from the seed.
///
/// Injected faults ([`LabOptions::faults`]) act on simulated time: error frames reach every
/// node at their tick, before that tick's frames; lossy and delayed links act on each
/// node's receive side; a stalled plant freezes (no sensor frames, no integration, no
/// rows) while the card's clock runs on; a killed supervisor neither sends nor hears. No
/// error frame stops the lab: each node handles it as its firmware would.
#[derive(Debug)]
pub struct Lab {
    /// The scenario.
    pub scenario: Scenario,
    /// The card node.
    pub card: CardNode,
    /// The plant node.
    pub plant: PlantNode,
    /// The supervisor.
    pub supervisor: Supervisor,
    /// The recorder.
    pub recorder: Recorder,
    hub: InprocHub,
    card_bus: Impaired<InprocBus>,
    plant_bus: Impaired<InprocBus>,
    sup_bus: Impaired<InprocBus>,
    monitor: InprocBus,
    node: NodeId,
    tick: u64,
    clock: Arc<AtomicU64>,
    plan: FaultPlan,
    max_loss: f64,
    plant_bus_faults: BTreeMap<BusEvent, u64>,
    /// Ticks in which the supervisor sends nothing (watchdog tests): from this tick on.
    pub supervisor_dies_at: Option<u64>,
    /// Ticks from which the plant stops sending sensor frames.
    pub plant_dies_at: Option<u64>,
    /// The card under QEMU, when it replaces [`Lab::card`].
    #[cfg(unix)]
    qemu: Option<qemu_card::QemuCard>,
}

impl Lab {
    /// Builds the lab for `scenario` on `model`.
    pub fn new(model: &Model, scenario: Scenario, opts: &LabOptions) -> Result<Lab> {
        let plant = Plant::new(
            model,
            PlantOptions {
                substep_rate: opts.substep_rate,
                seed: opts.seed,
                environment: scenario.environment(0.0),
            },
        )?;
        let entries = scenario.gains.entries(&scenario.scale, scenario.mode)?;
        gains::check(&entries, scenario.mode)?;
        let name = format!("lab-{}", opts.seed);
        let hub = match opts.faults.rx_queue() {
            Some(n) => InprocHub::with_rx_capacity(&name, n),
            None => InprocHub::new(&name),
        };
        let mut supervisor = Supervisor::new(
            opts.node,
            scenario.scale,
            entries,
            scenario.mode,
            scenario.target,
            scenario.trajectory.clone(),
            scenario.rate_hz,
            Some(scenario.streaming_s()),
        );
        supervisor.set_velocity_ff(scenario.velocity_ff);
        supervisor.set_silent_windows(
            opts.faults
                .items
                .iter()
                .filter_map(|i| match i {
                    inject::Injection::KillSupervisor(w) => Some(*w),
                    _ => None,
                })
                .collect(),
        );
        let clock = Arc::new(AtomicU64::new(0));
        let link = |who: Node, k: u64| {
            let mut b = Impaired::new(
                hub.attach(who.name()),
                LinkClock::Ticks(clock.clone()),
                opts.seed
                    .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .wrapping_add(k),
            );
            for f in opts.faults.link_faults(who) {
                b.add(f);
            }
            b
        };
        Ok(Lab {
            card: CardNode::new(opts.node, true).map_err(|e| anyhow!("card: {e:?}"))?,
            plant: PlantNode::new(plant, opts.node),
            recorder: Recorder::new(
                opts.node,
                scenario.scale.motor_cpr(),
                scenario.scale.gear_ratio(),
            )
            .with_output_encoder(f64::from(scenario.scale.card.output_cpr)),
            supervisor,
            card_bus: link(Node::Card, 1),
            plant_bus: link(Node::Plant, 2),
            sup_bus: link(Node::Supervisor, 3),
            monitor: hub.attach_unbounded("recorder"),
            hub,
            scenario,
            node: opts.node,
            tick: 0,
            clock,
            plan: opts.faults.clone(),
            max_loss: opts.max_loss,
            plant_bus_faults: BTreeMap::new(),
            supervisor_dies_at: None,
            plant_dies_at: None,
            #[cfg(unix)]
            qemu: None,
        })
    }

    /// Runs the card as the firmware image under QEMU from now on (before the first step):
    /// the frames [`Lab::card`] would have handled go to `card` over SLCAN, and its answers
    /// go on the bus in the same place. `Lab::card` then stays idle.
    #[cfg(unix)]
    pub fn use_qemu_card(&mut self, card: qemu_card::QemuCard) {
        self.qemu = Some(card);
    }

    /// The QEMU card, if the lab runs one.
    #[cfg(unix)]
    pub fn qemu_card(&self) -> Option<&qemu_card::QemuCard> {
        self.qemu.as_ref()
    }

    /// Whether the card is the firmware image under QEMU rather than [`Lab::card`].
    pub fn emulated(&self) -> bool {
        #[cfg(unix)]
        return self.qemu.is_some();
        #[cfg(not(unix))]
        false
    }

    /// The bus hub (for load statistics, or to inject an error frame by hand).
    pub fn hub(&self) -> &InprocHub {
        &self.hub
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.tick as f64 * 1e-3
    }

    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    fn send(bus: &mut impl CanBus, node: NodeId, m: &Message) -> Result<()> {
        let f: ClassicFrame = m.encode(node).map_err(|e| anyhow!("encode {m:?}: {e:?}"))?;
        bus.send(&f)?;
        Ok(())
    }

    /// One 1 ms tick: injected error frames, supervisor, sensor frames, card, actuator,
    /// recording, plant advance.
    pub fn step(&mut self) -> Result<()> {
        if self.tick == 0 {
            self.recorder.keep_on_disk()?;
        }
        self.tick += 1;
        self.clock.store(self.tick, Ordering::Relaxed);
        let t = self.time();
        let env = self.scenario.environment(t);
        if env != self.plant.plant().environment() {
            self.plant.plant_mut().set_environment(env)?;
        }
        // 0. injected error frames: every node sees them before this tick's frames
        for ev in self.plan.bus_events_at(self.tick) {
            self.hub.inject_fault(ev.fault());
        }
        // 1. supervisor (its tick count is the sensor count, like on a real bus)
        let sup_alive = self.supervisor_dies_at.is_none_or(|d| self.tick < d)
            && !self.supervisor.silent_at(self.tick);
        if sup_alive {
            for m in self.supervisor.on_tick(self.tick) {
                Self::send(&mut self.sup_bus, self.node, &m)?;
            }
        }
        // 2. plant: sensor frames of this tick
        let plant_alive =
            self.plant_dies_at.is_none_or(|d| self.tick < d) && !self.plan.plant_stalled(self.tick);
        if plant_alive {
            for f in self.plant.sensor_frames() {
                self.plant_bus.send(&f)?;
            }
        }
        // 3. card: everything queued, in bus order; an error frame goes to its bus-fault
        //    handling. Without its tick (a lost or late sensor frame, a stalled plant) the
        //    card's clock still runs, so its timeouts fire.
        let emulated = self.emulated();
        #[cfg(unix)]
        if let Some(q) = self.qemu.as_mut() {
            // One exchange per tick: the image answers each frame before acknowledging it,
            // so its answers come back in the order the host card would have sent them, and
            // nobody else sends on the bus during this step. SLCAN carries data frames only:
            // error frames do not reach the emulated card (the recorder still logs them).
            let mut batch = Vec::new();
            loop {
                match self.card_bus.try_recv() {
                    Ok(Some(f)) => batch.push(f),
                    Ok(None) => break,
                    Err(BusError::Fault { .. }) => {}
                    Err(e) => return Err(e.into()),
                }
            }
            for g in q.exchange(&batch)? {
                self.card_bus.send(&g)?;
            }
            if !plant_alive {
                bail!("the QEMU card's lockstep clock is its sensor frames: a dead or stalled plant cannot be emulated (use the host card)");
            }
        }
        let mut ticked = false;
        loop {
            let out = match self.card_bus.try_recv() {
                Ok(Some(f)) => {
                    let out = self.card.on_frame(0, &f);
                    ticked |= out.ticked;
                    out
                }
                Ok(None) => break,
                Err(BusError::Fault { fault, .. }) => self.card.on_bus_fault(&fault),
                Err(e) => return Err(e.into()),
            };
            for g in out.frames {
                self.card_bus.send(&g)?;
            }
        }
        if !ticked && !emulated {
            let out = self.card.on_idle(self.tick * 1000);
            for g in out.frames {
                self.card_bus.send(&g)?;
            }
        }
        // 4. plant takes the actuator frame
        loop {
            match self.plant_bus.try_recv() {
                Ok(Some(f)) => {
                    self.plant.on_frame(&f);
                }
                Ok(None) => break,
                Err(BusError::Fault { fault, .. }) => {
                    if let Some(c) = BusEvent::classify(&fault) {
                        *self.plant_bus_faults.entry(c).or_default() += 1;
                    }
                }
                Err(e) => return Err(e.into()),
            }
        }
        // 5. supervisor hears the card
        loop {
            match self.sup_bus.try_recv() {
                Ok(Some(f)) => {
                    if let (true, Ok((node, m))) = (sup_alive, Message::decode(&f)) {
                        self.supervisor.on_message(node, &m);
                    }
                }
                Ok(None) => break,
                Err(BusError::Fault { fault, .. }) => {
                    if sup_alive {
                        self.supervisor.on_bus_fault(&fault);
                    }
                }
                Err(e) => return Err(e.into()),
            }
        }
        // 6. record (error frames too), then integrate the next millisecond
        loop {
            match self.monitor.try_recv() {
                Ok(Some(f)) => self.recorder.observe(t, &f)?,
                Ok(None) => break,
                Err(BusError::Fault { fault, .. }) => self.recorder.observe_fault(t, &fault)?,
                Err(e) => return Err(e.into()),
            }
        }
        if plant_alive {
            self.recorder.tick(t, &self.plant)?;
            self.plant.advance();
        }
        Ok(())
    }

    /// Runs the scenario to the end (with a progress callback every 100 ticks).
    pub fn run(&mut self, mut progress: impl FnMut(u64, u64)) -> Result<()> {
        let n = self.scenario.ticks();
        while self.tick < n {
            self.step().with_context(|| format!("tick {}", self.tick))?;
            if self.tick.is_multiple_of(100) {
                progress(self.tick, n);
            }
        }
        self.recorder.flush()
    }

    /// What the lab knows now, for a [`Report`] titled `title`.
    pub fn facts(&self, title: &str, interrupted: bool) -> Facts {
        let card = self.card.card();
        let gains = &self.scenario.gains;
        Facts {
            title: title.to_string(),
            ticks_planned: self.scenario.ticks(),
            ticks_run: self.tick,
            interrupted,
            tally: self.recorder.tally().clone(),
            missing_actuator: self.plant.missing,
            stale_actuator: self.plant.stale,
            plant_bus_faults: self.plant_bus_faults.clone(),
            // An emulated card's own state is inside QEMU; the report then reads the card
            // from the bus (its fault frames) only.
            card: (!self.emulated()).then(|| CardFacts {
                state: card.state(),
                fault: card.fault(),
                bus_warnings: card.bus_warnings(),
                sensor_frames_lost: card.sensor_frames_lost(),
            }),
            supervisor: Some(SupervisorFacts {
                phase: self.supervisor.phase(),
                committed: self.supervisor.committed(),
                commit_attempts: self.supervisor.commit_attempts(),
                events: self.supervisor.events.clone(),
                bus_faults: self.supervisor.bus_faults().clone(),
                recoveries: self.supervisor.recoveries(),
            }),
            links: vec![
                (Node::Card, self.card_bus.stats()),
                (Node::Plant, self.plant_bus.stats()),
                (Node::Supervisor, self.sup_bus.stats()),
            ],
            injected: self.plan.items.iter().map(|i| i.to_string()).collect(),
            lateness: None,
            sensor_timeout_us: gains
                .sensor_timeout_us
                .map_or_else(report::default_sensor_timeout_us, u64::from),
            max_loss: self.max_loss,
        }
    }

    /// Judges the run and computes the figures its verdict allows.
    pub fn report(&mut self, title: &str, interrupted: bool) -> Result<Report> {
        let r = Report::judge(self.facts(title, interrupted));
        let figures = self.figures(r.withholds())?;
        Ok(r.with_figures(figures))
    }

    /// The scenario's figures from what was recorded, whatever happened (a report withholds
    /// them when the run faulted; tests and benches want them anyway).
    pub fn summary(&mut self) -> Result<Summary> {
        self.figures(None)
    }

    fn figures(&mut self, withhold: Option<&str>) -> Result<Summary> {
        let stats = self.hub.stats();
        let el = std::time::Duration::from_secs_f64(self.time().max(1e-3));
        self.recorder.flush()?;
        let path = self
            .recorder
            .csv_path()
            .ok_or_else(|| anyhow!("the lab has not run a tick"))?
            .to_path_buf();
        summary::summarize_with(
            &self.scenario,
            || recorder::read_rows(&path),
            stats.load_over(BITRATE, el),
            stats.worst_case_load_over(BITRATE, el),
            withhold,
        )
    }
}
