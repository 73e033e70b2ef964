//! Host files through ARM semihosting, for the QEMU images (`-semihosting-config
//! enable=on,target=native`: QEMU opens the named file relative to its working directory).
//! cortex-m-semihosting offers only writes to the console; reads need the raw `SYS_READ`.
#![allow(unsafe_code)]

use cortex_m_semihosting::{nr, syscall};

/// An open host file.
#[derive(Debug)]
pub struct HostFile {
    fd: usize,
}

impl HostFile {
    /// Opens `name` (a NUL-terminated path) for binary reading.
    pub fn open_read(name: &[u8]) -> Option<HostFile> {
        Self::open(name, nr::open::R_BINARY)
    }

    /// Creates (truncates) `name` (a NUL-terminated path) for binary writing.
    pub fn create(name: &[u8]) -> Option<HostFile> {
        Self::open(name, nr::open::W_TRUNC_BINARY)
    }

    fn open(name: &[u8], mode: usize) -> Option<HostFile> {
        let len = name.len().checked_sub(1)?;
        if name.last() != Some(&0) {
            return None;
        }
        // SAFETY: SYS_OPEN reads `len` bytes of the NUL-terminated `name`, which outlives the
        // call; it writes no guest memory.
        let fd = unsafe { syscall!(OPEN, name.as_ptr(), mode, len) };
        (fd as isize != -1).then_some(HostFile { fd })
    }

    /// Reads up to `buf.len()` bytes; returns how many were read (0 at the end of file).
    pub fn read(&mut self, buf: &mut [u8]) -> usize {
        // SAFETY: SYS_READ writes at most `buf.len()` bytes into `buf`, which is exclusively
        // borrowed for the call; it returns the number of bytes NOT read.
        let left = unsafe { syscall!(READ, self.fd, buf.as_mut_ptr(), buf.len()) };
        buf.len().saturating_sub(left)
    }

    /// Writes all of `buf`; false if the host refused.
    pub fn write_all(&mut self, buf: &[u8]) -> bool {
        // SAFETY: SYS_WRITE reads `buf.len()` bytes of `buf`, borrowed for the call; it
        // returns the number of bytes NOT written.
        let left = unsafe { syscall!(WRITE, self.fd, buf.as_ptr(), buf.len()) };
        left == 0
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: SYS_CLOSE takes the handle by value and touches no guest memory.
        unsafe {
            syscall!(CLOSE, self.fd);
        }
    }
}

/// The command line QEMU was given for the image (`-semihosting-config …,arg=A,arg=B`: the
/// arguments joined by spaces), written into `buf`; `None` if the host has none.
pub fn cmdline(buf: &mut [u8]) -> Option<&[u8]> {
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    // SAFETY: SYS_GET_CMDLINE writes at most `block[1]` bytes to `block[0]` (our exclusively
    // borrowed `buf`) and the length it wrote into `block[1]`; `block` outlives the call.
    let r = unsafe { cortex_m_semihosting::syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    if r != 0 {
        return None;
    }
    let [_, len] = block;
    buf.get(..len)
}

/// Host time since QEMU started, ns (`SYS_ELAPSED`; QEMU counts in nanoseconds,
/// `SYS_TICKFREQ` = 10⁹): the PIL image's real-time clock.
pub fn elapsed_ns() -> u64 {
    let mut block = [0usize; 2];
    // SAFETY: SYS_ELAPSED writes two words (the 64-bit count, low word first) into `block`,
    // which is exclusively borrowed for the call.
    let r = unsafe { cortex_m_semihosting::syscall1(nr::ELAPSED, block.as_mut_ptr() as usize) };
    if r != 0 {
        return 0;
    }
    let [lo, hi] = block;
    (hi as u64).wrapping_shl(32) | lo as u64
}
