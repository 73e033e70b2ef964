//! The QEMU machines' UART0 as a polled byte link, the serial line of the PIL image
//! (`-serial chardev:…` puts it on a host socket). Polled, not interrupt-driven: the PIL
//! loop has nothing else to do while it waits for the next byte, and a poll keeps the card's
//! work in one thread with no shared state.
//!
//! * mps2-an386 (thumbv7em): CMSDK APB UART0 at 0x4000_4000, one-byte buffers.
//! * microbit (thumbv6m): nRF51 UART0 at 0x4000_2000, a six-byte receive FIFO.
#![allow(unsafe_code)]

use core::ptr::{read_volatile, write_volatile};

/// UART0 of the machine this image is built for.
#[derive(Debug)]
pub struct Uart {
    _private: (),
}

#[cfg(target_has_atomic = "32")]
mod regs {
    //! CMSDK APB UART (ARM DDI0479C).
    pub const BASE: usize = 0x4000_4000;
    pub const DATA: usize = BASE;
    pub const STATE: usize = BASE + 0x04;
    pub const CTRL: usize = BASE + 0x08;
    pub const BAUDDIV: usize = BASE + 0x10;
    pub const STATE_TX_FULL: u32 = 1;
    pub const STATE_RX_FULL: u32 = 1 << 1;
    pub const INTSTATUS: usize = BASE + 0x0C;
    pub const CTRL_TX_RX_EN_RX_INT: u32 = 0b1011;
    pub const INT_RX: u32 = 1 << 1;
    /// UART0's receive interrupt on the AN386.
    pub const IRQ: u16 = 0;
    /// 25 MHz / 115 200 baud (the model needs a divisor ≥ 16 to pass bytes at all).
    pub const DIV_115200: u32 = 217;
}

#[cfg(not(target_has_atomic = "32"))]
mod regs {
    //! nRF51 UART (nRF51 Series Reference Manual v3.0, §29).
    pub const BASE: usize = 0x4000_2000;
    pub const STARTRX: usize = BASE;
    pub const STARTTX: usize = BASE + 0x008;
    pub const RXDRDY: usize = BASE + 0x108;
    pub const TXDRDY: usize = BASE + 0x11C;
    pub const ENABLE: usize = BASE + 0x500;
    pub const RXD: usize = BASE + 0x518;
    pub const TXD: usize = BASE + 0x51C;
    pub const BAUDRATE: usize = BASE + 0x524;
    pub const INTENSET: usize = BASE + 0x304;
    pub const INT_RXDRDY: u32 = 1 << 2;
    /// UART0's interrupt (peripheral id 2).
    pub const IRQ: u16 = 2;
    pub const ENABLE_UART: u32 = 4;
    pub const BAUD_115200: u32 = 0x01D7_E000;
}

/// The UART's interrupt line, for the NVIC.
#[derive(Clone, Copy, Debug)]
struct Irq;

// SAFETY: `regs::IRQ` is the machine's interrupt number of UART0.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        regs::IRQ
    }
}

fn rd(addr: usize) -> u32 {
    // SAFETY: `addr` is one of the UART registers above: a valid, aligned MMIO word.
    unsafe { read_volatile(addr as *const u32) }
}

fn wr(addr: usize, v: u32) {
    // SAFETY: as in `rd`; writing these registers has no effect on memory.
    unsafe { write_volatile(addr as *mut u32, v) }
}

impl Uart {
    /// Enables receiver and transmitter at 115 200 baud (the rate means nothing to QEMU).
    pub fn init() -> Uart {
        #[cfg(target_has_atomic = "32")]
        {
            wr(regs::BAUDDIV, regs::DIV_115200);
            wr(regs::CTRL, regs::CTRL_TX_RX_EN_RX_INT);
        }
        #[cfg(not(target_has_atomic = "32"))]
        {
            wr(regs::ENABLE, regs::ENABLE_UART);
            wr(regs::BAUDRATE, regs::BAUD_115200);
            wr(regs::TXDRDY, 0);
            wr(regs::RXDRDY, 0);
            wr(regs::STARTTX, 1);
            wr(regs::STARTRX, 1);
            wr(regs::INTENSET, regs::INT_RXDRDY);
        }
        cortex_m::interrupt::disable();
        // SAFETY: PRIMASK is set for good (above), so unmasking only lets the line wake
        // `wfi`; no handler ever runs and no critical section is broken.
        unsafe { cortex_m::peripheral::NVIC::unmask(Irq) };
        Uart { _private: () }
    }

    /// True if a byte is waiting.
    #[inline]
    pub fn ready(&self) -> bool {
        #[cfg(target_has_atomic = "32")]
        {
            rd(regs::STATE) & regs::STATE_RX_FULL != 0
        }
        #[cfg(not(target_has_atomic = "32"))]
        {
            rd(regs::RXDRDY) != 0
        }
    }

    /// Sleeps until a byte arrives or another interrupt (SysTick) pends. Pending state is
    /// cleared first and the receiver checked again after, so a byte that arrives in between
    /// either is seen or wakes the `wfi` at once.
    pub fn sleep(&mut self) {
        #[cfg(target_has_atomic = "32")]
        wr(regs::INTSTATUS, regs::INT_RX);
        cortex_m::peripheral::NVIC::unpend(Irq);
        cortex_m::peripheral::SCB::clear_pendst();
        if !self.ready() {
            cortex_m::asm::wfi();
        }
    }

    /// A received byte, if one is waiting.
    #[inline]
    pub fn try_read(&mut self) -> Option<u8> {
        #[cfg(target_has_atomic = "32")]
        {
            (rd(regs::STATE) & regs::STATE_RX_FULL != 0).then(|| rd(regs::DATA) as u8)
        }
        #[cfg(not(target_has_atomic = "32"))]
        {
            if rd(regs::RXDRDY) == 0 {
                return None;
            }
            // Clear the event before reading: the read sets it again if the FIFO holds more.
            wr(regs::RXDRDY, 0);
            Some(rd(regs::RXD) as u8)
        }
    }

    /// Sends one byte (waits while the transmitter is busy).
    pub fn write_byte(&mut self, b: u8) {
        #[cfg(target_has_atomic = "32")]
        {
            while rd(regs::STATE) & regs::STATE_TX_FULL != 0 {}
            wr(regs::DATA, u32::from(b));
        }
        #[cfg(not(target_has_atomic = "32"))]
        {
            wr(regs::TXDRDY, 0);
            wr(regs::TXD, u32::from(b));
            while rd(regs::TXDRDY) == 0 {}
        }
    }

    /// Sends all of `bytes`.
    pub fn write_all(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_byte(*b);
        }
    }
}
