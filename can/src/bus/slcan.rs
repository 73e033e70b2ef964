//! The `slcan` bus backend: a CAN node behind a serial line speaking SLCAN (the Lawicel
//! protocol of CANable/USBtin adapters and `slcand`; codec in [`controller::slcan`], shared
//! with the card's firmware).
//!
//! Where the line goes ([`SlcanTarget`]):
//! * a serial device (`slcan:/dev/ttyACM0`, optionally `,BITRATE` in bit/s): put in raw
//!   mode, closed, set to the bit rate (`S8` = 1 Mbit/s by default), opened (`O`);
//! * a Unix socket (`slcan:unix:PATH`) or TCP (`slcan:tcp:HOST:PORT`): QEMU's UART as a
//!   socket chardev, or `socat` in front of anything.
//!
//! A reader thread turns the byte stream into frames and replies, so `recv_timeout` is a
//! channel wait. Replies are counted: `send` returns once the line is written, and
//! [`SlcanBus::wait_acks`] waits for every outstanding `z`/`Z`. In synchronous mode
//! ([`SlcanBus::set_synchronous`]) `send` waits itself; the PIL card relies on that, because
//! its card answers a frame before acknowledging it.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use controller::slcan::{self, Line, LineReader, SlFrame, BITRATES, CR};

use super::{BusError, CanBus, ClassicFrame};

/// How long a command or a frame may wait for its reply.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

/// Where an SLCAN line goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SlcanTarget {
    /// A serial device and the CAN bit rate to set.
    Device {
        /// Path, e.g. `/dev/ttyACM0`.
        path: String,
        /// CAN bit rate, bit/s (one of [`BITRATES`]).
        bitrate: u32,
    },
    /// A Unix stream socket.
    Unix(String),
    /// A TCP address `HOST:PORT`.
    Tcp(String),
}

impl SlcanTarget {
    /// Parses what follows `slcan:`: `unix:PATH`, `tcp:HOST:PORT`, or `DEVICE[,BITRATE]`.
    pub fn parse(rest: &str) -> Result<Self, String> {
        if let Some(p) = rest.strip_prefix("unix:") {
            if p.is_empty() {
                return Err("empty socket path after `unix:`".into());
            }
            return Ok(SlcanTarget::Unix(p.into()));
        }
        if let Some(a) = rest.strip_prefix("tcp:") {
            if !a.contains(':') {
                return Err(format!("`tcp:{a}` needs HOST:PORT"));
            }
            return Ok(SlcanTarget::Tcp(a.into()));
        }
        let (path, rate) = match rest.split_once(',') {
            Some((p, r)) => (p, Some(r)),
            None => (rest, None),
        };
        if path.is_empty() {
            return Err(
                "no device; e.g. slcan:/dev/ttyACM0, slcan:/dev/ttyACM0,500000, \
                        slcan:unix:/tmp/card.sock or slcan:tcp:127.0.0.1:5555"
                    .into(),
            );
        }
        let bitrate = match rate {
            None => 1_000_000,
            Some(r) => {
                let v: u32 = r
                    .trim()
                    .parse()
                    .map_err(|_| format!("bit rate `{r}` is not a number of bit/s"))?;
                if !BITRATES.contains(&v) {
                    return Err(format!(
                        "bit rate {v} is not one SLCAN can set; one of {BITRATES:?}"
                    ));
                }
                v
            }
        };
        Ok(SlcanTarget::Device {
            path: path.into(),
            bitrate,
        })
    }
}

/// What the reader thread hands over.
#[derive(Debug)]
enum Event {
    Frame(ClassicFrame),
    /// `\r`, `z` or `Z`.
    Ack,
    /// BELL.
    Refused,
    /// A line that is not SLCAN (its text) and why.
    Bad(Vec<u8>, slcan::Error),
    /// End of stream or a read error.
    Closed(String),
}

/// Printable form of a line for error messages (control characters escaped).
fn show(line: &[u8]) -> String {
    line.iter()
        .flat_map(|b| std::ascii::escape_default(*b))
        .map(char::from)
        .collect()
}

/// Why a parse failed, in words.
pub fn explain(e: &slcan::Error) -> String {
    match e {
        slcan::Error::UnknownCommand(c) => {
            format!("unknown command `{}`", show(&[*c]))
        }
        slcan::Error::NotHex { at } => format!("character {at} is not a hex digit"),
        slcan::Error::DlcTooLarge(d) => format!("data length {d} is above 8"),
        slcan::Error::IdOutOfRange(id) => format!("identifier {id:#x} is out of range"),
        slcan::Error::Length { expected, got } => format!(
            "{got} characters where its command and length need {expected} (or 4 more with a timestamp)"
        ),
        slcan::Error::BadBitrate(b) => {
            format!("bit rate index `{}` is not 0..=8", show(&[*b]))
        }
        slcan::Error::TooLong => format!("longer than {} characters", slcan::MAX_LINE),
    }
}

/// The reading half of a link; `Ok(None)` is a read timeout (checked against the stop flag).
trait Source: Send {
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>>;
}

struct SocketSource<S: Read + Send>(S);

impl<S: Read + Send> Source for SocketSource<S> {
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match self.0.read(buf) {
            Ok(n) => Ok(Some(n)),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Ok(None)
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(None),
            Err(e) => Err(e),
        }
    }
}

/// A tty in raw mode with VMIN = 0, VTIME = 1: a read returns after 100 ms without data (0
/// bytes, which on a tty is not the end); an unplugged adapter gives an error.
#[cfg(unix)]
struct TtySource(std::fs::File);

#[cfg(unix)]
impl Source for TtySource {
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match self.0.read(buf) {
            Ok(0) => Ok(None),
            Ok(n) => Ok(Some(n)),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(None),
            Err(e) => Err(e),
        }
    }
}

fn reader(mut src: Box<dyn Source>, tx: mpsc::Sender<Event>, stop: Arc<AtomicBool>) {
    let mut lines = LineReader::new();
    let mut raw: Vec<u8> = Vec::new();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let n = match src.read_some(&mut buf) {
            Ok(None) => continue,
            Ok(Some(0)) => {
                let _ = tx.send(Event::Closed("end of stream".into()));
                return;
            }
            Ok(Some(n)) => n,
            Err(e) => {
                let _ = tx.send(Event::Closed(e.to_string()));
                return;
            }
        };
        for &b in &buf[..n] {
            if b != CR && b != b'\n' && raw.len() <= slcan::MAX_LINE {
                raw.push(b);
            }
            let Some(parsed) = lines.push(b) else {
                continue;
            };
            let text = std::mem::take(&mut raw);
            let ev = match parsed {
                Ok(Line::Frame(f, _)) => match f.to_frame::<ClassicFrame>() {
                    Some(fr) => Event::Frame(fr),
                    None => Event::Bad(text, slcan::Error::IdOutOfRange(f.id)),
                },
                Ok(Line::Ok | Line::Queued { .. }) => Event::Ack,
                Ok(Line::Error) => Event::Refused,
                // A command sent to the host is not an answer: a confused peer.
                Ok(other) => Event::Bad(
                    format!("{other:?}").into_bytes(),
                    slcan::Error::UnknownCommand(text.first().copied().unwrap_or(b'?')),
                ),
                Err(e) => Event::Bad(text, e),
            };
            if tx.send(ev).is_err() {
                return;
            }
        }
    }
}

/// A CAN bus reached through an SLCAN line. See the module docs.
pub struct SlcanBus {
    name: String,
    writer: Box<dyn Write + Send>,
    rx: mpsc::Receiver<Event>,
    stop: Arc<AtomicBool>,
    pending_acks: usize,
    queued: VecDeque<ClassicFrame>,
    synchronous: bool,
    closer: Option<Box<dyn FnOnce() + Send>>,
}

impl std::fmt::Debug for SlcanBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlcanBus")
            .field("name", &self.name)
            .field("pending_acks", &self.pending_acks)
            .field("queued", &self.queued.len())
            .field("synchronous", &self.synchronous)
            .finish()
    }
}

impl SlcanBus {
    /// Opens `target`: a device is configured and opened (`C`, `Sn`, `O`); a socket is
    /// opened with `O` (its peer is a card, which needs no bit rate).
    pub fn open(target: &SlcanTarget) -> Result<SlcanBus, BusError> {
        match target {
            SlcanTarget::Device { path, bitrate } => open_device(path, *bitrate),
            SlcanTarget::Unix(p) => {
                #[cfg(unix)]
                {
                    let name = format!("slcan:unix:{p}");
                    let s = std::os::unix::net::UnixStream::connect(p)
                        .map_err(|e| io_err(&name, "connect", e))?;
                    Self::from_unix(s, &name)
                }
                #[cfg(not(unix))]
                {
                    Err(BusError::BadSpec {
                        spec: format!("slcan:unix:{p}"),
                        reason: "Unix sockets need a Unix host".into(),
                    })
                }
            }
            SlcanTarget::Tcp(a) => {
                let name = format!("slcan:tcp:{a}");
                let s = std::net::TcpStream::connect(a).map_err(|e| io_err(&name, "connect", e))?;
                s.set_nodelay(true)
                    .map_err(|e| io_err(&name, "connect", e))?;
                s.set_read_timeout(Some(Duration::from_millis(100)))
                    .map_err(|e| io_err(&name, "connect", e))?;
                let r = s.try_clone().map_err(|e| io_err(&name, "connect", e))?;
                let closer = s.try_clone().map_err(|e| io_err(&name, "connect", e))?;
                let mut bus = Self::start(
                    name,
                    Box::new(SocketSource(r)),
                    Box::new(s),
                    Some(Box::new(move || {
                        let _ = closer.shutdown(std::net::Shutdown::Both);
                    })),
                );
                bus.command(Line::Open)?;
                Ok(bus)
            }
        }
    }

    /// An SLCAN link over a connected Unix stream (QEMU's socket chardev), opened with `O`.
    #[cfg(unix)]
    pub fn from_unix(s: std::os::unix::net::UnixStream, name: &str) -> Result<SlcanBus, BusError> {
        s.set_read_timeout(Some(Duration::from_millis(100)))
            .map_err(|e| io_err(name, "configure", e))?;
        let r = s.try_clone().map_err(|e| io_err(name, "configure", e))?;
        let closer = s.try_clone().map_err(|e| io_err(name, "configure", e))?;
        let mut bus = Self::start(
            name.to_string(),
            Box::new(SocketSource(r)),
            Box::new(s),
            Some(Box::new(move || {
                let _ = closer.shutdown(std::net::Shutdown::Both);
            })),
        );
        bus.command(Line::Open)?;
        Ok(bus)
    }

    fn start(
        name: String,
        src: Box<dyn Source>,
        writer: Box<dyn Write + Send>,
        closer: Option<Box<dyn FnOnce() + Send>>,
    ) -> SlcanBus {
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let st = stop.clone();
        std::thread::Builder::new()
            .name(format!("{name} reader"))
            .spawn(move || reader(src, tx, st))
            .ok();
        SlcanBus {
            name,
            writer,
            rx,
            stop,
            pending_acks: 0,
            queued: VecDeque::new(),
            synchronous: false,
            closer,
        }
    }

    /// In synchronous mode `send` returns only after the peer acknowledged the frame, with
    /// every frame that arrived before the acknowledgement queued for `recv`.
    pub fn set_synchronous(&mut self, on: bool) {
        self.synchronous = on;
    }

    fn err(&self, reason: String) -> BusError {
        BusError::Slcan {
            bus: self.name.clone(),
            reason,
        }
    }

    fn write_line(&mut self, line: &Line) -> Result<(), BusError> {
        let f = slcan::format(line);
        self.writer
            .write_all(f.as_bytes())
            .and_then(|()| self.writer.flush())
            .map_err(|e| io_err(&self.name, "write", e))
    }

    /// Sends a command (`O`, `C`, `Sn`) and waits for its reply.
    pub fn command(&mut self, cmd: Line) -> Result<(), BusError> {
        self.write_line(&cmd)?;
        self.pending_acks += 1;
        self.wait_acks(REPLY_TIMEOUT).map_err(|e| match e {
            BusError::Slcan { bus, reason } => BusError::Slcan {
                bus,
                reason: format!(
                    "command `{}`: {reason}",
                    show(slcan::format(&cmd).as_bytes())
                ),
            },
            other => other,
        })
    }

    /// Handles one event; `Ok(true)` if it was a frame (queued).
    fn handle(&mut self, ev: Event) -> Result<bool, BusError> {
        match ev {
            Event::Frame(f) => {
                self.queued.push_back(f);
                Ok(true)
            }
            Event::Ack => {
                self.pending_acks = self.pending_acks.saturating_sub(1);
                Ok(false)
            }
            Event::Refused => {
                self.pending_acks = self.pending_acks.saturating_sub(1);
                Err(self.err(
                    "the peer refused a line (BELL): the channel is not open, or it could not take the frame"
                        .into(),
                ))
            }
            Event::Bad(text, e) => Err(self.err(format!(
                "bad line `{}` from the peer: {}",
                show(&text),
                explain(&e)
            ))),
            Event::Closed(why) => Err(self.err(format!("the line closed: {why}"))),
        }
    }

    /// Waits until every line sent so far is acknowledged (frames that arrive meanwhile are
    /// queued for `recv`).
    pub fn wait_acks(&mut self, timeout: Duration) -> Result<(), BusError> {
        let deadline = Instant::now() + timeout;
        while self.pending_acks > 0 {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(ev) => {
                    self.handle(ev)?;
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    return Err(self.err(format!(
                        "no reply within {timeout:?} ({} outstanding); is the peer an SLCAN device, and open?",
                        self.pending_acks
                    )))
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(self.err("the reader stopped".into()))
                }
            }
        }
        Ok(())
    }

    /// Lines sent and not yet acknowledged.
    pub fn pending_acks(&self) -> usize {
        self.pending_acks
    }
}

impl CanBus for SlcanBus {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        let f = SlFrame::from_frame(frame).ok_or_else(|| BusError::Unrepresentable {
            bus: self.name.clone(),
            reason: format!("{frame} is not a classic frame"),
        })?;
        self.write_line(&Line::Frame(f, None))?;
        self.pending_acks += 1;
        if self.synchronous {
            self.wait_acks(REPLY_TIMEOUT)?;
        }
        Ok(())
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        // Anything already delivered first (acks are folded in without waiting).
        loop {
            if let Some(f) = self.queued.pop_front() {
                return Ok(Some(f));
            }
            match self.rx.try_recv() {
                Ok(ev) => {
                    self.handle(ev)?;
                }
                Err(_) => break,
            }
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(ev) => {
                    if self.handle(ev)? {
                        return Ok(self.queued.pop_front());
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => return Ok(None),
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(self.err("the reader stopped".into()))
                }
            }
        }
    }

    fn name(&self) -> &str {
        &self.name
    }
}

impl Drop for SlcanBus {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Close the channel politely; a peer that is already gone does not matter here.
        let _ = self
            .writer
            .write_all(slcan::format(&Line::Close).as_bytes());
        let _ = self.writer.flush();
        if let Some(c) = self.closer.take() {
            c();
        }
    }
}

fn io_err(bus: &str, op: &'static str, source: io::Error) -> BusError {
    BusError::Io {
        bus: bus.to_string(),
        op,
        source,
    }
}

#[cfg(unix)]
fn open_device(path: &str, bitrate: u32) -> Result<SlcanBus, BusError> {
    use nix::sys::termios::{self, SetArg, SpecialCharacterIndices};
    use std::os::unix::fs::OpenOptionsExt;

    let name = format!("slcan:{path}");
    if !Path::new(path).exists() {
        return Err(BusError::Slcan {
            bus: name,
            reason: format!(
                "{path} does not exist: plug in the adapter (CANable, USBtin: /dev/ttyACM*, \
                 FTDI-based: /dev/ttyUSB*) or check `ls /dev/tty{{ACM,USB}}*`"
            ),
        });
    }
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(nix::libc::O_NOCTTY)
        .open(path)
        .map_err(|e| io_err(&name, "open", e))?;
    let tty_err = |e: nix::Error| BusError::Slcan {
        bus: name.clone(),
        reason: format!("{path} is not a serial device (termios: {e})"),
    };
    let mut t = termios::tcgetattr(&file).map_err(tty_err)?;
    termios::cfmakeraw(&mut t);
    // USB CDC adapters ignore the line rate; a UART bridge running the Lawicel firmware
    // commonly uses 115 200. A static build (the CI's VM guest) leaves the rate as it is:
    // glibc versions its line-rate functions, which a static link cannot resolve.
    #[cfg(not(target_feature = "crt-static"))]
    termios::cfsetspeed(&mut t, termios::BaudRate::B115200).map_err(tty_err)?;
    t.control_chars[SpecialCharacterIndices::VMIN as usize] = 0;
    t.control_chars[SpecialCharacterIndices::VTIME as usize] = 1;
    termios::tcsetattr(&file, SetArg::TCSANOW, &t).map_err(tty_err)?;
    let _ = termios::tcflush(&file, termios::FlushArg::TCIOFLUSH);
    let r = file.try_clone().map_err(|e| io_err(&name, "open", e))?;
    let mut bus = SlcanBus::start(name, Box::new(TtySource(r)), Box::new(file), None);
    // Close first (an adapter left open by an earlier run refuses `Sn`); its answer does not
    // matter, so it is not counted.
    bus.write_line(&Line::Close)?;
    std::thread::sleep(Duration::from_millis(50));
    while bus.rx.try_recv().is_ok() {}
    let idx = BITRATES.iter().position(|b| *b == bitrate).unwrap_or(8) as u8;
    bus.command(Line::Bitrate(idx))?;
    bus.command(Line::Open)?;
    Ok(bus)
}

#[cfg(not(unix))]
fn open_device(path: &str, _bitrate: u32) -> Result<SlcanBus, BusError> {
    Err(BusError::BadSpec {
        spec: format!("slcan:{path}"),
        reason: "serial devices are supported on Unix hosts".into(),
    })
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use controller::slcan::BELL;
    use std::os::unix::net::UnixStream;

    /// A scripted peer on the other end of a socket pair: answers `O` and frames the way the
    /// PIL card does (frames first, then `z`).
    fn peer(mut s: UnixStream, script: fn(&[u8]) -> Vec<u8>) -> std::thread::JoinHandle<()> {
        std::thread::spawn(move || {
            let mut line = Vec::new();
            let mut b = [0u8; 1];
            while let Ok(1) = s.read(&mut b) {
                if b[0] == CR {
                    let out = script(&line);
                    if s.write_all(&out).is_err() {
                        return;
                    }
                    line.clear();
                } else {
                    line.push(b[0]);
                }
            }
        })
    }

    fn echo_card(line: &[u8]) -> Vec<u8> {
        match line.first() {
            Some(b'O') | Some(b'C') => b"\r".to_vec(),
            Some(b't') => {
                let mut v = b"t7FF0\r".to_vec(); // the answer
                v.extend_from_slice(b"z\r");
                v
            }
            Some(b'x') => b"t12G0\r".to_vec(),
            _ => vec![BELL],
        }
    }

    #[test]
    fn synchronous_send_has_the_answer_queued() {
        let (a, b) = UnixStream::pair().unwrap();
        let _p = peer(b, echo_card);
        let mut bus = SlcanBus::from_unix(a, "test").unwrap();
        bus.set_synchronous(true);
        for _ in 0..3 {
            bus.send(&ClassicFrame::std(0x181, &[1, 2]).unwrap())
                .unwrap();
            assert_eq!(bus.pending_acks(), 0);
            let f = bus.recv_timeout(Duration::ZERO).unwrap().unwrap();
            assert_eq!(f, ClassicFrame::std(0x7FF, &[]).unwrap());
            assert_eq!(bus.recv_timeout(Duration::ZERO).unwrap(), None);
        }
    }

    #[test]
    fn refusals_bad_lines_and_a_closed_line_are_clear_errors() {
        let (a, b) = UnixStream::pair().unwrap();
        let _p = peer(b, echo_card);
        let mut bus = SlcanBus::from_unix(a, "test").unwrap();
        let e = bus.command(Line::Bitrate(6)).unwrap_err().to_string();
        assert!(e.contains("refused") && e.contains("S6"), "{e}");
        bus.writer.write_all(b"x\r").unwrap();
        let e = bus
            .recv_timeout(Duration::from_secs(2))
            .unwrap_err()
            .to_string();
        assert!(e.contains("t12G0") && e.contains("not a hex digit"), "{e}");

        // the peer hangs up
        let (c, d) = UnixStream::pair().unwrap();
        drop(d);
        let mut dead = SlcanBus::start(
            "dead".into(),
            Box::new(SocketSource(c.try_clone().unwrap())),
            Box::new(c),
            None,
        );
        let e = dead
            .recv_timeout(Duration::from_secs(2))
            .unwrap_err()
            .to_string();
        assert!(e.contains("closed"), "{e}");
    }

    #[test]
    fn target_specs() {
        assert_eq!(
            SlcanTarget::parse("/dev/ttyACM0").unwrap(),
            SlcanTarget::Device {
                path: "/dev/ttyACM0".into(),
                bitrate: 1_000_000
            }
        );
        assert_eq!(
            SlcanTarget::parse("/dev/ttyUSB1,500000").unwrap(),
            SlcanTarget::Device {
                path: "/dev/ttyUSB1".into(),
                bitrate: 500_000
            }
        );
        assert_eq!(
            SlcanTarget::parse("unix:/tmp/x").unwrap(),
            SlcanTarget::Unix("/tmp/x".into())
        );
        assert!(SlcanTarget::parse("/dev/x,123")
            .unwrap_err()
            .contains("one of"));
        assert!(SlcanTarget::parse("tcp:nohost").is_err());
        assert!(SlcanTarget::parse("").is_err());
        let e = SlcanBus::open(&SlcanTarget::parse("/dev/no-such-adapter").unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not exist") && e.contains("ttyACM"), "{e}");
        let e = SlcanBus::open(&SlcanTarget::parse("/dev/null").unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a serial device"), "{e}");
    }
}
