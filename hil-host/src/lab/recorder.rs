//! Recordings: a 1 kHz CSV with units in the column names (every tick, nothing dropped) and
//! the raw frames — error frames included — as a candump `-L` log.
//!
//! The recorder sits beside the plant node: it knows the true state of the simulated joint
//! and sees every frame on the bus (setpoints, actuator, telemetry, heartbeats, faults), so
//! it can log what the card was told, what it commanded and what the joint did.
//!
//! Memory stays bounded however long a run lasts: rows go to disk as they come (buffered,
//! flushed at least once a wall-clock second, at the end and when dropped), into the CSV the
//! caller asked for or, without one, a temporary file of the same format. Only the last
//! [`RECENT_ROWS`] rows stay in memory; summaries and plots read the file back
//! ([`read_rows`]). What the run's report needs — rows, faulted ticks, missing commands,
//! error frames by class, the card's fault frames — is counted as it is written
//! ([`Tally`]), so the report, the CSV and the candump log agree by construction.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use controller::proto::scale::{self, MOTOR_TORQUE_NM_PER_LSB, OUTPUT_TORQUE_NM_PER_LSB};
use controller::proto::{ControlWord, FaultCode, Message, NodeId, State};

use jointlab_can::bus::{BusFault, ClassicFrame};
use jointlab_can::candump::{CandumpWriter, Timestamp};

use super::inject::BusEvent;
use super::plant_node::PlantNode;

/// The CSV header (the single definition of the recording's columns and units).
pub const COLUMNS: [&str; 16] = [
    "time_s",
    "seq",
    "setpoint_pos_rad",
    "setpoint_torque_Nm",
    "motor_pos_rad",
    "output_pos_rad",
    "motor_vel_est_rad_s",
    "motor_vel_rad_s",
    "output_vel_rad_s",
    "torque_cmd_Nm",
    "torque_sensor_Nm",
    "output_torque_true_Nm",
    "state",
    "flags",
    "fault",
    "cmd_missing",
];

/// Rows kept in memory (the latest; the whole recording is on disk).
pub const RECENT_ROWS: usize = 1000;

/// Longest wall time between two flushes of the files.
pub const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// Card fault frames remembered one by one (the rest are only counted).
pub const FAULTS_KEPT: usize = 32;

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
    /// No actuator frame answered this tick (the plant held zero torque).
    pub cmd_missing: bool,
}

/// A card fault frame the recorder saw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeenFault {
    /// When, s.
    pub time_s: f64,
    /// Which.
    pub code: FaultCode,
    /// Its detail word.
    pub detail: i32,
}

/// What was recorded, counted as it was written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tally {
    /// CSV rows.
    pub rows: u64,
    /// Rows whose actuator frame carried the fault bit.
    pub faulted_rows: u64,
    /// Time of the first of them.
    pub first_faulted_s: Option<f64>,
    /// Rows without an actuator frame.
    pub missing_rows: u64,
    /// Time of the last row.
    pub last_time_s: f64,
    /// Data frames seen (each is a candump line when logging).
    pub frames: u64,
    /// Error frames seen, by class (each is a candump line when logging).
    pub error_frames: BTreeMap<BusEvent, u64>,
    /// Error frames that only report recovery or counters.
    pub info_frames: u64,
    /// Time of the first error frame of each class.
    pub first_error_s: BTreeMap<BusEvent, f64>,
    /// The first [`FAULTS_KEPT`] fault frames of this node's card.
    pub card_faults: Vec<SeenFault>,
    /// All of them.
    pub card_fault_frames: u64,
}

impl Tally {
    /// Error frames of every class.
    pub fn error_frames_total(&self) -> u64 {
        self.error_frames.values().sum::<u64>() + self.info_frames
    }
}

/// Where the rows go.
#[derive(Debug)]
struct Sink {
    path: PathBuf,
    out: BufWriter<File>,
    /// A temporary file (no CSV asked for), deleted with the recorder.
    _temp: Option<tempfile::TempPath>,
}

/// Collects rows and frames; writes them as they come. See the module docs.
#[derive(Debug)]
pub struct Recorder {
    node: NodeId,
    motor_rad_per_count: f64,
    output_rad_per_motor_count: f64,
    /// Output rad per output-encoder count, when the joint has one.
    output_rad_per_count: Option<f64>,
    /// The card was last enabled in a non-colocated mode.
    non_colocated: bool,
    setpoint_pos: f64,
    setpoint_torque: f64,
    vel_est: f64,
    state: State,
    /// The latest rows, at most [`RECENT_ROWS`] (oldest first; the last is the newest).
    pub rows: Vec<Row>,
    csv: Option<Sink>,
    candump: Option<(PathBuf, CandumpWriter<BufWriter<File>>, String)>,
    last_flush: Instant,
    tally: Tally,
}

impl Recorder {
    /// A recorder for `node` with `motor_cpr` counts per motor rev and gear ratio `n`.
    pub fn new(node: NodeId, motor_cpr: f64, n: f64) -> Self {
        let r = std::f64::consts::TAU / motor_cpr;
        Recorder {
            node,
            motor_rad_per_count: r,
            output_rad_per_motor_count: r / n,
            output_rad_per_count: None,
            non_colocated: false,
            setpoint_pos: 0.0,
            setpoint_torque: 0.0,
            vel_est: 0.0,
            state: State::Disabled,
            rows: Vec::new(),
            csv: None,
            candump: None,
            last_flush: Instant::now(),
            tally: Tally::default(),
        }
    }

    /// The joint's output encoder (counts per output rev), for the setpoints of the
    /// non-colocated modes, which the recorder learns from the `Enable` it sees.
    pub fn with_output_encoder(mut self, counts_per_rev: f64) -> Self {
        self.output_rad_per_count =
            (counts_per_rev > 0.0).then(|| std::f64::consts::TAU / counts_per_rev);
        self
    }

    fn open_sink(path: &Path, temp: Option<tempfile::TempPath>) -> Result<Sink> {
        let f = File::options()
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut out = BufWriter::new(f);
        writeln!(out, "{}", COLUMNS.join(","))
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(Sink {
            path: path.to_path_buf(),
            out,
            _temp: temp,
        })
    }

    /// Writes the CSV to `path` (header now, a line per tick). Call before the first tick.
    pub fn write_csv(&mut self, path: &Path) -> Result<()> {
        if self.tally.rows > 0 {
            bail!(
                "{}: the recording already has {} rows elsewhere; choose the CSV before the first tick",
                path.display(),
                self.tally.rows
            );
        }
        self.csv = Some(Self::open_sink(path, None)?);
        Ok(())
    }

    /// Without a CSV of its own, the recording goes to a temporary file (deleted with the
    /// recorder) so that summaries and plots can read it back. Called by the lab before its
    /// first tick; a no-op once a file is chosen.
    pub fn keep_on_disk(&mut self) -> Result<()> {
        if self.csv.is_some() {
            return Ok(());
        }
        if self.tally.rows > 0 {
            bail!("the recording already has rows that were not kept on disk");
        }
        let temp = tempfile::Builder::new()
            .prefix("jointlab-rec-")
            .suffix(".csv")
            .tempfile()
            .context("cannot create a temporary recording file")?
            .into_temp_path();
        let path = temp.to_path_buf();
        self.csv = Some(Self::open_sink(&path, Some(temp))?);
        Ok(())
    }

    /// The file the rows go to, if any.
    pub fn csv_path(&self) -> Option<&Path> {
        self.csv.as_ref().map(|s| s.path.as_path())
    }

    /// Also write every frame, error frames included, to a candump `-L` log at `path` as
    /// interface `iface`.
    pub fn write_candump(&mut self, path: &Path, iface: &str) -> Result<()> {
        let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        self.candump = Some((
            path.to_path_buf(),
            CandumpWriter::new(BufWriter::new(f)),
            iface.to_string(),
        ));
        Ok(())
    }

    /// What was recorded so far.
    pub fn tally(&self) -> &Tally {
        &self.tally
    }

    fn stamp(t: f64) -> Timestamp {
        Timestamp::from_duration(Duration::from_secs_f64(t.max(0.0)))
    }

    /// Sees one frame on the bus at time `t` (s).
    pub fn observe(&mut self, t: f64, f: &ClassicFrame) -> Result<()> {
        self.tally.frames += 1;
        if let Some((path, w, iface)) = &mut self.candump {
            w.write_frame(Self::stamp(t), iface, f)
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
                // In the non-colocated modes the position is in output counts (protocol).
                let per_count = match self.output_rad_per_count {
                    Some(r) if self.non_colocated => r,
                    _ => self.output_rad_per_motor_count,
                };
                self.setpoint_pos = f64::from(s.position) * per_count
            }
            Message::ControlWord(ControlWord::Enable(mode)) => {
                self.non_colocated = mode.needs_output_encoder()
            }
            Message::SetpointForce(s) => {
                self.setpoint_torque = f64::from(s.output_torque) * OUTPUT_TORQUE_NM_PER_LSB
            }
            Message::TelemetryMotion(t) => {
                self.vel_est =
                    f64::from(scale::velocity_from_wire(t.velocity)) * self.motor_rad_per_count
            }
            Message::Heartbeat(h) => self.state = h.state,
            Message::Fault(x) => {
                self.state = State::FaultReaction;
                self.tally.card_fault_frames += 1;
                if self.tally.card_faults.len() < FAULTS_KEPT {
                    self.tally.card_faults.push(SeenFault {
                        time_s: t,
                        code: x.code,
                        detail: x.detail,
                    });
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Sees one error frame at time `t` (s): logged to candump and counted by class.
    pub fn observe_fault(&mut self, t: f64, fault: &BusFault) -> Result<()> {
        if let Some((path, w, iface)) = &mut self.candump {
            w.write_fault(Self::stamp(t), iface, fault)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        match BusEvent::classify(fault) {
            Some(c) => {
                *self.tally.error_frames.entry(c).or_default() += 1;
                self.tally.first_error_s.entry(c).or_insert(t);
            }
            None => self.tally.info_frames += 1,
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
                .map(|a| f64::from(a.torque) * MOTOR_TORQUE_NM_PER_LSB)
                .unwrap_or(0.0),
            torque_sensor_nm: sens.torque,
            output_torque_true_nm: s.environment_torque,
            state: self.state,
            flags: cmd.map(|a| a.limits.bits()).unwrap_or(0),
            fault: cmd.is_some_and(|a| a.fault),
            cmd_missing: cmd.is_none(),
        };
        if let Some(sink) = &mut self.csv {
            write_row(&mut sink.out, &row)
                .with_context(|| format!("writing {}", sink.path.display()))?;
        }
        let tl = &mut self.tally;
        tl.rows += 1;
        tl.last_time_s = t;
        if row.fault {
            tl.faulted_rows += 1;
            tl.first_faulted_s.get_or_insert(t);
        }
        if row.cmd_missing {
            tl.missing_rows += 1;
        }
        if self.rows.len() >= 2 * RECENT_ROWS {
            self.rows.drain(..RECENT_ROWS);
        }
        self.rows.push(row);
        if self.last_flush.elapsed() >= FLUSH_EVERY {
            self.flush()?;
        }
        Ok(())
    }

    /// The latest rows, at most [`RECENT_ROWS`].
    pub fn recent(&self) -> &[Row] {
        let n = self.rows.len();
        self.rows
            .get(n.saturating_sub(RECENT_ROWS)..)
            .unwrap_or_default()
    }

    /// Flushes both files (at least every [`FLUSH_EVERY`], at the end, on Ctrl-C, on drop).
    pub fn flush(&mut self) -> Result<()> {
        self.last_flush = Instant::now();
        if let Some(sink) = &mut self.csv {
            sink.out
                .flush()
                .with_context(|| format!("flushing {}", sink.path.display()))?;
        }
        if let Some((path, w, _)) = &mut self.candump {
            w.flush()
                .with_context(|| format!("flushing {}", path.display()))?;
        }
        Ok(())
    }

    /// Flushes, then reads the whole recording back, row by row.
    pub fn read_back(&mut self) -> Result<RowReader> {
        self.flush()?;
        let path = self
            .csv_path()
            .ok_or_else(|| anyhow!("the recording was not kept on disk"))?;
        read_rows(path)
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}

fn write_row(w: &mut impl Write, row: &Row) -> std::io::Result<()> {
    writeln!(
        w,
        "{:.3},{},{:.9},{:.4},{:.9},{:.9},{:.6},{:.6},{:.6},{:.4},{:.4},{:.6},{},{},{},{}",
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
        u8::from(row.fault),
        u8::from(row.cmd_missing),
    )
}

/// Reads a recording written by [`Recorder`] row by row (bounded memory).
#[derive(Debug)]
pub struct RowReader {
    path: PathBuf,
    lines: std::io::Lines<BufReader<File>>,
    line_no: usize,
}

/// Opens a recording and checks its header.
pub fn read_rows(path: &Path) -> Result<RowReader> {
    let f = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut lines = BufReader::new(f).lines();
    let header = lines
        .next()
        .transpose()
        .with_context(|| format!("reading {}", path.display()))?
        .unwrap_or_default();
    if header != COLUMNS.join(",") {
        bail!(
            "{} line 1: not a jointlab recording header (expected `{}`)",
            path.display(),
            COLUMNS.join(",")
        );
    }
    Ok(RowReader {
        path: path.to_path_buf(),
        lines,
        line_no: 1,
    })
}

fn parse_row(line: &str) -> std::result::Result<Row, String> {
    let v: Vec<&str> = line.split(',').collect();
    if v.len() != COLUMNS.len() {
        return Err(format!("{} fields, expected {}", v.len(), COLUMNS.len()));
    }
    let f = |i: usize| -> std::result::Result<f64, String> {
        v[i].parse::<f64>()
            .map_err(|_| format!("column `{}`: `{}` is not a number", COLUMNS[i], v[i]))
    };
    let int = |i: usize| -> std::result::Result<u8, String> {
        v[i].parse::<u8>()
            .map_err(|_| format!("column `{}`: `{}` is not a byte", COLUMNS[i], v[i]))
    };
    let flag = |i: usize| -> std::result::Result<bool, String> {
        match v[i] {
            "0" => Ok(false),
            "1" => Ok(true),
            x => Err(format!("column `{}`: `{x}` is not 0 or 1", COLUMNS[i])),
        }
    };
    Ok(Row {
        time_s: f(0)?,
        seq: int(1)?,
        setpoint_pos_rad: f(2)?,
        setpoint_torque_nm: f(3)?,
        motor_pos_rad: f(4)?,
        output_pos_rad: f(5)?,
        motor_vel_est_rad_s: f(6)?,
        motor_vel_rad_s: f(7)?,
        output_vel_rad_s: f(8)?,
        torque_cmd_nm: f(9)?,
        torque_sensor_nm: f(10)?,
        output_torque_true_nm: f(11)?,
        state: State::from_name(v[12])
            .ok_or_else(|| format!("column `state`: unknown state `{}`", v[12]))?,
        flags: int(13)?,
        fault: flag(14)?,
        cmd_missing: flag(15)?,
    })
}

impl Iterator for RowReader {
    type Item = Result<Row>;

    fn next(&mut self) -> Option<Result<Row>> {
        let line = match self.lines.next()? {
            Ok(l) => l,
            Err(e) => return Some(Err(anyhow!("reading {}: {e}", self.path.display()))),
        };
        self.line_no += 1;
        Some(
            parse_row(&line)
                .map_err(|e| anyhow!("{} line {}: {e}", self.path.display(), self.line_no)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A setpoint is in motor counts, or in output counts once the card was enabled in a
    /// non-colocated mode (protocol, "Modes"); the log gives output radians either way.
    #[test]
    fn setpoints_follow_the_encoder_the_mode_feeds_back() {
        use controller::proto::{ControlWord, Mode, SetpointMotion};
        let node = NodeId::new(1).unwrap();
        let (motor_cpr, n, output_cpr) = (2304.0, 30.0, 1_048_576.0);
        let mut rec = Recorder::new(node, motor_cpr, n).with_output_encoder(output_cpr);
        let send = |rec: &mut Recorder, m: Message| {
            let f: ClassicFrame = m.encode(node).unwrap();
            rec.observe(0.0, &f).unwrap();
        };
        let sp = Message::SetpointMotion(SetpointMotion {
            position: 100_000,
            velocity_ff: 0,
            torque_ff: 0,
        });
        let tau = std::f64::consts::TAU;
        for (mode, per_count) in [
            (Mode::PositionPdColocated, tau / motor_cpr / n),
            (Mode::PositionPdNonColocated, tau / output_cpr),
            (Mode::ImpedanceColocated, tau / motor_cpr / n),
        ] {
            send(&mut rec, Message::ControlWord(ControlWord::Enable(mode)));
            send(&mut rec, sp);
            assert!(
                (rec.setpoint_pos / (100_000.0 * per_count) - 1.0).abs() < 1e-12,
                "{mode:?}"
            );
        }
    }

    fn row(k: u64) -> Row {
        Row {
            time_s: k as f64 / 1000.0,
            seq: k as u8,
            setpoint_pos_rad: 0.125,
            setpoint_torque_nm: -1.5,
            motor_pos_rad: 3.25,
            output_pos_rad: 0.108333333,
            motor_vel_est_rad_s: 1.5,
            motor_vel_rad_s: -2.25,
            output_vel_rad_s: 0.5,
            torque_cmd_nm: 0.1234,
            torque_sensor_nm: 2.5,
            output_torque_true_nm: 0.25,
            state: State::FaultReaction,
            flags: 5,
            fault: k.is_multiple_of(2),
            cmd_missing: k.is_multiple_of(3),
        }
    }

    #[test]
    fn rows_round_trip_through_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.csv");
        let mut s = Recorder::open_sink(&p, None).unwrap();
        for k in 0..10 {
            write_row(&mut s.out, &row(k)).unwrap();
        }
        s.out.flush().unwrap();
        let back: Vec<Row> = read_rows(&p).unwrap().map(|r| r.unwrap()).collect();
        assert_eq!(back, (0..10).map(row).collect::<Vec<_>>());
    }

    #[test]
    fn a_broken_line_is_named_with_its_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.csv");
        let good = {
            let mut v = Vec::new();
            write_row(&mut v, &row(1)).unwrap();
            String::from_utf8(v).unwrap()
        };
        std::fs::write(
            &p,
            format!(
                "{}\n{good}{}",
                COLUMNS.join(","),
                good.replace("FaultReaction", "Wobbly")
            ),
        )
        .unwrap();
        let rows: Vec<_> = read_rows(&p).unwrap().collect();
        assert!(rows[0].is_ok());
        let e = rows[1].as_ref().unwrap_err().to_string();
        assert!(
            e.contains("bad.csv line 3") && e.contains("`Wobbly`"),
            "{e}"
        );
        std::fs::write(&p, "a,b\n").unwrap();
        let e = read_rows(&p).unwrap_err().to_string();
        assert!(e.contains("line 1"), "{e}");
    }
}
