//! Instruction counts under QEMU (`-icount shift=0`: one guest instruction is one
//! nanosecond of virtual time, so SysTick counts instructions at the machine's clock
//! divided down). Prints raw SysTick figures; `benches/insn.rs` turns them into the table.
//!
//! Lines: `calib <instructions> <ticks>` (a counted asm loop of known length),
//! `case <case> <inputs> <steps> <ticks>`, `tick <n> <ticks> <max_ticks>` (one card tick:
//! Sensor frame in, frames out), `build <n> <ticks>` (config::build), `commit <n> <ticks>`
//! (a ParamCommit of the full set, as the card handles it).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("qemu-bench is a thumb image: build it with --target thumbv7em-none-eabihf or thumbv6m-none-eabi");
}

#[cfg(target_os = "none")]
mod image {
    use controller::card::node::CardNode;
    use controller::card::{config, Card, ParamStore};
    use controller::proto::{Message, Mode, NodeId, ParamStatus, RawFrame, Sensor};
    use core::hint::black_box;
    use cortex_m::peripheral::{syst::SystClkSource, SYST};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    use firmware::bench::{self, Bench, Case, Inputs};

    const STEPS: u32 = 1024;

    fn now() -> u32 {
        SYST::get_current()
    }

    /// Ticks elapsed from `t0` (SysTick counts down, 24 bits).
    fn since(t0: u32) -> u32 {
        t0.wrapping_sub(now()) & 0x00FF_FFFF
    }

    /// A loop of exactly 2·n + 1 instructions (`subs`, `bne` per turn, plus the `mov`).
    #[allow(unsafe_code)]
    #[inline(never)]
    fn known_loop(n: u32) {
        // SAFETY: touches only the scratch register it declares.
        unsafe {
            core::arch::asm!(
                "movs {r}, {n}",
                "2:",
                "subs {r}, #1",
                "bne 2b",
                n = in(reg) n,
                r = out(reg) _,
                options(nomem, nostack)
            );
        }
    }

    fn fail(why: &str) -> ! {
        hprintln!("qemu-bench: {}", why);
        debug::exit(debug::EXIT_FAILURE);
        #[allow(clippy::empty_loop)]
        loop {}
    }

    #[entry]
    fn main() -> ! {
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            fail("peripherals")
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00FF_FFFF);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();

        let n = 50_000u32;
        let t0 = now();
        known_loop(n);
        hprintln!("calib {} {}", 2 * n + 1, since(t0));

        for inputs in [Inputs::Bench, Inputs::Tracking] {
            laws(inputs);
        }
        card_tick();
        config_build();
        debug::exit(debug::EXIT_SUCCESS);
        #[allow(clippy::empty_loop)]
        loop {}
    }

    /// Every law on one input set. Its own frame, so the M0's 16 KiB of stack is free again
    /// for the card afterwards.
    #[inline(never)]
    fn laws(inputs: Inputs) {
        let Some(mut b) = Bench::new(inputs) else {
            fail("bench config")
        };
        for case in Case::ALL {
            let t0 = now();
            black_box(b.run(black_box(case), STEPS));
            let dt = since(t0);
            hprintln!("case {:?} {:?} {} {}", case, inputs, STEPS, dt);
        }
    }

    /// One whole tick as the CAN ISR runs it: decode the Sensor frame, step the card,
    /// encode every frame it sends.
    #[inline(never)]
    fn card_tick() {
        let x0 = 1_000_000u32;
        let Some(node) = NodeId::new(bench::NODE) else {
            fail("node")
        };
        let Ok(card) = Card::new(node) else {
            fail("card")
        };
        let mut card = CardNode::new(card, 1000, true);
        if !bench::configure(card.card_mut(), x0) {
            fail("configure");
        }
        let ticks = 256u32;
        let (mut total, mut max, mut base) = (0u32, 0u32, 0u32);
        for k in 0..ticks {
            let s = Sensor {
                motor_counts: x0.wrapping_add((k % 9).wrapping_mul(3)),
                output_torque: Some(((k % 13) as i16).wrapping_sub(6)),
                seq: (k as u8).wrapping_add(3),
                output_encoder: false,
                encoder_error: false,
            };
            let t0 = now();
            let Ok(f) = Message::Sensor(s).encode::<RawFrame>(node) else {
                fail("encode")
            };
            let f = black_box(f);
            base = base.wrapping_add(since(t0));
            let t0 = now();
            card.on_frame(0, &f, |m| {
                black_box(m.to_bytes(node).ok());
            });
            let dt = since(t0);
            total = total.wrapping_add(dt);
            max = max.max(dt);
        }
        hprintln!("tick {} {} {}", ticks, total, max);
        let _ = base;
    }

    #[inline(never)]
    fn config_build() {
        let mut store = ParamStore::new();
        store.apply(&bench::full_param_set());
        let n = 8u32;
        let t0 = now();
        for _ in 0..n {
            black_box(config::build(black_box(&store), Some(Mode::PositionPid)).ok());
        }
        hprintln!("build {} {}", n, since(t0));

        let Some(node) = NodeId::new(bench::NODE) else {
            fail("node")
        };
        let Ok(mut card) = Card::new(node) else {
            fail("card")
        };
        if !bench::configure(&mut card, 1_000_000) {
            fail("configure");
        }
        // While enabled only `Any` parameters may be written (the ripple period and length
        // are idle-only).
        let entries = bench::driving_param_set();
        let mut total = 0u32;
        for i in 0..n {
            let commit = bench::writes_and_commit(&entries, (i as u8).wrapping_add(9), |m| {
                card.handle_message(0, node, m);
            });
            while card.poll_transmit().is_some() {}
            let t0 = now();
            card.handle_message(0, node, Message::ParamCommit(commit));
            total = total.wrapping_add(since(t0));
            match card.poll_transmit() {
                Some(Message::ParamResponse(r)) if r.status == ParamStatus::Ok => {}
                _ => fail("the benchmark's commit was refused"),
            }
            while card.poll_transmit().is_some() {}
        }
        hprintln!("commit {} {}", n, total);
    }

    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo) -> ! {
        fail("panic")
    }
}
