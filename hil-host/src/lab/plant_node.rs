//! The plant node: a `sim-plant` model on the bus, seen by the card exactly as a real joint's
//! sensor electronics would be — a `Sensor` frame (and an `OutputEncoder` frame when the
//! joint has one) per tick, answered by an `Actuator` frame.
//!
//! Lockstep (the default): the node sends the sensor frame of tick k, waits for the
//! actuator frame echoing k's sequence number, integrates 1 ms with that command held (zero
//! order hold, ≥ 10 kHz internal substeps), and repeats; nothing depends on wall time, so a
//! run is bit-reproducible. Real time: the same per tick, but paced by a 1 kHz wall clock,
//! counting late and missing actuator frames (see [`super::threaded`]).

use controller::proto::scale::{MOTOR_TORQUE_NM_PER_LSB, OUTPUT_TORQUE_NM_PER_LSB};
use controller::proto::{Actuator, Message, NodeId, OutputEncoder, Sensor};
use sim_plant::{Plant, Sensors as PlantSensors, TrueState};

use jointlab_can::bus::ClassicFrame;

/// The plant on the bus.
#[derive(Debug)]
pub struct PlantNode {
    plant: Plant,
    node: NodeId,
    seq: u8,
    tick: u64,
    period_s: f64,
    cmd: Option<Actuator>,
    sensors: PlantSensors,
    /// Actuator frames that never came (lockstep timeout or real-time deadline).
    pub missing: u64,
    /// Actuator frames answering an older tick.
    pub stale: u64,
}

impl PlantNode {
    /// Wraps `plant` for card `node`; reads the first sensor sample.
    pub fn new(mut plant: Plant, node: NodeId) -> Self {
        let sensors = plant.read_sensors();
        PlantNode {
            plant,
            node,
            seq: 0,
            tick: 0,
            period_s: 1e-3,
            cmd: None,
            sensors,
            missing: 0,
            stale: 0,
        }
    }

    /// The simulated joint.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }
    /// Mutable access (e.g. to change the environment between ticks).
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }
    /// True state after the last advance.
    pub fn state(&self) -> TrueState {
        self.plant.state()
    }
    /// The sensor sample sent this tick.
    pub fn sensors(&self) -> &PlantSensors {
        &self.sensors
    }
    /// Ticks completed.
    pub fn tick(&self) -> u64 {
        self.tick
    }
    /// Sequence number of the current tick.
    pub fn seq(&self) -> u8 {
        self.seq
    }
    /// The actuator command received for the current tick, if any.
    pub fn command(&self) -> Option<Actuator> {
        self.cmd
    }

    /// The frames of the current tick: `OutputEncoder` first (lower ID, and the card needs
    /// it before the `Sensor` frame that triggers its step), then `Sensor`.
    pub fn sensor_frames(&mut self) -> Vec<ClassicFrame> {
        self.seq = self.seq.wrapping_add(1);
        self.cmd = None;
        let s = &self.sensors;
        let mut out = Vec::with_capacity(2);
        if let Some(c) = s.output_counts {
            let m = Message::OutputEncoder(OutputEncoder {
                output_counts: c as u32,
                seq: self.seq,
            });
            out.extend(m.encode::<ClassicFrame>(self.node).ok());
        }
        let lsb = (s.torque / OUTPUT_TORQUE_NM_PER_LSB).round();
        let sensor = Sensor {
            motor_counts: s.motor_counts as u32,
            output_torque: Some(lsb.clamp(-32767.0, 32767.0) as i16),
            seq: self.seq,
            output_encoder: s.output_counts.is_some(),
            encoder_error: false,
        };
        out.extend(
            Message::Sensor(sensor)
                .encode::<ClassicFrame>(self.node)
                .ok(),
        );
        out
    }

    /// Takes a received frame. Returns the actuator command if it answers the current tick.
    pub fn on_frame(&mut self, f: &ClassicFrame) -> Option<Actuator> {
        match Message::decode(f) {
            Ok((node, Message::Actuator(a))) if node == self.node => {
                if a.seq == self.seq {
                    self.cmd = Some(a);
                    Some(a)
                } else {
                    self.stale += 1;
                    None
                }
            }
            _ => None,
        }
    }

    /// The torque this tick's command holds (N·m at the motor): zero if none came (a real
    /// power stage without a command drives nothing; counted as missing) or it does not drive.
    fn held_torque(&mut self) -> f64 {
        match self.cmd {
            Some(a) if a.drive => f64::from(a.torque) * MOTOR_TORQUE_NM_PER_LSB,
            Some(_) => 0.0,
            None => {
                self.missing += 1;
                0.0
            }
        }
    }

    /// Integrates one period with the command of this tick held, then samples the sensors.
    pub fn advance(&mut self) {
        let tau = self.held_torque();
        self.plant.advance(tau, self.period_s);
        self.sensors = self.plant.read_sensors();
        self.tick += 1;
    }

    /// [`PlantNode::advance`] in `parts` equal sub-intervals, calling `before(j, plant)` before
    /// part j: the true joint inside the hold, for a recording that logs it between two sensor
    /// samples (mid-hold positions, a fine grid). With `parts` = the plant's substeps per period
    /// (or a divisor of them) every part is whole substeps of the same length: the same
    /// integrator steps as one `advance`, only the half-drifts it merges across substep
    /// boundaries are taken one by one (a difference in rounding, not in physics).
    pub fn advance_in_parts(&mut self, parts: usize, mut before: impl FnMut(usize, &Plant)) {
        let tau = self.held_torque();
        let parts = parts.max(1);
        let h = self.period_s / parts as f64;
        for j in 0..parts {
            before(j, &self.plant);
            self.plant.advance(tau, h);
        }
        self.sensors = self.plant.read_sensors();
        self.tick += 1;
    }
}
