//! SLCAN, the Lawicel serial-line CAN protocol (CANable/USBtin adapters, Linux `slcand`):
//! CAN frames as ASCII lines over a byte link. The card speaks it over a UART for
//! processor-in-the-loop runs (the firmware's QEMU image), and the host's `slcan` bus backend
//! speaks it to the same image or to a USB adapter, so one codec serves both ends.
//!
//! ```text
//! tiiildd…\r   standard data frame: 3 hex id digits, 1 dlc digit, 2 hex digits per byte
//! Tiiiiiiiildd…\r  extended data frame: 8 hex id digits
//! riiil\r / Riiiiiiiil\r   remote frames (no data)
//! O\r open   L\r open listen-only   C\r close   S0..S8\r bit rate (10k … 1M)
//! \r ok   z\r / Z\r frame queued (t·r / T·R)   \x07 (BELL) error
//! ```
//!
//! A frame line may end with a 4-digit millisecond timestamp (adapters send it after `Z1`);
//! [`parse`] accepts and reports it. Parsing is total: every byte string is either one
//! [`Line`] or one [`Error`] that says what is wrong, and nothing panics — the property tests
//! feed it arbitrary bytes. [`LineReader`] splits a byte stream into lines with a bounded
//! buffer, so a garbled or endless line costs one error and the next line parses again.

use embedded_can::{ExtendedId, Frame, Id, StandardId};

/// Longest line [`LineReader`] keeps: `T`, 8 id digits, dlc, 16 data digits, a 4-digit
/// timestamp (the terminating CR is not stored).
pub const MAX_LINE: usize = 1 + 8 + 1 + 16 + 4;

/// Line terminator.
pub const CR: u8 = b'\r';
/// The error reply.
pub const BELL: u8 = 0x07;

/// A classic CAN frame as SLCAN carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlFrame {
    /// 11-bit (`extended == false`) or 29-bit identifier.
    pub id: u32,
    /// 29-bit identifier.
    pub extended: bool,
    /// Remote (RTR) frame: no data bytes, `dlc` is the requested length.
    pub remote: bool,
    /// Data length 0..=8.
    pub dlc: u8,
    /// Data bytes (zero beyond `dlc`, all zero for a remote frame).
    pub data: [u8; 8],
}

impl SlFrame {
    /// The data bytes (empty for a remote frame).
    pub fn bytes(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            self.data.get(..usize::from(self.dlc)).unwrap_or(&[])
        }
    }

    /// From any `embedded_can` frame; `None` for a data length above 8.
    pub fn from_frame<F: Frame>(f: &F) -> Option<SlFrame> {
        let (id, extended) = match f.id() {
            Id::Standard(s) => (u32::from(s.as_raw()), false),
            Id::Extended(e) => (e.as_raw(), true),
        };
        let dlc = u8::try_from(f.dlc()).ok().filter(|d| *d <= 8)?;
        let mut data = [0u8; 8];
        if !f.is_remote_frame() {
            let src = f.data();
            data.get_mut(..src.len())?.copy_from_slice(src);
        }
        Some(SlFrame {
            id,
            extended,
            remote: f.is_remote_frame(),
            dlc,
            data,
        })
    }

    /// Into any `embedded_can` frame type (`None` if that type refuses it).
    pub fn to_frame<F: Frame>(&self) -> Option<F> {
        let id: Id = if self.extended {
            ExtendedId::new(self.id)?.into()
        } else {
            StandardId::new(u16::try_from(self.id).ok()?)?.into()
        };
        if self.remote {
            F::new_remote(id, usize::from(self.dlc))
        } else {
            F::new(id, self.bytes())
        }
    }
}

/// CAN bit rates of the `S` command.
pub const BITRATES: [u32; 9] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

/// One SLCAN line, from either side of the link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Line {
    /// A frame (`t`, `T`, `r`, `R`), with the adapter's timestamp (ms) if it sent one.
    Frame(SlFrame, Option<u16>),
    /// `O`: open the channel.
    Open,
    /// `L`: open listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Sn`: bit rate index 0..=8 (see [`BITRATES`]).
    Bitrate(u8),
    /// An empty line: the reply "ok".
    Ok,
    /// `z` (`extended == false`) or `Z`: the reply "frame queued for transmission".
    Queued {
        /// `Z`: the frame was extended.
        extended: bool,
    },
    /// BELL: the reply "error".
    Error,
}

/// Why a line is not SLCAN.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// The first byte is no command this codec knows.
    UnknownCommand(u8),
    /// A character that should be a hex digit is not; `at` is its offset in the line.
    NotHex {
        /// Offset in the line.
        at: u8,
    },
    /// The data length digit is above 8.
    DlcTooLarge(u8),
    /// A standard id above 0x7FF or an extended id above 0x1FFF_FFFF.
    IdOutOfRange(u32),
    /// The line is not as long as its command and dlc say (nor that plus a timestamp).
    Length {
        /// Bytes expected without a timestamp.
        expected: u8,
        /// Bytes present.
        got: u8,
    },
    /// A bit rate index above 8.
    BadBitrate(u8),
    /// The line was longer than [`MAX_LINE`] (dropped up to its end).
    TooLong,
}

fn hex_digit(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b.wrapping_sub(b'0')),
        b'a'..=b'f' => Some(b.wrapping_sub(b'a').wrapping_add(10)),
        b'A'..=b'F' => Some(b.wrapping_sub(b'A').wrapping_add(10)),
        _ => None,
    }
}

/// `digits` hex digits of `line` from `at` (at most 8, so the value fits a u32).
fn hex(line: &[u8], at: usize, digits: usize) -> Result<u32, Error> {
    let mut v = 0u32;
    for i in 0..digits.min(8) {
        let pos = at.wrapping_add(i);
        let d = line
            .get(pos)
            .copied()
            .and_then(hex_digit)
            .ok_or(Error::NotHex {
                at: u8::try_from(pos).unwrap_or(u8::MAX),
            })?;
        v = v.wrapping_shl(4) | u32::from(d);
    }
    Ok(v)
}

fn len_u8(n: usize) -> u8 {
    u8::try_from(n).unwrap_or(u8::MAX)
}

/// Parses one line without its terminating CR (a lone BELL is a line of its own).
pub fn parse(line: &[u8]) -> Result<Line, Error> {
    let Some((&cmd, rest)) = line.split_first() else {
        return Ok(Line::Ok);
    };
    let simple = |l: Line| {
        if rest.is_empty() {
            Ok(l)
        } else {
            Err(Error::Length {
                expected: 1,
                got: len_u8(line.len()),
            })
        }
    };
    match cmd {
        b't' | b'T' | b'r' | b'R' => parse_frame(line, cmd),
        b'O' => simple(Line::Open),
        b'L' => simple(Line::ListenOnly),
        b'C' => simple(Line::Close),
        b'z' => simple(Line::Queued { extended: false }),
        b'Z' => simple(Line::Queued { extended: true }),
        BELL => simple(Line::Error),
        b'S' => match rest {
            [d @ b'0'..=b'8'] => Ok(Line::Bitrate(d.wrapping_sub(b'0'))),
            [d] => Err(Error::BadBitrate(*d)),
            _ => Err(Error::Length {
                expected: 2,
                got: len_u8(line.len()),
            }),
        },
        other => Err(Error::UnknownCommand(other)),
    }
}

fn parse_frame(line: &[u8], cmd: u8) -> Result<Line, Error> {
    let extended = cmd == b'T' || cmd == b'R';
    let remote = cmd == b'r' || cmd == b'R';
    // Command, identifier digits, length digit, data: small constants, so the sums below
    // cannot overflow (wrapping only to satisfy the no-unchecked-arithmetic lint).
    let (id_digits, dlc_at): (usize, usize) = if extended { (8, 9) } else { (3, 4) };
    let data_at = dlc_at.wrapping_add(1);
    if line.len() <= dlc_at {
        return Err(Error::Length {
            expected: len_u8(data_at),
            got: len_u8(line.len()),
        });
    }
    let id = hex(line, 1, id_digits)?;
    let max = if extended { 0x1FFF_FFFF } else { 0x7FF };
    if id > max {
        return Err(Error::IdOutOfRange(id));
    }
    let dlc = hex(line, dlc_at, 1)?;
    if dlc > 8 {
        return Err(Error::DlcTooLarge(len_u8(dlc as usize)));
    }
    let dlc = dlc as usize;
    let data_bytes = if remote { 0 } else { dlc };
    let expected = data_at.wrapping_add(data_bytes.wrapping_mul(2));
    let stamp = match line.len().checked_sub(expected) {
        Some(0) => None,
        Some(4) => Some(hex(line, expected, 4)? as u16),
        _ => {
            return Err(Error::Length {
                expected: len_u8(expected),
                got: len_u8(line.len()),
            })
        }
    };
    let mut data = [0u8; 8];
    for (i, b) in data.iter_mut().enumerate().take(data_bytes) {
        *b = hex(line, data_at.wrapping_add(i.wrapping_mul(2)), 2)? as u8;
    }
    Ok(Line::Frame(
        SlFrame {
            id,
            extended,
            remote,
            dlc: dlc as u8,
            data,
        },
        stamp,
    ))
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// A formatted line: the bytes to send, CR included (a BELL has none).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Formatted {
    buf: [u8; MAX_LINE + 1],
    len: u8,
}

impl Formatted {
    /// The bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buf.get(..usize::from(self.len)).unwrap_or(&[])
    }

    fn push(&mut self, b: u8) {
        if let Some(slot) = self.buf.get_mut(usize::from(self.len)) {
            *slot = b;
            self.len = self.len.wrapping_add(1);
        }
    }

    fn push_hex(&mut self, v: u32, digits: u32) {
        for i in (0..digits).rev() {
            let nib = (v.wrapping_shr(i.wrapping_mul(4)) & 0xF) as usize;
            self.push(HEX.get(nib).copied().unwrap_or(b'0'));
        }
    }
}

/// Formats `line` as it goes on the wire (upper-case hex, as `slcand` and adapters write it).
pub fn format(line: &Line) -> Formatted {
    let mut f = Formatted {
        buf: [0; MAX_LINE + 1],
        len: 0,
    };
    match *line {
        Line::Frame(fr, stamp) => {
            let cmd = match (fr.extended, fr.remote) {
                (false, false) => b't',
                (true, false) => b'T',
                (false, true) => b'r',
                (true, true) => b'R',
            };
            f.push(cmd);
            let (mask, digits) = if fr.extended {
                (0x1FFF_FFFF, 8)
            } else {
                (0x7FF, 3)
            };
            f.push_hex(fr.id & mask, digits);
            let dlc = fr.dlc.min(8);
            f.push_hex(u32::from(dlc), 1);
            if !fr.remote {
                for b in fr.data.iter().take(usize::from(dlc)) {
                    f.push_hex(u32::from(*b), 2);
                }
            }
            if let Some(t) = stamp {
                f.push_hex(u32::from(t), 4);
            }
        }
        Line::Open => f.push(b'O'),
        Line::ListenOnly => f.push(b'L'),
        Line::Close => f.push(b'C'),
        Line::Bitrate(i) => {
            f.push(b'S');
            f.push(b'0'.wrapping_add(i.min(8)));
        }
        Line::Ok => {}
        Line::Queued { extended } => f.push(if extended { b'Z' } else { b'z' }),
        Line::Error => {
            f.push(BELL);
            return f;
        }
    }
    f.push(CR);
    f
}

/// Splits a byte stream into lines: CR ends a line, LF is ignored (some tools send CR LF), a
/// BELL is a line by itself. A line longer than [`MAX_LINE`] is dropped up to its CR and
/// reported once as [`Error::TooLong`].
#[derive(Clone, Copy, Debug)]
pub struct LineReader {
    buf: [u8; MAX_LINE],
    len: u8,
    overflow: bool,
}

impl Default for LineReader {
    fn default() -> Self {
        Self::new()
    }
}

impl LineReader {
    /// Empty.
    pub const fn new() -> Self {
        LineReader {
            buf: [0; MAX_LINE],
            len: 0,
            overflow: false,
        }
    }

    /// Feeds one byte; a completed line comes back parsed.
    pub fn push(&mut self, b: u8) -> Option<Result<Line, Error>> {
        match b {
            CR => {
                let line = self.buf.get(..usize::from(self.len)).unwrap_or(&[]);
                let r = if self.overflow {
                    Err(Error::TooLong)
                } else {
                    parse(line)
                };
                self.len = 0;
                self.overflow = false;
                Some(r)
            }
            b'\n' => None,
            BELL if self.len == 0 && !self.overflow => Some(Ok(Line::Error)),
            _ => {
                match self.buf.get_mut(usize::from(self.len)) {
                    Some(slot) if !self.overflow => {
                        *slot = b;
                        self.len = self.len.wrapping_add(1);
                    }
                    _ => self.overflow = true,
                }
                None
            }
        }
    }

    /// Bytes of the unfinished line.
    pub fn pending(&self) -> usize {
        usize::from(self.len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fr(id: u32, extended: bool, remote: bool, data: &[u8]) -> SlFrame {
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        SlFrame {
            id,
            extended,
            remote,
            dlc: data.len() as u8,
            data: if remote { [0; 8] } else { d },
        }
    }

    #[test]
    fn worked_examples() {
        assert_eq!(
            parse(b"t1232AABB"),
            Ok(Line::Frame(fr(0x123, false, false, &[0xAA, 0xBB]), None))
        );
        assert_eq!(
            parse(b"T1FFFFFFF0"),
            Ok(Line::Frame(fr(0x1FFF_FFFF, true, false, &[]), None))
        );
        let mut r = fr(0x7FF, false, true, &[]);
        r.dlc = 4;
        assert_eq!(parse(b"r7FF4"), Ok(Line::Frame(r, None)));
        assert_eq!(
            parse(b"t0011ff1234"),
            Ok(Line::Frame(fr(1, false, false, &[0xFF]), Some(0x1234)))
        );
        assert_eq!(parse(b"S6"), Ok(Line::Bitrate(6)));
        assert_eq!(parse(b"O"), Ok(Line::Open));
        assert_eq!(parse(b"C"), Ok(Line::Close));
        assert_eq!(parse(b""), Ok(Line::Ok));
        assert_eq!(parse(b"z"), Ok(Line::Queued { extended: false }));
        assert_eq!(
            format(&Line::Frame(fr(0x181, false, false, &[1, 2, 0xFE]), None)).as_bytes(),
            b"t18130102FE\r"
        );
        assert_eq!(
            format(&Line::Frame(fr(0x1234_5678, true, false, &[]), None)).as_bytes(),
            b"T123456780\r"
        );
        assert_eq!(format(&Line::Bitrate(6)).as_bytes(), b"S6\r");
        assert_eq!(format(&Line::Error).as_bytes(), &[BELL]);
        assert_eq!(format(&Line::Ok).as_bytes(), b"\r");
    }

    #[test]
    fn bad_lines_say_what_is_wrong() {
        assert_eq!(parse(b"x"), Err(Error::UnknownCommand(b'x')));
        assert_eq!(parse(b"t12G0"), Err(Error::NotHex { at: 3 }));
        assert_eq!(parse(b"t1239"), Err(Error::DlcTooLarge(9)));
        assert_eq!(parse(b"t8000"), Err(Error::IdOutOfRange(0x800)));
        assert_eq!(parse(b"T200000000"), Err(Error::IdOutOfRange(0x2000_0000)));
        assert_eq!(
            parse(b"t1232AA"),
            Err(Error::Length {
                expected: 9,
                got: 7
            })
        );
        assert_eq!(
            parse(b"t12"),
            Err(Error::Length {
                expected: 5,
                got: 3
            })
        );
        assert_eq!(parse(b"S9"), Err(Error::BadBitrate(b'9')));
        assert_eq!(
            parse(b"Ox"),
            Err(Error::Length {
                expected: 1,
                got: 2
            })
        );
    }

    #[test]
    fn reader_splits_resyncs_and_bounds_its_buffer() {
        let mut r = LineReader::new();
        let mut got = heapless::Vec::<Result<Line, Error>, 8>::new();
        let stream: &[u8] = b"t1000\r\nz\r\x07t1";
        for &b in stream {
            if let Some(l) = r.push(b) {
                got.push(l).unwrap();
            }
        }
        assert_eq!(got.len(), 3);
        assert_eq!(got[1], Ok(Line::Queued { extended: false }));
        assert_eq!(got[2], Ok(Line::Error));
        assert_eq!(r.pending(), 2);
        let mut r = LineReader::new();
        let mut last = None;
        for _ in 0..100 {
            last = r.push(b'1').or(last);
        }
        assert_eq!(last, None);
        assert_eq!(r.push(CR), Some(Err(Error::TooLong)));
        assert_eq!(r.push(b'O'), None);
        assert_eq!(r.push(CR), Some(Ok(Line::Open)));
    }
}
