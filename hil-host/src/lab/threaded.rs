//! The nodes as loops over their own bus handle: threads in one process (`hil-host run`) or
//! separate processes (`hil-host card|plant|supervise`) on SocketCAN.
//!
//! Time: in lockstep the plant paces everything (sensor frame k → actuator k → integrate),
//! the card's clock is its tick count and the supervisor counts `Sensor` frames, so the
//! control behaviour does not depend on wall time or scheduling. In real time the plant ticks
//! from a 1 kHz wall clock and measures how late each tick started ([`LateHistogram`]: p50,
//! p99, the worst stall and when), besides the actuator frames that came late or not at all.
//!
//! Every loop hands an error frame to its node (the card's bus-fault handling, the
//! supervisor's and the plant's counts, the recorder's candump log) and carries on; only a
//! bus that fails outright ends a loop.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use controller::proto::{Kind, Message, NodeId};

use jointlab_can::bus::{BusError, CanBus, ClassicFrame, InprocHub};

use super::card_node::{kind_of, CardNode};
use super::inject::{BusEvent, FaultPlan};
use super::plant_node::PlantNode;
use super::recorder::Recorder;
use super::report::Lateness;
use super::scenario::Scenario;
use super::supervisor::{Phase, Supervisor};

/// How the plant paces ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Clock {
    /// Wait for each actuator frame (at most `timeout`), then integrate.
    Lockstep {
        /// Give up on one actuator frame after this long and count it missing.
        timeout: Duration,
    },
    /// A 1 kHz wall-clock tick.
    RealTime,
}

/// What the plant loop measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlantStats {
    /// Ticks run.
    pub ticks: u64,
    /// Actuator frames that never came within their tick.
    pub missing: u64,
    /// Actuator frames that answered an older tick.
    pub stale: u64,
    /// Wall time of the loop.
    pub wall: Duration,
    /// Real time only: how late the ticks started.
    pub lateness: Option<Lateness>,
    /// Error frames the plant node heard, by class.
    pub bus_faults: BTreeMap<BusEvent, u64>,
    /// Frames seen on the bus and their exact/worst-case bit counts.
    pub frames: u64,
    /// Sum of exact bit lengths of the frames seen plus the node's own.
    pub exact_bits: u64,
    /// Worst-case bit sum.
    pub worst_bits: u64,
}

impl PlantStats {
    /// Lockstep cycles per wall second.
    pub fn cycles_per_second(&self) -> f64 {
        self.ticks as f64 / self.wall.as_secs_f64().max(1e-9)
    }
    /// Bus load over simulated time (ticks × 1 ms) at 1 Mbit/s, (exact, worst-case).
    pub fn bus_load(&self) -> (f64, f64) {
        let bits = super::BITRATE as f64 * self.ticks as f64 * 1e-3;
        (
            self.exact_bits as f64 / bits.max(1.0),
            self.worst_bits as f64 / bits.max(1.0),
        )
    }
}

fn account(stats: &mut PlantStats, f: &ClassicFrame) {
    stats.frames += 1;
    stats.exact_bits += u64::from(jointlab_can::bus::bits::exact_bits(f));
    stats.worst_bits += u64::from(jointlab_can::bus::bits::worst_case_bits_of(f));
}

/// Tick-start lateness in 10 µs bins up to 100 ms (and one bin beyond): p50/p99 to 10 µs,
/// the maximum exactly, in 40 kB however long the run.
#[derive(Clone, Debug)]
pub struct LateHistogram {
    bins: Vec<u32>,
    over: u64,
    n: u64,
    max_us: f64,
    worst_at_s: f64,
    late: u64,
}

/// Width of one [`LateHistogram`] bin, µs.
pub const LATE_BIN_US: f64 = 10.0;
const LATE_BINS: usize = 10_000;

impl Default for LateHistogram {
    fn default() -> Self {
        LateHistogram {
            bins: vec![0; LATE_BINS],
            over: 0,
            n: 0,
            max_us: 0.0,
            worst_at_s: 0.0,
            late: 0,
        }
    }
}

impl LateHistogram {
    /// One tick that started `us` late at run time `t_s`.
    pub fn add(&mut self, us: f64, t_s: f64) {
        let us = us.max(0.0);
        self.n += 1;
        if us > self.max_us {
            self.max_us = us;
            self.worst_at_s = t_s;
        }
        if us > 500.0 {
            self.late += 1;
        }
        match self.bins.get_mut((us / LATE_BIN_US) as usize) {
            Some(b) => *b = b.saturating_add(1),
            None => self.over += 1,
        }
    }

    /// The `q` quantile (upper edge of its bin), µs.
    pub fn quantile(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let want = ((self.n as f64 * q).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (i, &c) in self.bins.iter().enumerate() {
            seen += u64::from(c);
            if seen >= want {
                return ((i + 1) as f64 * LATE_BIN_US).min(self.max_us);
            }
        }
        self.max_us
    }

    /// The summary a report carries.
    pub fn lateness(&self) -> Lateness {
        Lateness {
            p50_us: self.quantile(0.5),
            p99_us: self.quantile(0.99),
            max_us: self.max_us,
            worst_at_s: self.worst_at_s,
            late_ticks: self.late,
            ticks: self.n,
        }
    }
}

/// How the plant loop runs.
#[derive(Clone, Debug)]
pub struct PlantLoop {
    /// Pacing.
    pub clock: Clock,
    /// Ticks to run.
    pub ticks: u64,
    /// Lockstep only: never run more than this many ticks past the last frame from the
    /// supervisor while it is alive (0 = do not pace on the supervisor). In lockstep the
    /// simulation runs many times faster than real time; a supervisor thread or process that
    /// is briefly descheduled would otherwise fall hundreds of ticks behind and trip the
    /// card's watchdog, which counts ticks.
    pub supervisor_window: u64,
    /// Wall time after which a silent supervisor is taken as gone (pacing stops, so the
    /// card's watchdog can do its job). Must stay below [`LOCKSTEP_DEAD_PLANT`], or the card
    /// would take the plant's wait for a dead supervisor as a dead plant.
    pub supervisor_grace: Duration,
    /// Injected faults: error frames (put on `hub` at their tick), plant stalls (the loop
    /// sleeps: a stalled process; in lockstep the card notices only beyond
    /// [`LOCKSTEP_DEAD_PLANT`]).
    pub faults: FaultPlan,
    /// The in-process hub the error frames go to.
    pub hub: Option<InprocHub>,
    /// The plant's tick, published for the other nodes' impaired links.
    pub tick: Option<Arc<AtomicU64>>,
}

impl PlantLoop {
    /// Lockstep for `ticks`, pacing on the supervisor with a 100-tick window.
    pub fn lockstep(ticks: u64) -> Self {
        PlantLoop {
            clock: Clock::Lockstep {
                timeout: Duration::from_millis(200),
            },
            ticks,
            supervisor_window: 100,
            supervisor_grace: Duration::from_millis(1000),
            faults: FaultPlan::default(),
            hub: None,
            tick: None,
        }
    }
}

/// Frames a supervisor sends (control word, setpoints, parameter traffic) to `node`.
fn from_supervisor(f: &ClassicFrame) -> bool {
    matches!(
        kind_of(f),
        Some(k) if k == Kind::SetpointMotion as u16
            || k == Kind::SetpointForce as u16
            || k == Kind::ControlWord as u16
            || k == Kind::ParamWrite as u16
            || k == Kind::ParamCommit as u16
            || k == Kind::ParamRead as u16
    )
}

/// The plant loop: `ticks` ticks (or until `stop`), recording everything it sees.
pub fn run_plant(
    bus: &mut dyn CanBus,
    plant: &mut PlantNode,
    scenario: Option<&Scenario>,
    recorder: &mut Recorder,
    opts: PlantLoop,
    stop: &AtomicBool,
    mut progress: impl FnMut(u64, u64),
) -> Result<PlantStats> {
    let (clock, ticks) = (opts.clock, opts.ticks);
    let mut st = PlantStats::default();
    let mut last_sup: Option<u64> = None;
    let mut sup_gone = false;
    let mut t_start = Instant::now();
    let mut late = LateHistogram::default();
    let mut stalled = false;
    recorder.keep_on_disk()?;
    while st.ticks < ticks && !stop.load(Ordering::Relaxed) {
        let k = st.ticks + 1;
        let t = k as f64 * 1e-3;
        if let Some(tk) = &opts.tick {
            tk.store(k, Ordering::Relaxed);
        }
        if let Some(hub) = &opts.hub {
            for ev in opts.faults.bus_events_at(k) {
                hub.inject_fault(ev.fault());
            }
        }
        // An injected stall: the plant process sleeps through it, then carries on (in real
        // time, late: it catches up with its schedule).
        if opts.faults.plant_stalled(k) && !stalled {
            stalled = true;
            let mut n = 0u64;
            while opts.faults.plant_stalled(k + n) {
                n += 1;
            }
            let d = Duration::from_millis(n);
            let until = Instant::now() + d;
            while Instant::now() < until && !stop.load(Ordering::Relaxed) {
                std::thread::sleep((until - Instant::now()).min(Duration::from_millis(10)));
            }
            if clock != Clock::RealTime {
                // lockstep: the stall is wall time; the schedule does not move
                t_start += d;
            }
        }
        stalled &= opts.faults.plant_stalled(k);
        if let Some(sc) = scenario {
            let env = sc.environment(t);
            if env != plant.plant().environment() {
                plant.plant_mut().set_environment(env)?;
            }
        }
        // Pace on the supervisor (lockstep): wait for it to catch up within its window —
        // from the start, so that a supervisor thread that starts late does not find
        // hundreds of ticks queued before its first commit is even answered.
        if let (Clock::Lockstep { .. }, ls, false) = (clock, last_sup.unwrap_or(0), sup_gone) {
            if opts.supervisor_window > 0 && k.saturating_sub(ls) > opts.supervisor_window {
                let give_up = Instant::now() + opts.supervisor_grace;
                loop {
                    let now = Instant::now();
                    if now >= give_up || stop.load(Ordering::Relaxed) {
                        sup_gone = true;
                        break;
                    }
                    match bus.recv_timeout(give_up - now) {
                        Ok(Some(f)) => {
                            account(&mut st, &f);
                            recorder.observe(t, &f)?;
                            if from_supervisor(&f) {
                                last_sup = Some(k);
                                break;
                            }
                        }
                        Ok(None) => {}
                        Err(BusError::Fault { fault, .. }) => {
                            fault_seen(&mut st, recorder, t, &fault)?;
                        }
                        Err(e) => return Err(e.into()),
                    }
                }
            }
        }
        let deadline = match clock {
            Clock::RealTime => {
                let due = t_start + Duration::from_micros(k * 1000);
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
                late.add(
                    Instant::now().saturating_duration_since(due).as_secs_f64() * 1e6,
                    t,
                );
                due + Duration::from_micros(1000)
            }
            Clock::Lockstep { timeout } => Instant::now() + timeout,
        };
        for f in plant.sensor_frames() {
            bus.send(&f)?;
            account(&mut st, &f);
            recorder.observe(t, &f)?;
        }
        loop {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            match bus.recv_timeout(deadline - now) {
                Ok(Some(f)) => {
                    account(&mut st, &f);
                    recorder.observe(t, &f)?;
                    if from_supervisor(&f) {
                        last_sup = Some(k);
                    }
                    if plant.on_frame(&f).is_some() && matches!(clock, Clock::Lockstep { .. }) {
                        break;
                    }
                }
                Ok(None) => break,
                Err(BusError::Fault { fault, .. }) => {
                    fault_seen(&mut st, recorder, t, &fault)?;
                    continue;
                }
                Err(e) => return Err(e.into()),
            }
        }
        recorder.tick(t, plant)?;
        plant.advance();
        st.ticks = k;
        if k.is_multiple_of(100) {
            progress(k, ticks);
        }
    }
    st.missing = plant.missing;
    st.stale = plant.stale;
    st.wall = t_start.elapsed();
    if clock == Clock::RealTime {
        st.lateness = Some(late.lateness());
    }
    recorder.flush()?;
    Ok(st)
}

/// An error frame at the plant node: counted, and recorded (candump and tally).
fn fault_seen(
    st: &mut PlantStats,
    recorder: &mut Recorder,
    t: f64,
    fault: &jointlab_can::bus::BusFault,
) -> Result<()> {
    if let Some(c) = BusEvent::classify(fault) {
        *st.bus_faults.entry(c).or_default() += 1;
    }
    recorder.observe_fault(t, fault)
}

/// In lockstep, how long the plant may stay silent (wall time) before the card's sensor
/// timeout starts counting.
pub const LOCKSTEP_DEAD_PLANT: Duration = Duration::from_millis(2000);

/// The card loop: runs until `stop`. In lockstep the card's time is its tick count; when no
/// sensor frame arrives for a while (a dead plant), wall time since the last one is added so
/// the sensor timeout still fires.
pub fn run_card(
    bus: &mut dyn CanBus,
    card: &mut CardNode,
    lockstep: bool,
    stop: &AtomicBool,
) -> Result<()> {
    let t0 = Instant::now();
    let mut last_rx = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let wall_us = t0.elapsed().as_micros() as u64;
        match bus.recv_timeout(Duration::from_millis(2)) {
            Ok(Some(f)) => {
                if kind_of(&f) == Some(Kind::Sensor as u16) {
                    last_rx = Instant::now();
                }
                let out = card.on_frame(wall_us, &f);
                for g in out.frames {
                    bus.send(&g)?;
                }
            }
            Ok(None) => {
                let now = if lockstep {
                    // Lockstep has no wall clock: scheduling gaps of a few ms between the
                    // processes are normal (more so under emulation), so only a plant silent
                    // for longer than LOCKSTEP_DEAD_PLANT counts, and from then on time runs.
                    let gap = last_rx.elapsed().saturating_sub(LOCKSTEP_DEAD_PLANT);
                    card.now_us() + gap.as_micros() as u64
                } else {
                    wall_us
                };
                let out = card.on_idle(now);
                for g in out.frames {
                    bus.send(&g)?;
                }
            }
            Err(BusError::Fault { fault, .. }) => {
                for g in card.on_bus_fault(&fault).frames {
                    let _ = bus.send(&g);
                }
            }
            Err(e) => {
                // The bus itself failed: the card can no longer hear its sensors or its
                // supervisor. Safe state first (a real card would also cut its power stage
                // here through `power_stage`), then report.
                card.on_bus_fault(&jointlab_can::bus::BusFault::bus_off());
                return Err(anyhow!("card bus failed: {e}"));
            }
        }
    }
    Ok(())
}

/// The supervisor loop: one `on_tick` per `Sensor` frame seen for its node, until the
/// script ends (plus `linger` ticks) or `stop`. Error frames are counted by the supervisor
/// ([`Supervisor::on_bus_fault`]); its silent windows ([`Supervisor::set_silent_windows`])
/// make it a killed supervisor for the card's watchdog.
pub fn run_supervisor(
    bus: &mut dyn CanBus,
    sup: &mut Supervisor,
    node: NodeId,
    stop: &AtomicBool,
    linger: u64,
    mut on_tick: impl FnMut(u64, &Supervisor),
) -> Result<u64> {
    let mut tick = 0u64;
    let mut stopped_at = None;
    let sensor_id = u32::from(controller::proto::id::compose(Kind::Sensor, node));
    while !stop.load(Ordering::Relaxed) {
        match bus.recv_timeout(Duration::from_millis(50)) {
            Ok(Some(f)) => {
                if !f.is_extended() && f.raw_id() == sensor_id {
                    tick += 1;
                    for m in sup.on_tick(tick) {
                        let g: ClassicFrame =
                            m.encode(node).map_err(|e| anyhow!("encode: {e:?}"))?;
                        bus.send(&g)?;
                    }
                    on_tick(tick, sup);
                    if sup.phase() == Phase::Stopped {
                        let s = *stopped_at.get_or_insert(tick);
                        if tick >= s + linger {
                            break;
                        }
                    }
                } else if let Ok((n, m)) = Message::decode(&f) {
                    sup.on_message(n, &m);
                }
            }
            Ok(None) => {}
            Err(BusError::Fault { fault, .. }) => sup.on_bus_fault(&fault),
            Err(e) => return Err(e.into()),
        }
    }
    Ok(tick)
}
