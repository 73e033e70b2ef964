//! The card loop under QEMU (mps2-an386 Cortex-M4F, microbit Cortex-M0): replays the frames
//! of a host recording to the card and writes what the card sends, bit for bit comparable
//! with the host card (see `firmware::stream` for the format and `tests/card_replay.rs`).
//!
//! Run from a directory holding `card-in.bin`; writes `card-out.bin` there:
//! `qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic -semihosting-config
//! enable=on,target=native -kernel qemu-card`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("qemu-card is a thumb image: build it with --target thumbv7em-none-eabihf or thumbv6m-none-eabi");
}

#[cfg(target_os = "none")]
mod image {
    use controller::card::node::CardNode;
    use controller::card::Card;
    use controller::proto::{Message, NodeId, RawFrame};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    use embedded_can::StandardId;
    use firmware::semihosting::HostFile;
    use firmware::stream::{Record, RECORD_LEN};

    /// Records per read / write call.
    const CHUNK: usize = 32;

    struct Out {
        file: HostFile,
        buf: [u8; RECORD_LEN * CHUNK],
        used: usize,
        frames: u32,
        ok: bool,
    }

    impl Out {
        fn push(&mut self, r: &Record) {
            if let Some(dst) = self.buf.get_mut(self.used..self.used + RECORD_LEN) {
                dst.copy_from_slice(&r.to_bytes());
                self.used += RECORD_LEN;
            }
            if self.used == self.buf.len() {
                self.flush();
            }
        }
        fn flush(&mut self) {
            if let Some(b) = self.buf.get(..self.used) {
                self.ok &= self.file.write_all(b);
            }
            self.used = 0;
        }
        fn message(&mut self, node: NodeId, m: &Message) {
            if let Ok((id, data, len)) = m.to_bytes(node) {
                self.frames += 1;
                self.push(&Record::frame(id, data.get(..len).unwrap_or(&[])));
            }
        }
    }

    fn fail(why: &str) -> ! {
        hprintln!("qemu-card: {}", why);
        debug::exit(debug::EXIT_FAILURE);
        #[allow(clippy::empty_loop)]
        loop {}
    }

    #[entry]
    fn main() -> ! {
        let Some(node) = NodeId::new(firmware::bench::NODE) else {
            fail("node")
        };
        let Ok(card) = Card::new(node) else {
            fail("card defaults")
        };
        let mut card = CardNode::new(card, 1000, true);
        let Some(mut input) = HostFile::open_read(b"card-in.bin\0") else {
            fail("cannot open card-in.bin")
        };
        let Some(file) = HostFile::create(b"card-out.bin\0") else {
            fail("cannot create card-out.bin")
        };
        let mut out = Out {
            file,
            buf: [0; RECORD_LEN * CHUNK],
            used: 0,
            frames: 0,
            ok: true,
        };
        let mut buf = [0u8; RECORD_LEN * CHUNK];
        let mut records = 0u32;
        'outer: loop {
            let n = input.read(&mut buf);
            if n == 0 || n % RECORD_LEN != 0 {
                break;
            }
            for chunk in buf.get(..n).unwrap_or(&[]).chunks_exact(RECORD_LEN) {
                let mut rec = [0u8; RECORD_LEN];
                rec.copy_from_slice(chunk);
                records += 1;
                match Record::from_bytes(&rec) {
                    Some(Record::Frame { id, len, data }) => {
                        let frame = StandardId::new(id).and_then(|sid| {
                            <RawFrame as embedded_can::Frame>::new(
                                sid,
                                data.get(..usize::from(len)).unwrap_or(&[]),
                            )
                        });
                        if let Some(f) = frame {
                            card.on_frame(0, &f, |m| out.message(node, m));
                        }
                    }
                    Some(Record::Idle(t)) => card.on_idle(t, |m| out.message(node, m)),
                    Some(Record::End) => break 'outer,
                    Some(Record::Done) | None => fail("bad input record"),
                }
                out.push(&Record::Done);
            }
        }
        out.push(&Record::End);
        out.flush();
        if !out.ok {
            fail("write to card-out.bin failed");
        }
        hprintln!(
            "qemu-card: {} records in, {} frames out",
            records,
            out.frames
        );
        debug::exit(debug::EXIT_SUCCESS);
        #[allow(clippy::empty_loop)]
        loop {}
    }

    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo) -> ! {
        fail("panic")
    }
}
