//! Recordings: a 1 kHz CSV with units in the column names (every tick, nothing dropped,
//! flushed on Ctrl-C and at the end) and the raw frames as a candump `-L` log.
//!
//! The recorder sits beside the plant node: it knows the true state of the simulated joint
//! and sees every frame on the bus (setpoints, actuator, telemetry, heartbeats, faults), so
//! it can log what the card was told, what it commanded and what the joint did.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use controller::proto::{Message, NodeId, State};

use crate::bus::ClassicFrame;
use crate::candump::{CandumpWriter, Timestamp};

use super::plant_node::{PlantNode, MOTOR_TORQUE_LSB};

/// The CSV header (the single definition of the recording's columns and units).
pub const COLUMNS: [&str; 15] = [
    "time_s",
    "seq",
    "setpoint_pos_rad",
    "setpoint_torque_nm",
    "motor_pos_rad",
    "output_pos_rad",
    "motor_vel_est_rad_s",
    "motor_vel_rad_s",
    "output_vel_rad_s",
    "torque_cmd_nm",
    "torque_sensor_nm",
    "output_torque_true_nm",
    "state",
    "flags",
    "fault",
];

/// One tick of a recording (motor quantities at the motor, output quantities at the output).
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Time, s.
    pub time_s: f64,
    /// Sensor sequence number.
    pub seq: u8,
    /// Position setpoint the card holds, output rad.
    pub setpoint_pos_rad: f64,
    /// Force setpoint, output N·m.
    pub setpoint_torque_nm: f64,
    /// Motor position from the encoder counts, motor rad.
    pub motor_pos_rad: f64,
    /// True output position, rad.
    pub output_pos_rad: f64,
    /// The card's velocity estimate (last telemetry), motor rad/s.
    pub motor_vel_est_rad_s: f64,
    /// True motor velocity, rad/s.
    pub motor_vel_rad_s: f64,
    /// True output velocity, rad/s.
    pub output_vel_rad_s: f64,
    /// Torque command of this tick, motor N·m.
    pub torque_cmd_nm: f64,
    /// Torque sensor reading, output N·m.
    pub torque_sensor_nm: f64,
    /// True output torque on the environment, N·m.
    pub output_torque_true_nm: f64,
    /// Card state (last heartbeat / fault).
    pub state: State,
    /// Limit flags of the actuator frame.
    pub flags: u8,
    /// The actuator frame had the fault bit.
    pub fault: bool,
}

/// Collects rows and frames; writes them as they come.
#[derive(Debug)]
pub struct Recorder {
    node: NodeId,
    motor_rad_per_count: f64,
    output_rad_per_motor_count: f64,
    setpoint_pos: f64,
    setpoint_torque: f64,
    vel_est: f64,
    state: State,
    /// All rows so far (for the summary and plots).
    pub rows: Vec<Row>,
    csv: Option<(PathBuf, BufWriter<File>)>,
    candump: Option<(PathBuf, CandumpWriter<BufWriter<File>>, String)>,
}

impl Recorder {
    /// A recorder for `node` with `motor_cpr` counts per motor rev and gear ratio `n`.
    pub fn new(node: NodeId, motor_cpr: f64, n: f64) -> Self {
        let r = std::f64::consts::TAU / motor_cpr;
        Recorder {
            node,
            motor_rad_per_count: r,
            output_rad_per_motor_count: r / n,
            setpoint_pos: 0.0,
            setpoint_torque: 0.0,
            vel_est: 0.0,
            state: State::Disabled,
            rows: Vec::new(),
            csv: None,
            candump: None,
        }
    }

    /// Also write the CSV to `path` (header now, a line per tick).
    pub fn write_csv(&mut self, path: &Path) -> Result<()> {
        let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let mut w = BufWriter::new(f);
        writeln!(w, "{}", COLUMNS.join(","))?;
        self.csv = Some((path.to_path_buf(), w));
        Ok(())
    }

    /// Also write every frame to a candump `-L` log at `path` as interface `iface`.
    pub fn write_candump(&mut self, path: &Path, iface: &str) -> Result<()> {
        let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        self.candump = Some((
            path.to_path_buf(),
            CandumpWriter::new(BufWriter::new(f)),
            iface.to_string(),
        ));
        Ok(())
    }

    /// Sees one frame on the bus at time `t` (s).
    pub fn observe(&mut self, t: f64, f: &ClassicFrame) -> Result<()> {
        if let Some((path, w, iface)) = &mut self.candump {
            w.write_frame(
                Timestamp::from_duration(std::time::Duration::from_secs_f64(t.max(0.0))),
                iface,
                f,
            )
            .with_context(|| format!("writing {}", path.display()))?;
        }
        let Ok((node, m)) = Message::decode(f) else {
            return Ok(());
        };
        if node != self.node {
            return Ok(());
        }
        match m {
            Message::SetpointMotion(s) => {
                self.setpoint_pos = f64::from(s.position) * self.output_rad_per_motor_count
            }
            Message::SetpointForce(s) => self.setpoint_torque = f64::from(s.output_torque) * 0.01,
            Message::TelemetryMotion(t) => {
                self.vel_est = f64::from(t.velocity) * 8.0 * self.motor_rad_per_count
            }
            Message::Heartbeat(h) => self.state = h.state,
            Message::Fault(_) => self.state = State::FaultReaction,
            _ => {}
        }
        Ok(())
    }

    /// Records the tick the plant node just completed (call before `advance`).
    pub fn tick(&mut self, t: f64, plant: &PlantNode) -> Result<()> {
        let s = plant.state();
        let sens = plant.sensors();
        let cmd = plant.command();
        if let Some(a) = cmd {
            if a.fault && !matches!(self.state, State::FaultReaction | State::Fault) {
                self.state = State::FaultReaction;
            }
        }
        let row = Row {
            time_s: t,
            seq: plant.seq(),
            setpoint_pos_rad: self.setpoint_pos,
            setpoint_torque_nm: self.setpoint_torque,
            motor_pos_rad: f64::from(sens.motor_counts) * self.motor_rad_per_count,
            output_pos_rad: s.output_angle,
            motor_vel_est_rad_s: self.vel_est,
            motor_vel_rad_s: s.motor_velocity,
            output_vel_rad_s: s.output_velocity,
            torque_cmd_nm: cmd
                .map(|a| f64::from(a.torque) * MOTOR_TORQUE_LSB)
                .unwrap_or(0.0),
            torque_sensor_nm: sens.torque,
            output_torque_true_nm: s.environment_torque,
            state: self.state,
            flags: cmd.map(|a| a.limits.bits()).unwrap_or(0),
            fault: cmd.is_some_and(|a| a.fault),
        };
        if let Some((path, w)) = &mut self.csv {
            writeln!(
                w,
                "{:.3},{},{:.9},{:.4},{:.9},{:.9},{:.6},{:.6},{:.6},{:.4},{:.4},{:.6},{},{},{}",
                row.time_s,
                row.seq,
                row.setpoint_pos_rad,
                row.setpoint_torque_nm,
                row.motor_pos_rad,
                row.output_pos_rad,
                row.motor_vel_est_rad_s,
                row.motor_vel_rad_s,
                row.output_vel_rad_s,
                row.torque_cmd_nm,
                row.torque_sensor_nm,
                row.output_torque_true_nm,
                row.state.name(),
                row.flags,
                u8::from(row.fault)
            )
            .with_context(|| format!("writing {}", path.display()))?;
        }
        self.rows.push(row);
        Ok(())
    }

    /// Flushes both files (called at the end and on Ctrl-C).
    pub fn flush(&mut self) -> Result<()> {
        if let Some((path, w)) = &mut self.csv {
            w.flush()
                .with_context(|| format!("flushing {}", path.display()))?;
        }
        if let Some((path, w, _)) = &mut self.candump {
            w.flush()
                .with_context(|| format!("flushing {}", path.display()))?;
        }
        Ok(())
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}
