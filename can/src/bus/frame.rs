//! The harness-owned classic CAN 2.0 frame, and conversion between any two
//! [`embedded_can::Frame`] implementations.

use core::fmt;

use embedded_can::{ExtendedId, Frame as EmbeddedFrame, Id, StandardId};

/// Largest data length of a classic CAN frame.
pub const MAX_DLC: usize = 8;

/// A classic CAN 2.0 frame (data or remote, 11- or 29-bit ID, 0..=8 bytes).
///
/// This is the frame type every [`CanBus`](super::CanBus) carries. It implements
/// [`embedded_can::Frame`], so code written against that trait (the card's protocol layer,
/// `socketcan::CanFrame`, an MCU HAL's frame) converts to and from it with [`convert`].
///
/// Invariants (kept by every constructor): `dlc <= 8`; a data frame's bytes past `dlc` are
/// zero; a remote frame carries no data bytes (its `dlc` is the requested length).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClassicFrame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; MAX_DLC],
}

impl ClassicFrame {
    /// A data frame. `None` if `data` is longer than 8 bytes.
    pub fn new_data(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        if data.len() > MAX_DLC {
            return None;
        }
        let mut buf = [0u8; MAX_DLC];
        buf[..data.len()].copy_from_slice(data);
        Some(Self {
            id: id.into(),
            remote: false,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    /// A remote (RTR) frame requesting `dlc` bytes. `None` if `dlc > 8`.
    pub fn new_rtr(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        if dlc > MAX_DLC {
            return None;
        }
        Some(Self {
            id: id.into(),
            remote: true,
            dlc: dlc as u8,
            data: [0; MAX_DLC],
        })
    }

    /// A data frame with an 11-bit ID. `None` if `id > 0x7FF` or `data.len() > 8`.
    pub fn std(id: u16, data: &[u8]) -> Option<Self> {
        Self::new_data(StandardId::new(id)?, data)
    }

    /// A data frame with a 29-bit ID. `None` if `id > 0x1FFF_FFFF` or `data.len() > 8`.
    pub fn ext(id: u32, data: &[u8]) -> Option<Self> {
        Self::new_data(ExtendedId::new(id)?, data)
    }

    /// The identifier.
    pub fn id(&self) -> Id {
        self.id
    }

    /// The identifier as a plain number (11 or 29 significant bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(s) => u32::from(s.as_raw()),
            Id::Extended(e) => e.as_raw(),
        }
    }

    /// `true` for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    /// `true` for a remote transmission request.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// The data length code (0..=8). For a remote frame: the requested length.
    pub fn dlc(&self) -> usize {
        usize::from(self.dlc)
    }

    /// The payload (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..usize::from(self.dlc)]
        }
    }
}

impl EmbeddedFrame for ClassicFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        Self::new_data(id, data)
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        Self::new_rtr(id, dlc)
    }

    fn is_extended(&self) -> bool {
        ClassicFrame::is_extended(self)
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        ClassicFrame::dlc(self)
    }

    fn data(&self) -> &[u8] {
        ClassicFrame::data(self)
    }
}

/// candump compact notation: `123#DEADBEEF`, `12345678#R4`, `7FF#`.
impl fmt::Display for ClassicFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_extended() {
            write!(f, "{:08X}#", self.raw_id())?;
        } else {
            write!(f, "{:03X}#", self.raw_id())?;
        }
        if self.remote {
            f.write_str("R")?;
            if self.dlc > 0 {
                write!(f, "{}", self.dlc)?;
            }
        } else {
            for b in self.data() {
                write!(f, "{b:02X}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Debug for ClassicFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ClassicFrame({self})")
    }
}

/// Converts between any two [`embedded_can::Frame`] types (for example a
/// [`ClassicFrame`] and a `socketcan::CanFrame`, or the card's own frame type).
///
/// Keeps the ID (standard/extended), the remote flag and the DLC, and the data of a data
/// frame. Returns `None` when the target type cannot represent the frame (for example a
/// source frame with more than 8 data bytes, such as a CAN FD frame, converted to a classic
/// type).
pub fn convert<A: EmbeddedFrame, B: EmbeddedFrame>(frame: &A) -> Option<B> {
    if frame.is_remote_frame() {
        B::new_remote(frame.id(), frame.dlc())
    } else {
        B::new(frame.id(), frame.data())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_enforce_limits() {
        assert!(ClassicFrame::std(0x7FF, &[0; 8]).is_some());
        assert!(ClassicFrame::std(0x800, &[]).is_none());
        assert!(ClassicFrame::std(0x1, &[0; 9]).is_none());
        assert!(ClassicFrame::ext(0x1FFF_FFFF, &[]).is_some());
        assert!(ClassicFrame::ext(0x2000_0000, &[]).is_none());
        assert!(ClassicFrame::new_rtr(StandardId::ZERO, 9).is_none());
        let r = ClassicFrame::new_rtr(StandardId::new(0x10).unwrap(), 4).unwrap();
        assert_eq!(r.dlc(), 4);
        assert!(r.data().is_empty());
    }

    #[test]
    fn display_is_candump_compact() {
        assert_eq!(
            ClassicFrame::std(0x123, &[0xDE, 0xAD, 0xBE, 0xEF])
                .unwrap()
                .to_string(),
            "123#DEADBEEF"
        );
        assert_eq!(ClassicFrame::std(0x5, &[]).unwrap().to_string(), "005#");
        assert_eq!(
            ClassicFrame::ext(0x1234, &[1]).unwrap().to_string(),
            "00001234#01"
        );
        let r = ClassicFrame::new_rtr(StandardId::new(0x123).unwrap(), 0).unwrap();
        assert_eq!(r.to_string(), "123#R");
        let r = ClassicFrame::new_rtr(ExtendedId::new(0x12345678).unwrap(), 5).unwrap();
        assert_eq!(r.to_string(), "12345678#R5");
    }

    #[test]
    fn convert_round_trips_through_itself() {
        let f = ClassicFrame::ext(0xABCDE, &[1, 2, 3]).unwrap();
        let g: ClassicFrame = convert(&f).unwrap();
        assert_eq!(f, g);
        let r = ClassicFrame::new_rtr(StandardId::new(0x42).unwrap(), 3).unwrap();
        let s: ClassicFrame = convert(&r).unwrap();
        assert_eq!(r, s);
    }

    #[cfg(all(target_os = "linux", feature = "socketcan"))]
    #[test]
    fn convert_to_and_from_socketcan() {
        use socketcan::CanFrame;
        for f in [
            ClassicFrame::std(0x123, &[0xDE, 0xAD]).unwrap(),
            ClassicFrame::ext(0x1ABC_DEF0, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
            ClassicFrame::new_rtr(StandardId::new(0x7FF).unwrap(), 2).unwrap(),
            ClassicFrame::std(0x0, &[]).unwrap(),
        ] {
            let s: CanFrame = convert(&f).unwrap();
            assert_eq!(EmbeddedFrame::id(&s), f.id());
            assert_eq!(s.is_remote_frame(), f.is_remote());
            let back: ClassicFrame = convert(&s).unwrap();
            assert_eq!(back, f);
        }
    }
}
