//! Fuzz the frame decoder: any identifier (standard or extended), RTR flag and 0–8 data
//! bytes must decode without panicking, and every accepted frame must re-encode to the same
//! identifier and bytes.
#![no_main]

use controller::proto::{Message, RawFrame};
use embedded_can::{ExtendedId, Frame, StandardId};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    // Layout of the fuzz input: [flags, id0, id1, id2, id3, data…]; flags bit0 = extended,
    // bit1 = remote; data is truncated to 8 bytes (the remote DLC is flags >> 4, max 8).
    let Some((&flags, rest)) = input.split_first() else {
        return;
    };
    let Some((id_bytes, data)) = rest.split_first_chunk::<4>() else {
        return;
    };
    let raw = u32::from_le_bytes(*id_bytes);
    let data = &data[..data.len().min(8)];
    let frame = if flags & 1 != 0 {
        let Some(id) = ExtendedId::new(raw & 0x1FFF_FFFF) else {
            return;
        };
        if flags & 2 != 0 {
            RawFrame::new_remote(id, usize::from(flags >> 4).min(8))
        } else {
            RawFrame::new(id, data)
        }
    } else {
        let Some(id) = StandardId::new((raw & 0x7FF) as u16) else {
            return;
        };
        if flags & 2 != 0 {
            RawFrame::new_remote(id, usize::from(flags >> 4).min(8))
        } else {
            RawFrame::new(id, data)
        }
    };
    let Some(frame) = frame else { return };
    if let Ok((node, msg)) = Message::decode(&frame) {
        let again: RawFrame = msg.encode(node).expect("accepted message must re-encode");
        assert_eq!(again.id(), frame.id());
        assert_eq!(again.data(), frame.data());
    }
});
