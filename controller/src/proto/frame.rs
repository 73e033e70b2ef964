//! A plain, `Copy` CAN frame implementing [`embedded_can::Frame`], for code that has no
//! driver frame type at hand (host tests, the in-process bus, a card runtime's outbox).

use embedded_can::{Frame, Id};

/// A classic CAN frame: identifier, up to 8 data bytes, RTR flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawFrame {
    id: Id,
    data: [u8; 8],
    len: u8,
    remote: bool,
}

#[cfg(feature = "defmt")]
impl defmt::Format for RawFrame {
    fn format(&self, f: defmt::Formatter) {
        let raw = match self.id {
            Id::Standard(s) => u32::from(s.as_raw()),
            Id::Extended(e) => e.as_raw(),
        };
        defmt::write!(f, "{=u32:x}#{=[u8]:x}", raw, self.data());
    }
}

impl RawFrame {
    /// The 11-bit identifier, or `None` for an extended frame.
    pub fn standard_id(&self) -> Option<u16> {
        match self.id {
            Id::Standard(s) => Some(s.as_raw()),
            Id::Extended(_) => None,
        }
    }
}

impl Frame for RawFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        let mut buf = [0u8; 8];
        let dst = buf.get_mut(..data.len())?;
        dst.copy_from_slice(data);
        Some(RawFrame {
            id: id.into(),
            data: buf,
            len: u8::try_from(data.len()).ok()?,
            remote: false,
        })
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        if dlc > 8 {
            return None;
        }
        Some(RawFrame {
            id: id.into(),
            data: [0; 8],
            len: u8::try_from(dlc).ok()?,
            remote: true,
        })
    }

    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        usize::from(self.len)
    }

    fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            self.data.get(..usize::from(self.len)).unwrap_or(&[])
        }
    }
}
