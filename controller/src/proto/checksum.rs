//! The commit checksum: CRC-32/ISO-HDLC (the zlib / Ethernet CRC: reflected polynomial
//! 0xEDB88320, init 0xFFFFFFFF, final xor 0xFFFFFFFF, check value 0xCBF43926 for
//! `"123456789"`) over the staged entries, each entry contributing its 6 wire bytes
//! `param_id` (u16 LE) ‖ `value` (i32 LE), in the order the `ParamWrite` frames were sent.
//!
//! Why this CRC: every supervisor language has it built in (`zlib.crc32`, `crc32fast`,
//! `binascii.crc32`), so tools can compute a commit without this crate; it detects every
//! burst up to 32 bits and any reordering of entries (a plain sum would not), and the card
//! updates it incrementally as each write arrives, with no allocation and no table (a
//! bitwise loop of 48 iterations per entry, at configuration time, not in the 1 kHz path).
//! Supervisor and card both use [`SetChecksum`], so they cannot disagree on the definition.

/// CRC-32/ISO-HDLC reflected polynomial.
const POLY: u32 = 0xEDB8_8320;

/// Raw running CRC-32 register (exposed for tests against the standard check value).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Crc32 {
    reg: u32,
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// Fresh register (init 0xFFFFFFFF).
    pub const fn new() -> Self {
        Crc32 { reg: 0xFFFF_FFFF }
    }

    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.reg ^= u32::from(b);
            for _ in 0..8 {
                let lsb = self.reg & 1;
                self.reg >>= 1;
                if lsb != 0 {
                    self.reg ^= POLY;
                }
            }
        }
    }

    /// The CRC of everything fed so far (the register is left unchanged, so more can follow).
    pub const fn finish(&self) -> u32 {
        self.reg ^ 0xFFFF_FFFF
    }
}

/// Incremental checksum and count of one staged parameter set.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SetChecksum {
    crc: Crc32,
    count: u8,
}

impl SetChecksum {
    /// Empty set.
    pub const fn new() -> Self {
        SetChecksum {
            crc: Crc32::new(),
            count: 0,
        }
    }

    /// Adds one entry exactly as its `ParamWrite` frame carries it.
    pub fn push(&mut self, param_id: u16, value: i32) {
        self.crc.update(&param_id.to_le_bytes());
        self.crc.update(&value.to_le_bytes());
        self.count = self.count.saturating_add(1);
    }

    /// Entries pushed (saturating at 255, which exceeds any staging capacity).
    pub const fn count(&self) -> u8 {
        self.count
    }

    /// The value for `ParamCommit.crc`.
    pub const fn crc(&self) -> u32 {
        self.crc.finish()
    }

    /// Checksum of a whole slice of entries (supervisor side convenience).
    pub fn of(entries: &[(u16, i32)]) -> SetChecksum {
        let mut s = SetChecksum::new();
        for &(id, v) in entries {
            s.push(id, v);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_check_value() {
        let mut c = Crc32::new();
        c.update(b"123456789");
        assert_eq!(c.finish(), 0xCBF4_3926);
    }

    #[test]
    fn empty_set_is_zero_and_order_matters() {
        assert_eq!(SetChecksum::new().crc(), 0);
        let a = SetChecksum::of(&[(0x0101, 1), (0x0102, 2)]);
        let b = SetChecksum::of(&[(0x0102, 2), (0x0101, 1)]);
        assert_ne!(a.crc(), b.crc());
        assert_eq!(a.count(), 2);
    }

    #[test]
    fn incremental_equals_one_shot() {
        let mut bytes = [0u8; 12];
        bytes[..2].copy_from_slice(&0x0301u16.to_le_bytes());
        bytes[2..6].copy_from_slice(&(-5i32).to_le_bytes());
        bytes[6..8].copy_from_slice(&0x0101u16.to_le_bytes());
        bytes[8..].copy_from_slice(&70_000i32.to_le_bytes());
        let mut c = Crc32::new();
        c.update(&bytes);
        assert_eq!(
            SetChecksum::of(&[(0x0301, -5), (0x0101, 70_000)]).crc(),
            c.finish()
        );
    }
}
