//! The motor card on a NUCLEO-G474RE (STM32G474RE, Cortex-M4F at 170 MHz).
//!
//! ```text
//!  TIM6 update IRQ, 1 kHz, highest priority            thread mode (embassy executor)
//!  ─────────────────────────────────────────           ──────────────────────────────────
//!  read TIM2 (motor) / TIM4 (output) quadrature        can_rx: FDCAN1 frame → CardNode
//!  amplifier fault input → Card::power_stage_fault     can_tx: queued frames → FDCAN1
//!  Card::step → PowerStage (TIM3 PWM + DIR/EN/BRAKE)    build: BuildRequest::build (f64)
//!  INHIBIT line ← latched fault                                 → Card::finish_build
//!  telemetry / heartbeat / fault → TX queue
//! ```
//!
//! The card lives in one `critical_section::Mutex`. Every thread-mode access is short
//! (one received frame, one queue pop), because the only long operation — the f64
//! configuration build of a commit or an `Enable`, ~120 000 instructions — runs unlocked
//! in the build task ([`controller::card::Card::set_deferred_builds`]); its result is
//! swapped in at the next tick. So the tick's latency is bounded by the longest frame
//! handler, not by a commit.
//!
//! HAL: embassy-stm32 (pinned `=0.6.0`). Its FDCAN driver, quadrature decoder, PWM channel
//! (which implements embedded-hal 1.0 `SetDutyCycle`, what `controller::power_stage`
//! takes) and GPIO (`OutputPin`) are maintained for the G4; RTIC + the stm32g4 PAC would
//! have meant writing the FDCAN message-RAM driver by hand. The 1 kHz tick is not an async
//! timer: it is TIM6's update interrupt, so the control period does not depend on the
//! executor.
//!
//! On the host this file is a stub (`cargo test --workspace` builds it).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("firmware is the NUCLEO-G474RE image: cargo build -p firmware --release --target thumbv7em-none-eabihf");
}

#[cfg(target_os = "none")]
mod board {
    use core::cell::{Cell, RefCell};

    use controller::card::node::CardNode;
    use controller::card::{Card, Sensors};
    use controller::power_stage::{PowerStage, StageCommand};
    use controller::proto::{id, Kind, Message, NodeId};
    use critical_section::Mutex;
    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_stm32::can::enums::BusErrorMode;
    use embassy_stm32::can::{self, Can, CanRx, CanTx, Properties};
    use embassy_stm32::gpio::{Input, Level, Output, OutputType, Pull, Speed};
    #[cfg(feature = "output-encoder")]
    use embassy_stm32::peripherals::TIM4;
    use embassy_stm32::peripherals::{TIM2, TIM3};
    use embassy_stm32::time::Hertz;
    use embassy_stm32::timer::qei::Qei;
    use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm, SimplePwmChannel};
    use embassy_stm32::{bind_interrupts, interrupt, pac, peripherals};
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::signal::Signal;

    /// This card's node number (the protocol's `node_id` is read-only, set at boot).
    const NODE: u8 = 1;
    /// Torque (0.1 mN·m) at 100 % PWM duty: the amplifier's full-scale current times the
    /// motor's torque constant (here 2 N·m).
    const FULL_SCALE: u16 = 20_000;
    /// Control period, µs.
    const PERIOD_US: u32 = 1000;
    /// Frames the tick and the receive path can queue before the transmit task drains
    /// them (a tick queues at most a fault, a telemetry frame and a heartbeat).
    const TX_QUEUE: usize = 32;

    bind_interrupts!(struct Irqs {
        FDCAN1_IT0 => can::IT0InterruptHandler<peripherals::FDCAN1>;
        FDCAN1_IT1 => can::IT1InterruptHandler<peripherals::FDCAN1>;
    });

    type Stage = PowerStage<
        SimplePwmChannel<'static, TIM3>,
        Output<'static>,
        Output<'static>,
        Output<'static>,
    >;

    /// Everything the tick touches.
    struct Board {
        node: CardNode,
        motor: Qei<'static, TIM2>,
        motor_last: u16,
        motor_counts: u32,
        #[cfg(feature = "output-encoder")]
        output: Qei<'static, TIM4>,
        #[cfg(feature = "output-encoder")]
        output_last: u16,
        #[cfg(feature = "output-encoder")]
        output_counts: u32,
        stage: Stage,
        /// High = amplifier inhibited (hardware disable, pulled up on the board).
        inhibit: Output<'static>,
        /// Amplifier fault output, active low.
        amp_fault: Input<'static>,
        seq: u8,
        tx: heapless::Deque<(u16, u8, [u8; 8]), TX_QUEUE>,
        tx_dropped: u32,
    }

    static BOARD: Mutex<RefCell<Option<Board>>> = Mutex::new(RefCell::new(None));
    /// Microseconds at the last tick (the card's clock, 64-bit: it never wraps).
    static CLOCK_US: Mutex<Cell<u64>> = Mutex::new(Cell::new(0));
    static TX_READY: Signal<CriticalSectionRawMutex, ()> = Signal::new();
    static BUILD_READY: Signal<CriticalSectionRawMutex, ()> = Signal::new();

    /// The card's time: the last tick plus TIM6's count since (1 µs per count).
    fn now_us() -> u64 {
        critical_section::with(|cs| {
            let sub = u32::from(pac::TIM6.cnt().read().cnt()).min(PERIOD_US - 1);
            CLOCK_US.borrow(cs).get() + u64::from(sub)
        })
    }

    impl Board {
        fn queue(&mut self, m: &Message) {
            let Some(node) = NodeId::new(NODE) else {
                return;
            };
            if let Ok((id, data, len)) = m.to_bytes(node) {
                if self.tx.push_back((id, len as u8, data)).is_err() {
                    self.tx_dropped = self.tx_dropped.wrapping_add(1);
                }
            }
        }

        /// Extends a 16-bit quadrature count to the protocol's free-running u32.
        fn extend(last: &mut u16, counts: &mut u32, now: u16) -> u32 {
            let d = now.wrapping_sub(*last) as i16;
            *last = now;
            *counts = counts.wrapping_add(d as i32 as u32);
            *counts
        }

        /// One control period.
        fn tick(&mut self) {
            let now = now_us();
            if self.amp_fault.is_low() {
                self.node.card_mut().power_stage_fault(1);
            }
            let motor = Self::extend(
                &mut self.motor_last,
                &mut self.motor_counts,
                self.motor.count(),
            );
            #[cfg(feature = "output-encoder")]
            let output_counts = Some(Self::extend(
                &mut self.output_last,
                &mut self.output_counts,
                self.output.count(),
            ));
            #[cfg(not(feature = "output-encoder"))]
            let output_counts = None;
            self.seq = self.seq.wrapping_add(1);
            let s = Sensors {
                motor_counts: motor,
                output_torque: None,
                output_counts,
                seq: self.seq,
                encoder_error: false,
            };
            let act = self.node.card_mut().step(now, &s);
            let cmd = if act.fault {
                StageCommand::Fault
            } else if act.drive {
                StageCommand::Drive(act.torque)
            } else {
                StageCommand::Disabled
            };
            // The inhibit line first: a latched fault takes the amplifier off in hardware
            // whatever the PWM does next.
            self.inhibit
                .set_level(if act.fault { Level::High } else { Level::Low });
            if self.stage.apply(cmd).is_err() {
                self.inhibit.set_high();
                self.node.card_mut().power_stage_fault(2);
            }
            while let Some(m) = self.node.card_mut().poll_transmit() {
                self.queue(&m);
            }
        }
    }

    #[interrupt]
    fn TIM6_DAC() {
        pac::TIM6.sr().modify(|w| w.set_uif(false));
        let queued = critical_section::with(|cs| {
            let clock = CLOCK_US.borrow(cs);
            clock.set(clock.get() + u64::from(PERIOD_US));
            let mut b = BOARD.borrow_ref_mut(cs);
            b.as_mut().map(|b| {
                b.tick();
                !b.tx.is_empty()
            })
        });
        if queued == Some(true) {
            TX_READY.signal(());
        }
    }

    fn with_board<R>(f: impl FnOnce(&mut Board) -> R) -> Option<R> {
        critical_section::with(|cs| BOARD.borrow_ref_mut(cs).as_mut().map(f))
    }

    #[embassy_executor::task]
    async fn can_rx(mut rx: CanRx<'static>, props: Properties) {
        loop {
            match rx.read().await {
                Ok(env) => {
                    let f = env.frame;
                    // The board's tick and sensors are its own: another node's Sensor or
                    // OutputEncoder frame with this node number must not step the card.
                    if let embedded_can::Id::Standard(sid) = embedded_can::Frame::id(&f) {
                        if matches!(
                            id::split(sid.as_raw()),
                            Ok((Kind::Sensor | Kind::OutputEncoder, _))
                        ) {
                            continue;
                        }
                    }
                    let now = now_us();
                    let build = with_board(|b| {
                        let mut out: heapless::Vec<Message, 20> = heapless::Vec::new();
                        b.node.on_frame(now, &f, |m| {
                            let _ = out.push(*m);
                        });
                        for m in &out {
                            b.queue(m);
                        }
                        b.node.card().build_requested()
                    });
                    TX_READY.signal(());
                    if build == Some(true) {
                        BUILD_READY.signal(());
                    }
                }
                Err(e) => {
                    // A protocol error alone is the bus's business (CAN retransmits); error
                    // passive or bus-off means the card can no longer be heard: safe state.
                    let mode = props.bus_error_mode();
                    defmt::warn!(
                        "FDCAN1 {} ({})",
                        defmt::Debug2Format(&e),
                        defmt::Debug2Format(&mode)
                    );
                    let code = match mode {
                        BusErrorMode::ErrorPassive => 2,
                        BusErrorMode::BusOff => 3,
                        BusErrorMode::ErrorActive => continue,
                    };
                    with_board(|b| {
                        let mut out: heapless::Vec<Message, 20> = heapless::Vec::new();
                        b.node.on_bus_error(code, |m| {
                            let _ = out.push(*m);
                        });
                        for m in &out {
                            b.queue(m);
                        }
                    });
                    TX_READY.signal(());
                }
            }
        }
    }

    #[embassy_executor::task]
    async fn can_tx(mut tx: CanTx<'static>) {
        loop {
            while let Some((id, len, data)) = with_board(|b| b.tx.pop_front()).flatten() {
                let bytes = data.get(..usize::from(len)).unwrap_or(&[]);
                if let Ok(frame) = can::Frame::new_standard(id, bytes) {
                    tx.write(&frame).await;
                }
            }
            TX_READY.wait().await;
        }
    }

    /// Runs the card's configuration builds outside the tick (see the module docs).
    #[embassy_executor::task]
    async fn build() {
        loop {
            BUILD_READY.wait().await;
            while let Some(req) = with_board(|b| b.node.card_mut().take_build_request()).flatten() {
                let result = req.build(); // unlocked: the tick keeps running
                with_board(|b| {
                    b.node.card_mut().finish_build(req, result);
                    while let Some(m) = b.node.card_mut().poll_transmit() {
                        b.queue(&m);
                    }
                });
                TX_READY.signal(());
            }
        }
    }

    fn clocks() -> embassy_stm32::Config {
        use embassy_stm32::rcc::*;
        let mut c = embassy_stm32::Config::default();
        // HSI 16 MHz / 4 × 85 / 2 = 170 MHz (boost mode above 150 MHz).
        c.rcc.pll = Some(Pll {
            source: PllSource::HSI,
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL85,
            divp: None,
            divq: Some(PllQDiv::DIV2),
            divr: Some(PllRDiv::DIV2),
        });
        c.rcc.sys = Sysclk::PLL1_R;
        c.rcc.boost = true;
        // FDCAN kernel clock 85 MHz: 1 Mbit/s is 85 time quanta per bit.
        c.rcc.mux.fdcansel = mux::Fdcansel::PLL1_Q;
        c
    }

    /// TIM6 (basic timer, 170 MHz kernel clock): 1 MHz count, update every 1000 counts.
    fn start_tick() {
        pac::RCC.apb1enr1().modify(|w| w.set_tim6en(true));
        let t = pac::TIM6;
        t.psc().write_value(169);
        t.arr().write(|w| w.set_arr((PERIOD_US - 1) as u16));
        t.egr().write(|w| w.set_ug(true));
        t.sr().modify(|w| w.set_uif(false));
        t.dier().modify(|w| w.set_uie(true));
        t.cr1().modify(|w| w.set_cen(true));
        let mut nvic = cortex_m::Peripherals::take().map(|p| p.NVIC);
        if let Some(nvic) = nvic.as_mut() {
            // Highest priority: nothing delays the tick but the short critical sections.
            #[allow(unsafe_code)]
            // SAFETY: raising one interrupt's priority and unmasking it before any shared
            // data it uses is borrowed elsewhere (BOARD is filled before this call).
            unsafe {
                nvic.set_priority(pac::Interrupt::TIM6_DAC, 0);
                cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIM6_DAC);
            }
        }
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let p = embassy_stm32::init(clocks());
        defmt::info!("jointlab card, node {}", NODE);

        // Safe state before anything else: inhibit the amplifier.
        let inhibit = Output::new(p.PC8, Level::High, Speed::Low);
        let amp_fault = Input::new(p.PC9, Pull::Up);

        let pwm = SimplePwm::new(
            p.TIM3,
            Some(PwmPin::new(p.PB4, OutputType::PushPull)),
            None,
            None,
            None,
            Hertz(20_000),
            Default::default(),
        );
        let mut ch = pwm.split().ch1;
        ch.enable();
        let dir = Output::new(p.PB5, Level::Low, Speed::Low);
        let enable = Output::new(p.PB10, Level::Low, Speed::Low);
        let brake = Output::new(p.PA8, Level::High, Speed::Low);
        let stage = match PowerStage::new(ch, dir, enable, brake, FULL_SCALE) {
            Ok(s) => s,
            Err((_, e)) => {
                defmt::error!("power stage: {}", defmt::Debug2Format(&e));
                halt()
            }
        };

        let motor = Qei::new(p.TIM2, p.PA0, p.PA1, Default::default());
        #[cfg(feature = "output-encoder")]
        let output = Qei::new(p.TIM4, p.PB6, p.PB7, Default::default());

        let mut cfg = can::CanConfigurator::new(p.FDCAN1, p.PA11, p.PA12, Irqs);
        cfg.set_bitrate(1_000_000);
        let can: Can<'static> = cfg.into_normal_mode();
        let (tx, rx, props) = can.split();

        let Some(node) = NodeId::new(NODE) else {
            halt()
        };
        let mut card = match Card::new(node) {
            Ok(c) => c,
            Err(e) => {
                defmt::error!("card defaults do not build: {}", e.param());
                halt()
            }
        };
        card.set_deferred_builds(true);
        let board = Board {
            node: CardNode::new(card, u64::from(PERIOD_US), false),
            motor_last: motor.count(),
            motor,
            motor_counts: 0,
            #[cfg(feature = "output-encoder")]
            output_last: output.count(),
            #[cfg(feature = "output-encoder")]
            output,
            #[cfg(feature = "output-encoder")]
            output_counts: 0,
            stage,
            inhibit,
            amp_fault,
            seq: 0,
            tx: heapless::Deque::new(),
            tx_dropped: 0,
        };
        critical_section::with(|cs| BOARD.borrow(cs).replace(Some(board)));
        start_tick();
        spawner.spawn(can_rx(rx, props).unwrap_or_else(|_| halt()));
        spawner.spawn(can_tx(tx).unwrap_or_else(|_| halt()));
        spawner.spawn(build().unwrap_or_else(|_| halt()));
        defmt::info!("running: 1 kHz tick on TIM6, FDCAN1 1 Mbit/s");
    }

    fn halt() -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Panics cannot come from the card (it is panic-free by its lints), but a driver can
    /// panic: the amplifier goes off first — PWM duty 0, enable low, inhibit high, by
    /// register writes that need no driver state — then the message, then a halt.
    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        pac::TIM3.ccr(0).write(|w| w.set_ccr(0));
        pac::GPIOB.bsrr().write(|w| w.set_br(10, true)); // EN low
        pac::GPIOC.bsrr().write(|w| w.set_bs(8, true)); // INHIBIT high
        pac::GPIOA.bsrr().write(|w| w.set_bs(8, true)); // BRAKE on
        defmt::error!("panic: {}", defmt::Display2Format(info));
        halt()
    }
}
