//! candump `-L` log files (the can-utils log format), written and read.
//!
//! One frame per line, exactly as `candump -L` writes and `canplayer` reads:
//!
//! ```text
//! (1700000000.123456) vcan0 123#DEADBEEF
//! (1700000000.123789) vcan0 12345678#0102
//! (1700000000.124000) vcan0 123#R
//! (1700000000.124100) vcan0 123#R4
//! (1700000000.125000) vcan0 20000040#0000000000000000
//! ```
//!
//! * Timestamp: `(SECONDS.MICROSECONDS)`, seconds zero-padded to 10 digits on output
//!   (`%010lu.%06lu` as in candump), exactly 6 fraction digits on input (canplayer reads
//!   the fraction as an integer number of µs, so `(1.5)` would silently mean 1.000005 s;
//!   we reject it instead).
//! * ID: 3 hex digits = 11-bit, 8 hex digits = 29-bit; an 8-digit ID with `CAN_ERR_FLAG`
//!   (0x20000000) is an error frame, kept as a [`BusFault`].
//! * Data: hex byte pairs, uppercase on output; `.` separators between bytes are accepted.
//!   Remote frames: `R` plus an optional DLC digit (`R` = DLC 0), as can-utils ≥ 2020 writes.
//! * Rejected with the line number: CAN FD (`##`), DLC codes above 8 (`_X` suffix), bad
//!   hex, IDs out of range, missing fields ([`read_log`]; [`read_log_skipping`], which
//!   `replay` uses, skips and counts such lines instead, and refuses only a log with no frame). An optional trailing `R`/`T` (direction, written
//!   by newer candump with `-x`) is accepted and ignored. Blank lines are skipped.
//!
//! Checked against can-utils 2020.11 in the `.ci/vm` guest: `candump -L` output parses into
//! the frames sent, and `canplayer -I` replays a log written here.
//!
//! [`CandumpWriter`]/[`CandumpReader`]/[`read_log`] do the I/O; [`CandumpTap`] wraps any
//! [`CanBus`] and records what that node sends and receives.

use std::fmt;
use std::io::{self, BufRead, Write};
use std::path::Path;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use embedded_can::{ExtendedId, Id, StandardId};

use crate::bus::fault::CAN_ERR_FLAG;
use crate::bus::{BusError, BusFault, CanBus, ClassicFrame};

/// A log timestamp: seconds and microseconds (since the Unix epoch for live captures, or
/// since the start of a simulation; canplayer only uses differences).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp {
    /// Whole seconds.
    pub secs: u64,
    /// Microseconds, `0..1_000_000`.
    pub micros: u32,
}

impl Timestamp {
    /// From seconds and microseconds; `None` if `micros >= 1_000_000`.
    pub fn new(secs: u64, micros: u32) -> Option<Self> {
        (micros < 1_000_000).then_some(Self { secs, micros })
    }

    /// From a duration (truncated to whole µs), e.g. simulated time since start.
    pub fn from_duration(d: Duration) -> Self {
        Self {
            secs: d.as_secs(),
            micros: d.subsec_micros(),
        }
    }

    /// From wall-clock time (times before 1970 clamp to 0).
    pub fn from_system_time(t: SystemTime) -> Self {
        Self::from_duration(t.duration_since(UNIX_EPOCH).unwrap_or_default())
    }

    /// The current wall-clock time.
    pub fn now() -> Self {
        Self::from_system_time(SystemTime::now())
    }

    /// As a duration since the zero point.
    pub fn as_duration(&self) -> Duration {
        Duration::new(self.secs, self.micros * 1000)
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:010}.{:06})", self.secs, self.micros)
    }
}

/// What one log line carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoggedFrame {
    /// A data or remote frame.
    Can(ClassicFrame),
    /// An error frame.
    Error(BusFault),
}

impl fmt::Display for LoggedFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoggedFrame::Can(fr) => write!(f, "{fr}"),
            LoggedFrame::Error(e) => {
                write!(f, "{:08X}#", e.can_id())?;
                for b in e.data() {
                    write!(f, "{b:02X}")?;
                }
                Ok(())
            }
        }
    }
}

/// One line of a candump log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogRecord {
    /// When the frame was seen.
    pub time: Timestamp,
    /// Interface name (`vcan0`, `can0`, or any token without whitespace).
    pub iface: String,
    /// The frame.
    pub frame: LoggedFrame,
}

impl fmt::Display for LogRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {} {}", self.time, self.iface, self.frame)
    }
}

/// A parse or read error, with the 1-based line number.
#[derive(Debug, thiserror::Error)]
#[error("candump log line {line}: {message}{}", text.as_deref().map(|t| format!(" (in `{t}`)")).unwrap_or_default())]
pub struct CandumpError {
    /// 1-based line number (0 for an error opening the file).
    pub line: usize,
    /// What is wrong.
    pub message: String,
    /// The offending line, if it could be read.
    pub text: Option<String>,
    /// Underlying I/O error, if any.
    #[source]
    pub io: Option<io::Error>,
}

impl CandumpError {
    fn at(line: usize, text: &str, message: impl Into<String>) -> Self {
        Self {
            line,
            message: message.into(),
            text: Some(text.to_string()),
            io: None,
        }
    }
}

fn parse_hex_byte(s: &[u8]) -> Option<u8> {
    let h = |c: u8| (c as char).to_digit(16).map(|d| d as u8);
    Some(h(s[0])? << 4 | h(s[1])?)
}

fn parse_timestamp(tok: &str) -> Result<Timestamp, String> {
    let bad = || {
        format!(
            "bad timestamp `{tok}`: expected (SECONDS.MICROSECONDS) with exactly 6 fraction digits"
        )
    };
    let inner = tok
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(bad)?;
    let (s, us) = inner.split_once('.').ok_or_else(bad)?;
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    if us.len() != 6 || !us.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let secs = s.parse::<u64>().map_err(|_| bad())?;
    let micros = us.parse::<u32>().map_err(|_| bad())?;
    Ok(Timestamp { secs, micros })
}

/// Parses the `ID#DATA` part.
pub fn parse_frame(tok: &str) -> Result<LoggedFrame, String> {
    if tok.contains("##") {
        return Err(format!(
            "CAN FD frame `{tok}` (##): only classic CAN is supported"
        ));
    }
    let (id_s, data_s) = tok
        .split_once('#')
        .ok_or_else(|| format!("frame `{tok}` has no '#' between ID and data"))?;
    if !id_s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("CAN ID `{id_s}` is not hexadecimal"));
    }
    let raw = match id_s.len() {
        3 | 8 => u32::from_str_radix(id_s, 16).map_err(|e| e.to_string())?,
        n => {
            return Err(format!(
                "CAN ID `{id_s}` has {n} hex digits; expected 3 (11-bit) or 8 (29-bit)"
            ))
        }
    };
    let id: Id = if id_s.len() == 3 {
        StandardId::new(raw as u16)
            .ok_or_else(|| format!("11-bit CAN ID 0x{raw:03X} is above 0x7FF"))?
            .into()
    } else if raw & CAN_ERR_FLAG != 0 {
        if raw & !(CAN_ERR_FLAG | 0x1FFF_FFFF) != 0 {
            return Err(format!(
                "error frame ID 0x{raw:08X} has EFF/RTR flag bits set"
            ));
        }
        let data = parse_data(data_s)?;
        return Ok(LoggedFrame::Error(BusFault::from_raw(raw, &data)));
    } else {
        ExtendedId::new(raw)
            .ok_or_else(|| format!("29-bit CAN ID 0x{raw:08X} is above 0x1FFFFFFF"))?
            .into()
    };
    if let Some(rest) = data_s.strip_prefix(['R', 'r']) {
        let dlc = match rest {
            "" => 0,
            d if d.len() == 1 && d.as_bytes()[0].is_ascii_digit() => {
                usize::from(d.as_bytes()[0] - b'0')
            }
            d => return Err(format!("remote frame DLC `{d}` is not a digit 0..8")),
        };
        return ClassicFrame::new_rtr(id, dlc)
            .map(LoggedFrame::Can)
            .ok_or_else(|| format!("remote frame DLC {dlc} is above 8"));
    }
    let data = parse_data(data_s)?;
    ClassicFrame::new_data(id, &data)
        .map(LoggedFrame::Can)
        .ok_or_else(|| format!("{} data bytes; classic CAN carries at most 8", data.len()))
}

fn parse_data(s: &str) -> Result<Vec<u8>, String> {
    if s.contains('_') {
        return Err(format!(
            "data `{s}` has a `_` DLC suffix (DLC 9..15); only DLC 0..8 is supported"
        ));
    }
    let mut out = Vec::with_capacity(8);
    let b = s.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'.' {
            i += 1;
            continue;
        }
        if i + 1 >= b.len() {
            return Err(format!("data `{s}` has an odd number of hex digits"));
        }
        let byte = parse_hex_byte(&b[i..i + 2])
            .ok_or_else(|| format!("data `{s}` is not hexadecimal at offset {i}"))?;
        out.push(byte);
        if out.len() > 8 {
            return Err(format!("data `{s}` has more than 8 bytes"));
        }
        i += 2;
    }
    Ok(out)
}

/// Parses one line. `Ok(None)` for a blank line; `line_no` is used in errors.
pub fn parse_line(line: &str, line_no: usize) -> Result<Option<LogRecord>, CandumpError> {
    let text = line.trim_end_matches(['\r', '\n']);
    if text.trim().is_empty() {
        return Ok(None);
    }
    let mut toks = text.split_ascii_whitespace();
    let (Some(ts), Some(iface), Some(frame)) = (toks.next(), toks.next(), toks.next()) else {
        return Err(CandumpError::at(
            line_no,
            text,
            "expected `(SECONDS.MICROS) IFACE ID#DATA`",
        ));
    };
    match toks.next() {
        None | Some("R") | Some("T") => {}
        Some(extra) => {
            return Err(CandumpError::at(
                line_no,
                text,
                format!("unexpected trailing field `{extra}`"),
            ))
        }
    }
    if toks.next().is_some() {
        return Err(CandumpError::at(line_no, text, "too many fields"));
    }
    let time = parse_timestamp(ts).map_err(|m| CandumpError::at(line_no, text, m))?;
    let frame = parse_frame(frame).map_err(|m| CandumpError::at(line_no, text, m))?;
    Ok(Some(LogRecord {
        time,
        iface: iface.to_string(),
        frame,
    }))
}

/// Iterates over the records of a candump log; blank lines are skipped.
#[derive(Debug)]
pub struct CandumpReader<R> {
    input: R,
    line_no: usize,
    buf: String,
}

impl<R: BufRead> CandumpReader<R> {
    /// Reads from any buffered reader.
    pub fn new(input: R) -> Self {
        Self {
            input,
            line_no: 0,
            buf: String::new(),
        }
    }
}

impl<R: BufRead> Iterator for CandumpReader<R> {
    type Item = Result<LogRecord, CandumpError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            self.buf.clear();
            self.line_no += 1;
            match self.input.read_line(&mut self.buf) {
                Ok(0) => return None,
                Ok(_) => match parse_line(&self.buf, self.line_no) {
                    Ok(Some(r)) => return Some(Ok(r)),
                    Ok(None) => continue,
                    Err(e) => return Some(Err(e)),
                },
                Err(e) => {
                    return Some(Err(CandumpError {
                        line: self.line_no,
                        message: format!("read failed: {e}"),
                        text: None,
                        io: Some(e),
                    }))
                }
            }
        }
    }
}

/// Reads a whole log file; the first bad line is the error.
pub fn read_log(path: &Path) -> Result<Vec<LogRecord>, CandumpError> {
    let f = std::fs::File::open(path).map_err(|e| CandumpError {
        line: 0,
        message: format!("cannot open {}: {e}", path.display()),
        text: None,
        io: Some(e),
    })?;
    CandumpReader::new(io::BufReader::new(f)).collect()
}

/// A log read by [`read_log_skipping`]: its frames, and the lines that were not frames.
#[derive(Debug)]
pub struct SkippingLog {
    /// The frames, in file order.
    pub records: Vec<LogRecord>,
    /// CAN FD lines (`##`), skipped: only classic CAN is decoded.
    pub fd_lines: usize,
    /// Other lines that do not parse, skipped, each with its line number and reason.
    pub bad_lines: Vec<CandumpError>,
}

impl SkippingLog {
    /// A one-line summary of what was skipped (`None` when nothing was), for stderr.
    pub fn skipped_note(&self, file: &Path) -> Option<String> {
        if self.fd_lines == 0 && self.bad_lines.is_empty() {
            return None;
        }
        let mut s = format!(
            "note: {}: skipped {} line(s): {} CAN FD (##), {} unparseable",
            file.display(),
            self.fd_lines + self.bad_lines.len(),
            self.fd_lines,
            self.bad_lines.len()
        );
        if let Some(e) = self.bad_lines.first() {
            s.push_str(&format!("; the first: {e}"));
        }
        Some(s)
    }
}

/// Why [`read_log_skipping`] has no frames to give.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file could not be opened or read.
    #[error("{file}: {source}")]
    Read {
        /// File.
        file: String,
        /// What failed (with the line, for a read error).
        #[source]
        source: CandumpError,
    },
    /// Not one frame in the file.
    #[error(
        "{file}: no CAN frame in the log ({lines} line(s): {fd} CAN FD (##), {bad} unparseable); \
         expected candump -L lines `(SECONDS.MICROS) IFACE ID#DATA`{first}"
    )]
    NoFrames {
        /// File.
        file: String,
        /// Lines in the file.
        lines: usize,
        /// CAN FD lines skipped.
        fd: usize,
        /// Other lines that did not parse.
        bad: usize,
        /// The first unparseable line's error, as `; the first: …` (empty if none).
        first: String,
    },
}

/// Reads a whole log file, skipping (and counting) CAN FD lines and lines that do not parse,
/// so one odd line in a long capture does not lose the rest. A file with no frame at all is
/// the error, as is a failure to open or read it.
pub fn read_log_skipping(path: &Path) -> Result<SkippingLog, LogError> {
    let file = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| LogError::Read {
        file: file.clone(),
        source: CandumpError {
            line: 0,
            message: format!("cannot open: {e}"),
            text: None,
            io: Some(e),
        },
    })?;
    let mut log = SkippingLog {
        records: Vec::new(),
        fd_lines: 0,
        bad_lines: Vec::new(),
    };
    let mut reader = CandumpReader::new(io::BufReader::new(f));
    for r in reader.by_ref() {
        match r {
            Ok(rec) => log.records.push(rec),
            Err(e) if e.io.is_some() => {
                return Err(LogError::Read {
                    file: file.clone(),
                    source: e,
                })
            }
            Err(e) if e.text.as_deref().is_some_and(|t| t.contains("##")) => log.fd_lines += 1,
            Err(e) => log.bad_lines.push(e),
        }
    }
    if log.records.is_empty() {
        return Err(LogError::NoFrames {
            file,
            // The reader counted the end-of-file read as a line.
            lines: reader.line_no.saturating_sub(1),
            fd: log.fd_lines,
            bad: log.bad_lines.len(),
            first: log
                .bad_lines
                .first()
                .map(|e| format!("; the first: {e}"))
                .unwrap_or_default(),
        });
    }
    Ok(log)
}

/// Writes candump `-L` lines.
#[derive(Debug)]
pub struct CandumpWriter<W: Write> {
    out: W,
}

impl<W: Write> CandumpWriter<W> {
    /// Writes to `out` (wrap files in a `BufWriter`).
    pub fn new(out: W) -> Self {
        Self { out }
    }

    /// Writes one record. The interface must be a non-empty token without whitespace.
    pub fn write(&mut self, rec: &LogRecord) -> io::Result<()> {
        if rec.iface.is_empty() || rec.iface.chars().any(char::is_whitespace) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("interface name `{}` is empty or has whitespace", rec.iface),
            ));
        }
        writeln!(self.out, "{rec}")
    }

    /// Writes one data/remote frame.
    pub fn write_frame(
        &mut self,
        time: Timestamp,
        iface: &str,
        frame: &ClassicFrame,
    ) -> io::Result<()> {
        self.write(&LogRecord {
            time,
            iface: iface.to_string(),
            frame: LoggedFrame::Can(*frame),
        })
    }

    /// Writes one error frame.
    pub fn write_fault(
        &mut self,
        time: Timestamp,
        iface: &str,
        fault: &BusFault,
    ) -> io::Result<()> {
        self.write(&LogRecord {
            time,
            iface: iface.to_string(),
            frame: LoggedFrame::Error(*fault),
        })
    }

    /// Flushes the underlying writer.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// Returns the underlying writer.
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// Where a [`CandumpTap`] gets its timestamps.
pub type Clock = Box<dyn FnMut() -> Timestamp + Send>;

/// A [`CanBus`] wrapper that logs every frame it sends and receives (and every error frame
/// it receives) as candump `-L` lines: a node-local recorder.
///
/// The default clock is wall time ([`Timestamp::now`]); pass a simulated clock with
/// [`CandumpTap::with_clock`] for reproducible logs. Write errors do not disturb the bus
/// traffic; the first one is kept and returned by [`CandumpTap::finish`].
pub struct CandumpTap<B, W: Write> {
    inner: B,
    writer: CandumpWriter<W>,
    iface: String,
    clock: Clock,
    write_error: Option<io::Error>,
}

impl<B, W: Write> fmt::Debug for CandumpTap<B, W> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CandumpTap")
            .field("iface", &self.iface)
            .field("write_error", &self.write_error)
            .finish_non_exhaustive()
    }
}

impl<B: CanBus, W: Write + Send> CandumpTap<B, W> {
    /// Logs under the interface name `iface` with wall-clock timestamps.
    pub fn new(inner: B, out: W, iface: &str) -> Self {
        Self::with_clock(inner, out, iface, Box::new(Timestamp::now))
    }

    /// Logs with timestamps from `clock` (e.g. simulated time).
    pub fn with_clock(inner: B, out: W, iface: &str, clock: Clock) -> Self {
        Self {
            inner,
            writer: CandumpWriter::new(out),
            iface: iface.to_string(),
            clock,
            write_error: None,
        }
    }

    fn log(&mut self, frame: LoggedFrame) {
        if self.write_error.is_some() {
            return;
        }
        let rec = LogRecord {
            time: (self.clock)(),
            iface: self.iface.clone(),
            frame,
        };
        if let Err(e) = self.writer.write(&rec) {
            self.write_error = Some(e);
        }
    }

    /// Flushes and returns the bus and the writer, or the first write error.
    pub fn finish(mut self) -> io::Result<(B, W)> {
        if let Some(e) = self.write_error.take() {
            return Err(e);
        }
        self.writer.flush()?;
        Ok((self.inner, self.writer.into_inner()))
    }
}

impl<B: CanBus, W: Write + Send> CanBus for CandumpTap<B, W> {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        self.inner.send(frame)?;
        self.log(LoggedFrame::Can(*frame));
        Ok(())
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        match self.inner.recv_timeout(timeout) {
            Ok(Some(f)) => {
                self.log(LoggedFrame::Can(f));
                Ok(Some(f))
            }
            Err(e) => {
                if let Some(fault) = e.fault() {
                    self.log(LoggedFrame::Error(*fault));
                }
                Err(e)
            }
            other => other,
        }
    }

    fn name(&self) -> &str {
        self.inner.name()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn one(line: &str) -> LogRecord {
        parse_line(line, 1).unwrap().unwrap()
    }

    #[test]
    fn reads_can_utils_lines() {
        let r = one("(1700000000.123456) vcan0 123#DEADBEEF");
        assert_eq!(r.time, Timestamp::new(1_700_000_000, 123_456).unwrap());
        assert_eq!(r.iface, "vcan0");
        assert_eq!(
            r.frame,
            LoggedFrame::Can(ClassicFrame::std(0x123, &[0xDE, 0xAD, 0xBE, 0xEF]).unwrap())
        );
        let r = one("(0000000001.000001) can0 1ABCDEF0#01.02.03\n");
        assert_eq!(
            r.frame,
            LoggedFrame::Can(ClassicFrame::ext(0x1ABC_DEF0, &[1, 2, 3]).unwrap())
        );
        let r = one("(1.000000) can0 123#R");
        assert_eq!(
            r.frame,
            LoggedFrame::Can(ClassicFrame::new_rtr(StandardId::new(0x123).unwrap(), 0).unwrap())
        );
        let r = one("(1.000000) can0 00000123#R8 T");
        assert_eq!(
            r.frame,
            LoggedFrame::Can(ClassicFrame::new_rtr(ExtendedId::new(0x123).unwrap(), 8).unwrap())
        );
        let r = one("(1.000000) can0 7FF#");
        assert_eq!(
            r.frame,
            LoggedFrame::Can(ClassicFrame::std(0x7FF, &[]).unwrap())
        );
        let r = one("(1.000000) vcan0 20000040#0000000000000000");
        assert_eq!(r.frame, LoggedFrame::Error(BusFault::bus_off()));
        assert!(parse_line("   \n", 3).unwrap().is_none());
    }

    #[test]
    fn writes_can_utils_lines() {
        let mut w = CandumpWriter::new(Vec::new());
        let t = Timestamp::new(1_700_000_000, 123_456).unwrap();
        w.write_frame(
            t,
            "vcan0",
            &ClassicFrame::std(0x123, &[0xDE, 0xAD, 0xBE, 0xEF]).unwrap(),
        )
        .unwrap();
        w.write_frame(
            Timestamp::new(5, 7).unwrap(),
            "can0",
            &ClassicFrame::new_rtr(ExtendedId::new(0x12345678).unwrap(), 5).unwrap(),
        )
        .unwrap();
        w.write_fault(t, "vcan0", &BusFault::no_ack()).unwrap();
        assert!(w
            .write_frame(t, "bad name", &ClassicFrame::std(1, &[]).unwrap())
            .is_err());
        let s = String::from_utf8(w.into_inner()).unwrap();
        assert_eq!(
            s,
            "(1700000000.123456) vcan0 123#DEADBEEF\n\
             (0000000005.000007) can0 12345678#R5\n\
             (1700000000.123456) vcan0 20000020#0000000000000000\n"
        );
    }

    #[test]
    fn errors_name_the_line() {
        let input = "(1.000000) vcan0 123#00\n\n(1.000001) vcan0 123#0G\n";
        let res: Vec<_> = CandumpReader::new(input.as_bytes()).collect();
        assert!(res[0].is_ok());
        let e = res[1].as_ref().unwrap_err();
        assert_eq!(e.line, 3);
        let msg = e.to_string();
        assert!(msg.starts_with("candump log line 3: "), "{msg}");
        assert!(msg.contains("not hexadecimal"), "{msg}");

        for (line, needle) in [
            ("(1.5) vcan0 123#00", "6 fraction digits"),
            ("1.000000 vcan0 123#00", "bad timestamp"),
            ("(1.000000) vcan0 1234#00", "4 hex digits"),
            ("(1.000000) vcan0 800#00", "above 0x7FF"),
            ("(1.000000) vcan0 4FFFFFFF#00", "above 0x1FFFFFFF"),
            ("(1.000000) vcan0 123##1112233", "CAN FD"),
            ("(1.000000) vcan0 123#001", "odd number"),
            ("(1.000000) vcan0 123#000102030405060708", "more than 8"),
            ("(1.000000) vcan0 123#1122334455667788_E", "DLC"),
            ("(1.000000) vcan0 123#R9", "above 8"),
            ("(1.000000) vcan0 123", "no '#'"),
            ("(1.000000) vcan0", "expected"),
            ("(1.000000) vcan0 123#00 X", "trailing"),
        ] {
            let e = parse_line(line, 7).unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains("line 7"), "{msg}");
            assert!(msg.contains(needle), "`{line}` -> {msg}");
        }
    }

    fn any_record() -> impl Strategy<Value = LogRecord> {
        let frame = prop_oneof![
            (0u16..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8))
                .prop_map(|(id, d)| LoggedFrame::Can(ClassicFrame::std(id, &d).unwrap())),
            (
                0u32..=0x1FFF_FFFF,
                proptest::collection::vec(any::<u8>(), 0..=8)
            )
                .prop_map(|(id, d)| LoggedFrame::Can(ClassicFrame::ext(id, &d).unwrap())),
            (any::<bool>(), 0u32..=0x1FFF_FFFF, 0usize..=8).prop_map(|(ext, id, dlc)| {
                let id: Id = if ext {
                    ExtendedId::new(id).unwrap().into()
                } else {
                    StandardId::new((id & 0x7FF) as u16).unwrap().into()
                };
                LoggedFrame::Can(ClassicFrame::new_rtr(id, dlc).unwrap())
            }),
            (1u32..=0x3FF, any::<[u8; 8]>())
                .prop_map(|(c, d)| LoggedFrame::Error(BusFault::from_raw(c, &d))),
        ];
        (
            0u64..=9_999_999_999,
            0u32..1_000_000,
            "[a-z][a-z0-9_.-]{0,14}",
            frame,
        )
            .prop_map(|(secs, micros, iface, frame)| LogRecord {
                time: Timestamp { secs, micros },
                iface,
                frame,
            })
    }

    proptest! {
        #[test]
        fn round_trip(recs in proptest::collection::vec(any_record(), 0..40)) {
            let mut w = CandumpWriter::new(Vec::new());
            for r in &recs {
                w.write(r).unwrap();
            }
            let bytes = w.into_inner();
            let back: Vec<LogRecord> = CandumpReader::new(&bytes[..])
                .collect::<Result<_, _>>()
                .unwrap();
            prop_assert_eq!(back, recs);
        }

        /// Garbage never panics the parser; errors always carry the line number.
        #[test]
        fn garbage_is_an_error_not_a_panic(s in "\\PC{0,60}") {
            if let Err(e) = parse_line(&s, 42) {
                prop_assert!(e.to_string().contains("line 42"));
            }
        }
    }

    #[test]
    fn tap_logs_both_directions_with_a_sim_clock() {
        use crate::bus::InprocHub;
        let hub = InprocHub::new("tap");
        let mut t = 0u64;
        let clock: Clock = Box::new(move || {
            t += 1000;
            Timestamp::from_duration(Duration::from_micros(t))
        });
        let mut a = CandumpTap::with_clock(hub.attach("a"), Vec::new(), "sim0", clock);
        let mut b = hub.attach("b");
        a.send(&ClassicFrame::std(0x10, &[1]).unwrap()).unwrap();
        let got = b.recv_timeout(Duration::from_secs(1)).unwrap().unwrap();
        b.send(&ClassicFrame::std(0x11, got.data()).unwrap())
            .unwrap();
        assert!(a.recv_timeout(Duration::from_secs(1)).unwrap().is_some());
        hub.inject_fault(BusFault::bus_off());
        assert!(a.recv_timeout(Duration::from_secs(1)).is_err());
        let (_, out) = a.finish().unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "(0000000000.001000) sim0 010#01\n\
             (0000000000.002000) sim0 011#01\n\
             (0000000000.003000) sim0 20000040#0000000000000000\n"
        );
    }
}
