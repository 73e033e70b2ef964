//! Little-endian field access on a byte buffer that cannot panic.
//!
//! Every `Packet::new_checked` verifies the exact length once; after that the accessors call
//! these helpers. They still go through `get(..)` (the crate denies indexing) and fall back to
//! zero / do nothing if a range were ever out of bounds, which the length check rules out.

/// Reads `N` bytes at `off`, or zeros if the range is out of bounds.
pub(crate) fn get<const N: usize>(buf: &[u8], off: usize) -> [u8; N] {
    off.checked_add(N)
        .and_then(|end| buf.get(off..end))
        .and_then(|s| <[u8; N]>::try_from(s).ok())
        .unwrap_or([0; N])
}

/// Writes `N` bytes at `off`; a no-op if the range is out of bounds.
pub(crate) fn set<const N: usize>(buf: &mut [u8], off: usize, bytes: [u8; N]) {
    if let Some(dst) = off.checked_add(N).and_then(|end| buf.get_mut(off..end)) {
        // Same length by construction (`end - off == N`), so this cannot panic.
        dst.copy_from_slice(&bytes);
    }
}

pub(crate) fn u8_at(buf: &[u8], off: usize) -> u8 {
    buf.get(off).copied().unwrap_or(0)
}
pub(crate) fn set_u8(buf: &mut [u8], off: usize, v: u8) {
    if let Some(b) = buf.get_mut(off) {
        *b = v;
    }
}
pub(crate) fn u16_at(buf: &[u8], off: usize) -> u16 {
    u16::from_le_bytes(get(buf, off))
}
pub(crate) fn set_u16(buf: &mut [u8], off: usize, v: u16) {
    set(buf, off, v.to_le_bytes());
}
pub(crate) fn i16_at(buf: &[u8], off: usize) -> i16 {
    i16::from_le_bytes(get(buf, off))
}
pub(crate) fn set_i16(buf: &mut [u8], off: usize, v: i16) {
    set(buf, off, v.to_le_bytes());
}
pub(crate) fn u32_at(buf: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(get(buf, off))
}
pub(crate) fn set_u32(buf: &mut [u8], off: usize, v: u32) {
    set(buf, off, v.to_le_bytes());
}
pub(crate) fn i32_at(buf: &[u8], off: usize) -> i32 {
    i32::from_le_bytes(get(buf, off))
}
pub(crate) fn set_i32(buf: &mut [u8], off: usize, v: i32) {
    set(buf, off, v.to_le_bytes());
}

/// Defines the smoltcp-style `Packet<T>` wrapper of one message kind: a buffer whose length
/// has been checked to be exactly `LEN` (CAN DLC), so accessors need no further checks.
macro_rules! packet {
    ($kind:expr, $len:expr) => {
        /// The message kind this module encodes.
        pub const KIND: $crate::proto::Kind = $kind;
        /// Exact data length (DLC). Any other length is rejected: a frame with extra bytes is
        /// as suspicious as a short one, and exact lengths keep the bus-load budget honest.
        pub const LEN: usize = $len;

        /// A byte buffer known to hold exactly [`LEN`] bytes of this message.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub struct Packet<T: AsRef<[u8]>> {
            buffer: T,
        }

        impl<T: AsRef<[u8]>> Packet<T> {
            /// Wraps without checking; accessors on a wrong-length buffer read zeros.
            pub const fn new_unchecked(buffer: T) -> Self {
                Packet { buffer }
            }

            /// Wraps after checking the length is exactly [`LEN`].
            pub fn new_checked(buffer: T) -> Result<Self, $crate::proto::Error> {
                let p = Self::new_unchecked(buffer);
                p.check_len()?;
                Ok(p)
            }

            /// `Err(WrongLength)` unless the buffer holds exactly [`LEN`] bytes.
            pub fn check_len(&self) -> Result<(), $crate::proto::Error> {
                let got = self.buffer.as_ref().len();
                if got == LEN {
                    Ok(())
                } else {
                    Err($crate::proto::Error::WrongLength {
                        kind: KIND,
                        expected: LEN as u8,
                        got: u8::try_from(got).unwrap_or(u8::MAX),
                    })
                }
            }

            /// Gives the buffer back.
            pub fn into_inner(self) -> T {
                self.buffer
            }

            fn buf(&self) -> &[u8] {
                self.buffer.as_ref()
            }
        }

        impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
            #[allow(dead_code)]
            fn buf_mut(&mut self) -> &mut [u8] {
                self.buffer.as_mut()
            }
        }
    };
}
pub(crate) use packet;

/// Defines a `u8`-coded wire enum with `from_u8`, `as_u8`, `name` and `ALL`, so the names the
/// DBC `VAL_` tables and golden vectors use come from one list.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident { $( $(#[$vmeta:meta])* $var:ident = $val:literal ),+ $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(u8)]
        pub enum $name { $( $(#[$vmeta])* $var = $val ),+ }

        impl $name {
            /// Every value, in wire order.
            pub const ALL: &'static [$name] = &[ $( $name::$var ),+ ];

            /// Decodes a wire byte; `None` for values the spec does not define.
            pub const fn from_u8(v: u8) -> Option<Self> {
                match v {
                    $( $val => Some($name::$var), )+
                    _ => None,
                }
            }

            /// The wire byte.
            pub const fn as_u8(self) -> u8 {
                self as u8
            }

            /// The name used in `docs/protocol.md`, the DBC `VAL_` table and the golden vectors.
            pub const fn name(self) -> &'static str {
                match self {
                    $( $name::$var => stringify!($var), )+
                }
            }

            /// Inverse of [`Self::name`].
            pub fn from_name(s: &str) -> Option<Self> {
                Self::ALL.iter().copied().find(|v| v.name() == s)
            }
        }
    };
}
pub(crate) use wire_enum;
