//! The replay stream between a host and the QEMU card: fixed 12-byte records, the same
//! format in both directions.
//!
//! ```text
//! byte 0      tag      1 = frame, 2 = idle (the card checks its timeouts), 3 = end of the
//!                      card's answer to one input record, 0 = end of stream
//! byte 1      dlc      frame: data length 0..=8
//! bytes 2..4  id       frame: 11-bit identifier, little-endian
//! bytes 4..12 payload  frame: data bytes (zero beyond dlc); idle: card time in µs, u64 LE
//! ```
//!
//! Why a fixed record: the reader on the card needs no parser state, a record never
//! straddles anything but a read boundary, and a byte-for-byte comparison of two output
//! streams is the bit-identity check itself. After each input record the card writes its
//! frames and one `3` record, so a difference is located to the input that caused it.

/// Bytes per record.
pub const RECORD_LEN: usize = 12;

/// One record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Record {
    /// A classic CAN 2.0A data frame.
    Frame {
        /// 11-bit identifier.
        id: u16,
        /// Data length.
        len: u8,
        /// Data bytes (zero beyond `len`).
        data: [u8; 8],
    },
    /// No frame: the card polls its timeouts at this time (µs).
    Idle(u64),
    /// End of the card's answer to one input record.
    Done,
    /// End of the stream.
    End,
}

impl Record {
    /// A frame record from an identifier and data (at most 8 bytes are kept).
    pub fn frame(id: u16, bytes: &[u8]) -> Record {
        let mut data = [0u8; 8];
        let n = bytes.len().min(8);
        if let (Some(d), Some(s)) = (data.get_mut(..n), bytes.get(..n)) {
            d.copy_from_slice(s);
        }
        Record::Frame {
            id,
            len: u8::try_from(n).unwrap_or(8),
            data,
        }
    }

    /// The record's bytes.
    pub fn to_bytes(&self) -> [u8; RECORD_LEN] {
        let mut b = [0u8; RECORD_LEN];
        let (tag, dlc, id, payload) = match *self {
            Record::Frame { id, len, data } => (1u8, len, id, data),
            Record::Idle(t) => (2, 0, 0, t.to_le_bytes()),
            Record::Done => (3, 0, 0, [0; 8]),
            Record::End => (0, 0, 0, [0; 8]),
        };
        let [i0, i1] = id.to_le_bytes();
        let head = [tag, dlc, i0, i1];
        for (d, s) in b.iter_mut().zip(head.iter().chain(payload.iter())) {
            *d = *s;
        }
        b
    }

    /// Parses one record; `None` for an unknown tag or a dlc above 8.
    pub fn from_bytes(b: &[u8; RECORD_LEN]) -> Option<Record> {
        let [tag, dlc, i0, i1, p0, p1, p2, p3, p4, p5, p6, p7] = *b;
        let payload = [p0, p1, p2, p3, p4, p5, p6, p7];
        match tag {
            1 if dlc <= 8 => Some(Record::Frame {
                id: u16::from_le_bytes([i0, i1]),
                len: dlc,
                data: payload,
            }),
            2 => Some(Record::Idle(u64::from_le_bytes(payload))),
            3 => Some(Record::Done),
            0 => Some(Record::End),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip() {
        for r in [
            Record::frame(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]),
            Record::frame(0x7FF, &[]),
            Record::Idle(u64::MAX - 7),
            Record::Done,
            Record::End,
        ] {
            assert_eq!(Record::from_bytes(&r.to_bytes()), Some(r));
        }
        assert_eq!(
            Record::frame(0x201, &[0xAA; 3]).to_bytes(),
            [1, 3, 0x01, 0x02, 0xAA, 0xAA, 0xAA, 0, 0, 0, 0, 0]
        );
        let mut bad = Record::Done.to_bytes();
        bad[0] = 9;
        assert_eq!(Record::from_bytes(&bad), None);
        let mut bad = Record::frame(1, &[]).to_bytes();
        bad[1] = 9;
        assert_eq!(Record::from_bytes(&bad), None);
    }
}
