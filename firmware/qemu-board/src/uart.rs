//! The `virt` machine's 16550 UART at 0x1000_0000, polled: the space link's byte stream,
//! as board A's USB serial carries it (COBS frames; `fw_core::link`). No interrupts: the
//! main loop reads what arrived and writes what is queued every time it wakes. QEMU
//! takes no byte from the chardev while the receive FIFO is full, so nothing is lost on
//! the way in, only delayed.
#![allow(unsafe_code)]

const BASE: usize = 0x1000_0000;
const RBR_THR: usize = 0;
const IER: usize = 1;
const FCR: usize = 2;
const LCR: usize = 3;
const LSR: usize = 5;
const LSR_DATA_READY: u8 = 0x01;
const LSR_THR_EMPTY: u8 = 0x20;

fn read(reg: usize) -> u8 {
    // SAFETY: a register of the virt machine's 16550 (its MMIO page), byte-wide.
    unsafe { core::ptr::read_volatile((BASE + reg) as *const u8) }
}

fn write(reg: usize, v: u8) {
    // SAFETY: as in `read`.
    unsafe { core::ptr::write_volatile((BASE + reg) as *mut u8, v) }
}

/// The UART, set up: 8N1, FIFOs on and cleared, interrupts off.
pub struct Uart(());

impl Uart {
    pub fn new() -> Self {
        write(IER, 0);
        write(LCR, 0x03);
        write(FCR, 0x07);
        Uart(())
    }

    /// Bytes received, into `buf`; how many.
    pub fn read(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buf.len() && read(LSR) & LSR_DATA_READY != 0 {
            buf[n] = read(RBR_THR);
            n += 1;
        }
        n
    }

    /// Writes as many bytes of `bytes` as the transmitter takes now; how many.
    pub fn write(&mut self, bytes: &[u8]) -> usize {
        let mut n = 0;
        while n < bytes.len() && read(LSR) & LSR_THR_EMPTY != 0 {
            write(RBR_THR, bytes[n]);
            n += 1;
        }
        n
    }
}
