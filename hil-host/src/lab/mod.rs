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

pub mod card_node;
pub mod gains;
pub mod plant_node;
pub mod plot;
#[cfg(unix)]
pub mod qemu_card;
pub mod recorder;
pub mod scenario;
pub mod summary;
pub mod supervisor;
pub mod threaded;
pub mod trajectory;

use anyhow::{anyhow, bail, Context, Result};
use controller::proto::{Message, NodeId};
use sim_plant::{Model, Plant, PlantOptions};

use crate::bus::{CanBus, ClassicFrame, InprocBus, InprocHub};

use card_node::CardNode;
use plant_node::PlantNode;
use recorder::Recorder;
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
    /// Seed of the plant's sensor noise.
    pub seed: u64,
    /// Internal substep rate of the plant, Hz.
    pub substep_rate: f64,
}

impl Default for LabOptions {
    fn default() -> Self {
        LabOptions {
            node: NodeId::new(1).unwrap_or(NodeId::BROADCAST),
            seed: 1,
            substep_rate: 10_000.0,
        }
    }
}

/// Card + plant + supervisor on one in-process bus, stepped in lockstep in one thread:
/// bit-reproducible from the seed.
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
    card_bus: InprocBus,
    plant_bus: InprocBus,
    sup_bus: InprocBus,
    monitor: InprocBus,
    node: NodeId,
    tick: u64,
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
        let entries = scenario.gains.entries(&scenario.scale)?;
        gains::check(&entries, scenario.mode)?;
        let hub = InprocHub::new(&format!("lab-{}", opts.seed));
        let supervisor = Supervisor::new(
            opts.node,
            scenario.scale,
            entries,
            scenario.mode,
            scenario.target,
            scenario.trajectory.clone(),
            scenario.rate_hz,
            Some(scenario.streaming_s()),
        );
        Ok(Lab {
            card: CardNode::new(opts.node, true).map_err(|e| anyhow!("card: {e:?}"))?,
            plant: PlantNode::new(plant, opts.node),
            recorder: Recorder::new(
                opts.node,
                scenario.scale.motor_cpr,
                scenario.scale.gear_ratio,
            ),
            supervisor,
            card_bus: hub.attach("card"),
            plant_bus: hub.attach("plant"),
            sup_bus: hub.attach("supervisor"),
            monitor: hub.attach("recorder"),
            hub,
            scenario,
            node: opts.node,
            tick: 0,
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

    /// The bus hub (for load statistics).
    pub fn hub(&self) -> &InprocHub {
        &self.hub
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.tick as f64 * 1e-3
    }

    fn send(bus: &mut InprocBus, node: NodeId, m: &Message) -> Result<()> {
        let f: ClassicFrame = m.encode(node).map_err(|e| anyhow!("encode {m:?}: {e:?}"))?;
        bus.send(&f)?;
        Ok(())
    }

    /// One 1 ms tick: supervisor, sensor frames, card, actuator, recording, plant advance.
    pub fn step(&mut self) -> Result<()> {
        self.tick += 1;
        let t = self.time();
        let env = self.scenario.environment(t);
        if env != self.plant.plant().environment() {
            self.plant.plant_mut().set_environment(env)?;
        }
        // 1. supervisor (its tick count is the sensor count, like on a real bus)
        let sup_alive = self.supervisor_dies_at.is_none_or(|d| self.tick < d);
        if sup_alive {
            for m in self.supervisor.on_tick(self.tick) {
                Self::send(&mut self.sup_bus, self.node, &m)?;
            }
        }
        // 2. plant: sensor frames of this tick
        let plant_alive = self.plant_dies_at.is_none_or(|d| self.tick < d);
        if plant_alive {
            for f in self.plant.sensor_frames() {
                self.plant_bus.send(&f)?;
            }
        }
        // 3. card: everything queued, in bus order
        #[cfg(unix)]
        if let Some(q) = self.qemu.as_mut() {
            // One exchange per tick: the image answers each frame before acknowledging it,
            // so its answers come back in the order the host card would have sent them, and
            // nobody else sends on the bus during this step.
            let mut batch = Vec::new();
            while let Some(f) = self.card_bus.try_recv()? {
                batch.push(f);
            }
            for g in q.exchange(&batch)? {
                self.card_bus.send(&g)?;
            }
            if !plant_alive {
                bail!("the QEMU card's lockstep clock is its sensor frames: a dead plant cannot be emulated (use the host card)");
            }
        }
        while let Some(f) = self.card_bus.try_recv()? {
            let out = self.card.on_frame(0, &f);
            for g in out.frames {
                self.card_bus.send(&g)?;
            }
        }
        if !plant_alive {
            let out = self.card.on_idle(self.tick * 1000);
            for g in out.frames {
                self.card_bus.send(&g)?;
            }
        }
        // 4. plant takes the actuator frame
        while let Some(f) = self.plant_bus.try_recv()? {
            self.plant.on_frame(&f);
        }
        // 5. supervisor hears the card
        while let Some(f) = self.sup_bus.try_recv()? {
            if !sup_alive {
                continue;
            }
            if let Ok((node, m)) = Message::decode(&f) {
                self.supervisor.on_message(node, &m);
            }
        }
        // 6. record, then integrate the next millisecond
        while let Some(f) = self.monitor.try_recv()? {
            self.recorder.observe(t, &f)?;
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

    /// The scenario's figures from what was recorded.
    pub fn summary(&self) -> Summary {
        let stats = self.hub.stats();
        let el = std::time::Duration::from_secs_f64(self.time().max(1e-3));
        summary::summarize(
            &self.scenario,
            &self.recorder.rows,
            stats.load_over(BITRATE, el),
            stats.worst_case_load_over(BITRATE, el),
        )
    }
}
