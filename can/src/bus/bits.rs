//! Bit lengths of classic CAN frames on the wire, for bus-load accounting.
//!
//! Two figures per frame:
//!
//! * [`exact_bits`]: the real frame bits are laid out (SOF, arbitration, control, data,
//!   CRC-15 computed over them), bit stuffing is applied over SOF..end of the CRC sequence
//!   exactly as a transmitter does, and the fixed-form tail is added: CRC delimiter (1),
//!   ACK slot (1), ACK delimiter (1), EOF (7) and the inter-frame space (3) — 13 bits.
//! * [`worst_case_bits`]: the usual bound with the maximum number of stuff bits
//!   (Davis, Burns, Bril, Lukkien, "Controller Area Network (CAN) schedulability analysis",
//!   2007): for an 11-bit ID, `47 + 8n + floor((34 + 8n - 1) / 4)`; for a 29-bit ID,
//!   `67 + 8n + floor((54 + 8n - 1) / 4)`, `n` = data bytes (0 for a remote frame).
//!
//! Both include the 3-bit inter-frame space, so the sum over frames divided by
//! `bitrate * elapsed` is the bus load.

use embedded_can::Id;

use super::frame::ClassicFrame;

/// CRC-15/CAN generator polynomial x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1.
pub const CRC15_POLY: u16 = 0x4599;

/// Bits after the stuffed region: CRC delimiter, ACK slot, ACK delimiter, EOF (7), IFS (3).
pub const TAIL_BITS: u32 = 1 + 1 + 1 + 7 + 3;

/// CRC-15/CAN over a bit sequence (MSB-first, init 0, no reflection, no final XOR).
pub fn crc15_bits(bits: impl IntoIterator<Item = bool>) -> u16 {
    let mut crc: u16 = 0;
    for bit in bits {
        let next = bit ^ ((crc >> 14) & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= CRC15_POLY;
        }
    }
    crc
}

/// CRC-15/CAN over whole bytes, MSB first (the catalogue form; check value for
/// `b"123456789"` is `0x059E`).
pub fn crc15_bytes(bytes: &[u8]) -> u16 {
    crc15_bits(
        bytes
            .iter()
            .flat_map(|b| (0..8).rev().map(move |i| (b >> i) & 1 == 1)),
    )
}

/// Calls `out` with every bit from SOF through the end of the data field (dominant =
/// `false`), i.e. the bits the CRC covers.
///
/// Standard: SOF, ID\[10:0\], RTR, IDE=0, r0=0, DLC\[3:0\], data (19 + 8n bits).
/// Extended: SOF, ID\[28:18\], SRR=1, IDE=1, ID\[17:0\], RTR, r1=0, r0=0, DLC, data
/// (39 + 8n bits). A remote frame sends its DLC but no data.
fn for_each_crc_covered_bit(frame: &ClassicFrame, mut out: impl FnMut(bool)) {
    let mut push = |v: u32, n: u32| {
        for i in (0..n).rev() {
            out((v >> i) & 1 == 1);
        }
    };
    push(0, 1); // SOF
    match frame.id() {
        Id::Standard(s) => {
            push(u32::from(s.as_raw()), 11);
            push(u32::from(frame.is_remote()), 1); // RTR
            push(0, 1); // IDE
            push(0, 1); // r0
        }
        Id::Extended(e) => {
            let id = e.as_raw();
            push(id >> 18, 11); // base ID
            push(1, 1); // SRR (recessive)
            push(1, 1); // IDE (recessive)
            push(id & 0x3_FFFF, 18); // ID extension
            push(u32::from(frame.is_remote()), 1); // RTR
            push(0, 2); // r1, r0
        }
    }
    push(frame.dlc() as u32, 4);
    for b in frame.data() {
        push(u32::from(*b), 8);
    }
}

/// The unstuffed bits from SOF through the last CRC bit (34 + 8n bits for an 11-bit ID,
/// 54 + 8n for a 29-bit ID).
pub fn frame_bits_unstuffed(frame: &ClassicFrame) -> Vec<bool> {
    let mut bits = Vec::with_capacity(54 + 64 + 15);
    for_each_crc_covered_bit(frame, |b| bits.push(b));
    let crc = crc15_bits(bits.iter().copied());
    bits.extend((0..15).rev().map(|i| (crc >> i) & 1 == 1));
    bits
}

/// Counts stuff bits over a bit stream, one bit at a time (the transmitter's rule).
#[derive(Default)]
struct StuffCounter {
    last: Option<bool>,
    run: u32,
    stuffed: u32,
}

impl StuffCounter {
    fn push(&mut self, b: bool) {
        if Some(b) == self.last {
            self.run += 1;
        } else {
            self.last = Some(b);
            self.run = 1;
        }
        if self.run == 5 {
            self.stuffed += 1;
            self.last = Some(!b);
            self.run = 1;
        }
    }
}

/// Number of stuff bits a transmitter inserts into `bits`: after five consecutive equal
/// bits it inserts one complementary bit, which itself starts the next run. A stuff bit
/// after the last bit (the last CRC bit) is counted too, as on the wire.
pub fn stuff_bit_count(bits: &[bool]) -> u32 {
    let mut c = StuffCounter::default();
    bits.iter().for_each(|&b| c.push(b));
    c.stuffed
}

/// Exact number of bit times the frame occupies on the bus, including stuff bits and the
/// 3-bit inter-frame space. Streams the bits once (CRC and stuffing together), no
/// allocation.
pub fn exact_bits(frame: &ClassicFrame) -> u32 {
    let mut crc: u16 = 0;
    let mut n = 0u32;
    let mut stuff = StuffCounter::default();
    for_each_crc_covered_bit(frame, |bit| {
        n += 1;
        stuff.push(bit);
        let next = bit ^ ((crc >> 14) & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= CRC15_POLY;
        }
    });
    for i in (0..15).rev() {
        stuff.push((crc >> i) & 1 == 1);
    }
    n + 15 + stuff.stuffed + TAIL_BITS
}

/// Worst-case number of bit times (maximum stuffing) for a frame with `data_len` data bytes,
/// including the 3-bit inter-frame space.
pub fn worst_case_bits(extended: bool, data_len: usize) -> u32 {
    let n8 = 8 * data_len.min(8) as u32;
    if extended {
        67 + n8 + (54 + n8 - 1) / 4
    } else {
        47 + n8 + (34 + n8 - 1) / 4
    }
}

/// Worst case for a given frame (remote frames carry no data bytes).
pub fn worst_case_bits_of(frame: &ClassicFrame) -> u32 {
    worst_case_bits(frame.is_extended(), frame.data().len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::{ExtendedId, StandardId};
    use proptest::prelude::*;

    /// Reference: the CRC catalogue (Greg Cook, "reveng"), entry CRC-15/CAN:
    /// width=15 poly=0x4599 init=0x0000 refin=false refout=false xorout=0x0000 check=0x059e.
    #[test]
    fn crc15_catalogue_check_value() {
        assert_eq!(crc15_bytes(b"123456789"), 0x059E);
        assert_eq!(crc15_bytes(&[]), 0);
    }

    /// Derived by hand. ID 0x000, DLC 0, data frame: SOF..DLC are 19 dominant bits and the
    /// CRC of an all-zero message with init 0 is 0, so the stuffed region is 34 zeros. A
    /// stuff bit (recessive) follows every 5th zero and starts a new run, so stuff bits go
    /// after zeros 5, 10, 15, 20, 25, 30: 6 stuff bits. 34 + 6 + 13 = 53 bit times.
    #[test]
    fn all_dominant_frame_by_hand() {
        let f = ClassicFrame::std(0, &[]).unwrap();
        let bits = frame_bits_unstuffed(&f);
        assert_eq!(bits.len(), 34);
        assert!(bits.iter().all(|b| !b));
        assert_eq!(stuff_bit_count(&bits), 6);
        assert_eq!(exact_bits(&f), 53);
        assert_eq!(worst_case_bits_of(&f), 55);
    }

    /// Derived by hand. ID 0x7FF remote, DLC 0. SOF..DLC is `0 11111111111 1 0 0 0000`:
    /// after SOF come twelve recessive bits (ID + RTR): a stuff bit after the 5th one, and
    /// since the stuff bit starts a new run, another after the 10th; ones 11-12 are a run of
    /// 2. Then six dominant bits (IDE, r0, DLC): a stuff bit after the 5th. 3 stuff bits.
    #[test]
    fn recessive_id_frame_by_hand() {
        let f = ClassicFrame::new_rtr(StandardId::MAX, 0).unwrap();
        let bits = frame_bits_unstuffed(&f);
        let head = &bits[..19];
        let expect: Vec<bool> = "0111111111111000000".chars().map(|c| c == '1').collect();
        assert_eq!(head, &expect[..]);
        // Head: stuff after ones #5, #10 and after zeros #5 (IDE r0 DLC3..1) = 3.
        assert_eq!(stuff_bit_count(head), 3);
    }

    /// Long-division check of the CRC for `recessive_id_frame_by_hand`, done without the
    /// shift-register formulation: the CRC is the remainder of M(x)·x^15 mod G(x).
    #[test]
    fn crc_of_7ff_rtr_by_polynomial_division() {
        let msg: Vec<u8> = "0111111111111000000".bytes().map(|c| c - b'0').collect();
        let mut reg: Vec<u8> = msg.clone();
        reg.extend(std::iter::repeat_n(0u8, 15));
        let g: Vec<u8> = (0..16)
            .rev()
            .map(|i| ((0xC599u32 >> i) & 1) as u8)
            .collect();
        for i in 0..msg.len() {
            if reg[i] == 1 {
                for (j, gb) in g.iter().enumerate() {
                    reg[i + j] ^= gb;
                }
            }
        }
        let rem = reg[msg.len()..]
            .iter()
            .fold(0u16, |acc, b| (acc << 1) | u16::from(*b));
        assert_eq!(crc15_bits(msg.iter().map(|b| *b == 1)), rem);
    }

    #[test]
    fn worst_case_formula_values() {
        // 8-byte standard frame: 47 + 64 + floor(97/4)=24 -> 135; 0-byte: 55.
        assert_eq!(worst_case_bits(false, 8), 135);
        assert_eq!(worst_case_bits(false, 0), 55);
        // 8-byte extended frame: 67 + 64 + floor(117/4)=29 -> 160.
        assert_eq!(worst_case_bits(true, 8), 160);
    }

    #[test]
    fn unstuffed_lengths() {
        for n in 0..=8usize {
            let d = vec![0xA5u8; n];
            let s = ClassicFrame::std(0x123, &d).unwrap();
            let e = ClassicFrame::ext(0x123_4567, &d).unwrap();
            assert_eq!(frame_bits_unstuffed(&s).len(), 34 + 8 * n);
            assert_eq!(frame_bits_unstuffed(&e).len(), 54 + 8 * n);
        }
        let r = ClassicFrame::new_rtr(ExtendedId::MAX, 8).unwrap();
        assert_eq!(frame_bits_unstuffed(&r).len(), 54);
    }

    fn any_frame() -> impl Strategy<Value = ClassicFrame> {
        (
            any::<bool>(),
            any::<u32>(),
            any::<bool>(),
            proptest::collection::vec(any::<u8>(), 0..=8),
        )
            .prop_map(|(ext, id, rtr, data)| {
                let id: Id = if ext {
                    ExtendedId::new(id & 0x1FFF_FFFF).unwrap().into()
                } else {
                    StandardId::new((id & 0x7FF) as u16).unwrap().into()
                };
                if rtr {
                    ClassicFrame::new_rtr(id, data.len()).unwrap()
                } else {
                    ClassicFrame::new_data(id, &data).unwrap()
                }
            })
    }

    /// Unstuffs a stuffed stream (receiver side) so the stuffer can be checked both ways.
    fn stuff(bits: &[bool]) -> Vec<bool> {
        let mut out = Vec::new();
        let (mut last, mut run) = (None, 0);
        for &b in bits {
            out.push(b);
            if Some(b) == last {
                run += 1
            } else {
                last = Some(b);
                run = 1
            }
            if run == 5 {
                out.push(!b);
                last = Some(!b);
                run = 1;
            }
        }
        out
    }

    proptest! {
        #[test]
        fn exact_never_exceeds_worst_case(f in any_frame()) {
            let exact = exact_bits(&f);
            let worst = worst_case_bits_of(&f);
            let unstuffed = frame_bits_unstuffed(&f).len() as u32 + TAIL_BITS;
            prop_assert!(exact <= worst, "{f}: exact {exact} > worst {worst}");
            prop_assert!(exact >= unstuffed);
        }

        #[test]
        fn stuffed_stream_has_no_run_of_six(f in any_frame()) {
            let s = stuff(&frame_bits_unstuffed(&f));
            let mut run = 0; let mut last = None;
            for b in &s {
                if Some(*b) == last { run += 1 } else { last = Some(*b); run = 1 }
                prop_assert!(run <= 5);
            }
            prop_assert_eq!(s.len() as u32 + TAIL_BITS, exact_bits(&f));
        }

        /// The streaming count equals the count over the materialised bit vector.
        #[test]
        fn streaming_equals_materialised(f in any_frame()) {
            let bits = frame_bits_unstuffed(&f);
            prop_assert_eq!(exact_bits(&f), bits.len() as u32 + stuff_bit_count(&bits) + TAIL_BITS);
        }

        /// Appending the transmitted CRC to the message leaves a zero remainder.
        #[test]
        fn crc_residue_is_zero(f in any_frame()) {
            let bits = frame_bits_unstuffed(&f);
            prop_assert_eq!(crc15_bits(bits.iter().copied()), 0);
        }
    }
}
