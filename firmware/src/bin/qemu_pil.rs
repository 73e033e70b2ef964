//! Processor-in-the-loop: the card loop under QEMU (mps2-an386 Cortex-M4F, microbit
//! Cortex-M0) speaking SLCAN ([`controller::slcan`]) over UART0, so a host bus reaches it
//! like a CAN node behind a USB-serial adapter (`hil-host run --card qemu`).
//!
//! The serial line is the Lawicel protocol as an adapter speaks it: `O`/`L`/`C`/`Sn`
//! answered with CR, frames accepted only while open and answered `z`/`Z`, anything else
//! with BELL. What makes the link usable in lockstep: the card answers a frame (every frame
//! it sends because of it, as `t` lines) **before** the `z` that acknowledges it, so a host
//! that waits for the `z` has the card's whole answer.
//!
//! Arguments (semihosting command line, `-semihosting-config …,arg=node=1,arg=realtime`):
//! `node=N` (default 1), `realtime` (the card's clock is the host's, through semihosting,
//! instead of the count of its own Sensor frames, and SysTick wakes it every millisecond to
//! poll its timeouts).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("qemu-pil is a thumb image: build it with --target thumbv7em-none-eabihf or thumbv6m-none-eabi");
}

#[cfg(target_os = "none")]
mod image {
    use controller::card::node::CardNode;
    use controller::card::Card;
    use controller::proto::{Message, NodeId, RawFrame};
    use controller::slcan::{self, Line, LineReader, SlFrame};
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    use firmware::uart::Uart;

    /// SysTick reload for 1 ms (mps2-an386 runs at 25 MHz, the nRF51 at 16 MHz): in real
    /// time it only wakes the loop so the card polls its timeouts.
    #[cfg(target_has_atomic = "32")]
    const TICKS_PER_MS: u32 = 25_000;
    #[cfg(not(target_has_atomic = "32"))]
    const TICKS_PER_MS: u32 = 16_000;

    /// Card time in real time: the host's clock through semihosting, µs.
    fn now_us() -> u64 {
        firmware::semihosting::elapsed_ns() / 1000
    }

    fn fail(why: &str) -> ! {
        hprintln!("qemu-pil: {}", why);
        debug::exit(debug::EXIT_FAILURE);
        #[allow(clippy::empty_loop)]
        loop {}
    }

    struct Args {
        node: u8,
        realtime: bool,
    }

    fn args() -> Args {
        let mut a = Args {
            node: 1,
            realtime: false,
        };
        let mut buf = [0u8; 128];
        let Some(line) = firmware::semihosting::cmdline(&mut buf) else {
            return a;
        };
        for word in line.split(|b| *b == b' ') {
            if word == b"realtime" {
                a.realtime = true;
            } else if let Some(n) = word.strip_prefix(b"node=") {
                let mut v = 0u8;
                for d in n {
                    let Some(digit) = d.checked_sub(b'0').filter(|d| *d < 10) else {
                        fail("node=N: not a number")
                    };
                    let Some(next) = v.checked_mul(10).and_then(|v| v.checked_add(digit)) else {
                        fail("node=N: too large")
                    };
                    v = next;
                }
                a.node = v;
            }
        }
        a
    }

    fn send_message(uart: &mut Uart, node: NodeId, m: &Message) {
        let Ok(f) = m.encode::<RawFrame>(node) else {
            return;
        };
        if let Some(sl) = SlFrame::from_frame(&f) {
            uart.write_all(slcan::format(&Line::Frame(sl, None)).as_bytes());
        }
    }

    #[entry]
    fn main() -> ! {
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            fail("peripherals")
        };
        let a = args();
        let Some(node) = NodeId::new(a.node).filter(|n| !n.is_broadcast()) else {
            fail("node must be 1..=127")
        };
        let Ok(card) = Card::new(node) else {
            fail("card defaults")
        };
        let mut card = CardNode::new(card, 1000, !a.realtime);
        if a.realtime {
            cp.SYST.set_clock_source(SystClkSource::Core);
            cp.SYST.set_reload(TICKS_PER_MS.saturating_sub(1));
            cp.SYST.clear_current();
            cp.SYST.enable_interrupt(); // pends, wakes `wfi`; PRIMASK keeps the handler out
            cp.SYST.enable_counter();
        }
        let mut uart = Uart::init();
        let mut reader = LineReader::new();
        let mut open = false;
        let mut last_poll = 0u64;
        hprintln!(
            "qemu-pil: node {} on UART0, {}",
            a.node,
            if a.realtime { "real time" } else { "lockstep" }
        );
        loop {
            let Some(b) = uart.try_read() else {
                if a.realtime {
                    let now = now_us();
                    if now.saturating_sub(last_poll) >= 1000 {
                        last_poll = now;
                        card.on_idle(now, |m| send_message(&mut uart, node, m));
                    }
                }
                uart.sleep();
                continue;
            };
            let Some(line) = reader.push(b) else {
                continue;
            };
            let reply = match line {
                Ok(Line::Frame(f, _)) if open => {
                    // The card speaks classic 11-bit data frames; others are acknowledged
                    // (the bus carried them) but ignored, as a CAN filter would.
                    if let (false, false, Some(raw)) =
                        (f.extended, f.remote, f.to_frame::<RawFrame>())
                    {
                        let now = if a.realtime { now_us() } else { 0 };
                        card.on_frame(now, &raw, |m| send_message(&mut uart, node, m));
                    }
                    Line::Queued {
                        extended: f.extended,
                    }
                }
                Ok(Line::Open | Line::ListenOnly) => {
                    open = true;
                    Line::Ok
                }
                Ok(Line::Close) => {
                    open = false;
                    Line::Ok
                }
                Ok(Line::Bitrate(_)) if !open => Line::Ok,
                // Replies are for a host; a card that gets one ignores it.
                Ok(Line::Ok | Line::Queued { .. } | Line::Error) => continue,
                // A frame while closed, a bit rate while open, a bad line.
                Ok(Line::Frame(..) | Line::Bitrate(_)) | Err(_) => Line::Error,
            };
            uart.write_all(slcan::format(&reply).as_bytes());
        }
    }

    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo) -> ! {
        fail("panic")
    }
}
