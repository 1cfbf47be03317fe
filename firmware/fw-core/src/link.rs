//! The byte-stream links of the boards, between the UART/USB drivers and the control
//! task, over bounded embassy-sync queues:
//!
//! - ground uplink: transport bytes → [`Deframer`] → one TC per [`TcChannel`] slot;
//! - ground downlink: TM packets → COBS frames → [`ByteQueue`] → transport;
//! - A–B link: transport bytes ↔ [`ByteQueue`]s (the domain's A–B protocol frames
//!   and checks them itself).
//!
//! Every queue is bounded (sizes in [`crate::config`]) and says what happens when it is
//! full: the ground uplink drops the TC (the ground resends an unacknowledged TC), the
//! downlink refuses a whole frame (the caller keeps the packet), the A–B queues drop
//! bytes, which the A–B protocol detects (bad frame) and recovers (resend).

use crate::config;
use core::cell::Cell;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::pipe::Pipe;
use mmic_stream::{encode, Deframer};

/// One uplinked TC (a whole space packet).
pub type TcPacket = heapless::Vec<u8, { config::GROUND_RX_BUF }>;
/// Decoded TCs waiting for the OBSW.
pub type TcChannel = Channel<CriticalSectionRawMutex, TcPacket, { config::TC_QUEUE_DEPTH }>;
/// A bounded byte queue between a driver task and the control task.
pub type ByteQueue<const N: usize> = Pipe<CriticalSectionRawMutex, N>;

/// Counters of one link direction, shared between tasks.
pub struct Counters {
    inner: Mutex<CriticalSectionRawMutex, Cell<LinkStats>>,
}

/// Snapshot of a link's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames (or byte chunks) delivered.
    pub delivered: u32,
    /// Frames dropped for bad framing or length.
    pub frame_errors: u32,
    /// Frames or bytes dropped because the next queue was full.
    pub overflow: u32,
    /// Transport read/write errors.
    pub io_errors: u32,
}

impl Default for Counters {
    fn default() -> Self {
        Self::new()
    }
}

impl Counters {
    pub const fn new() -> Self {
        Self {
            inner: Mutex::new(Cell::new(LinkStats {
                delivered: 0,
                frame_errors: 0,
                overflow: 0,
                io_errors: 0,
            })),
        }
    }
    pub fn get(&self) -> LinkStats {
        self.inner.lock(|c| c.get())
    }
    pub(crate) fn update(&self, f: impl FnOnce(&mut LinkStats)) {
        self.inner.lock(|c| {
            let mut s = c.get();
            f(&mut s);
            c.set(s);
        })
    }
}

/// Feeds received ground-link bytes through the deframer; each complete TC goes to
/// `tcs` (dropped and counted when the queue is full).
pub fn uplink_bytes<const N: usize>(deframer: &mut Deframer<N>, bytes: &[u8], tcs: &TcChannel, counters: &Counters) {
    for &b in bytes {
        match deframer.push(b) {
            None => {}
            Some(Ok(packet)) => {
                let mut tc = TcPacket::new();
                // `packet` is at most N <= GROUND_RX_BUF bytes.
                if tc.extend_from_slice(packet).is_err() {
                    counters.update(|s| s.frame_errors = s.frame_errors.wrapping_add(1));
                } else if tcs.try_send(tc).is_err() {
                    counters.update(|s| s.overflow = s.overflow.wrapping_add(1));
                } else {
                    counters.update(|s| s.delivered = s.delivered.wrapping_add(1));
                }
            }
            Some(Err(_)) => counters.update(|s| s.frame_errors = s.frame_errors.wrapping_add(1)),
        }
    }
}

/// Frames `packet` and queues the whole frame for the downlink, or nothing: returns
/// `false` (and counts) when the queue lacks room, so the stream never carries half a
/// frame and the caller can keep the packet for later.
pub fn downlink_packet<const N: usize>(queue: &ByteQueue<N>, packet: &[u8], counters: &Counters) -> bool {
    let mut frame = [0u8; config::GROUND_FRAME_MAX];
    let Ok(n) = encode(packet, &mut frame) else {
        counters.update(|s| s.frame_errors = s.frame_errors.wrapping_add(1));
        return false;
    };
    if queue.free_capacity() < n {
        counters.update(|s| s.overflow = s.overflow.wrapping_add(1));
        return false;
    }
    // Single producer: the room checked above is still there. A ring buffer hands out
    // contiguous space only, so a frame that wraps around takes two writes.
    let mut rest = &frame[..n];
    while !rest.is_empty() {
        match queue.try_write(rest) {
            Ok(k) => rest = &rest[k..],
            Err(_) => break,
        }
    }
    if rest.is_empty() {
        counters.update(|s| s.delivered = s.delivered.wrapping_add(1));
        true
    } else {
        // Unreachable with one producer; counted rather than assumed.
        counters.update(|s| s.overflow = s.overflow.wrapping_add(1));
        false
    }
}

/// Queues bytes for a transmitter; bytes that do not fit are dropped and counted.
pub fn push_bytes<const N: usize>(queue: &ByteQueue<N>, bytes: &[u8], counters: &Counters) {
    let mut rest = bytes;
    while !rest.is_empty() {
        match queue.try_write(rest) {
            Ok(n) => rest = &rest[n..],
            Err(_) => break,
        }
    }
    if rest.is_empty() {
        if !bytes.is_empty() {
            counters.update(|s| s.delivered = s.delivered.wrapping_add(1));
        }
    } else {
        let lost = rest.len() as u32;
        counters.update(|s| s.overflow = s.overflow.wrapping_add(lost));
    }
}

/// Takes everything queued (up to `buf.len()` bytes) without waiting.
pub fn drain<const N: usize>(queue: &ByteQueue<N>, buf: &mut [u8]) -> usize {
    let mut n = 0;
    while n < buf.len() {
        match queue.try_read(&mut buf[n..]) {
            Ok(k) if k > 0 => n += k,
            _ => break,
        }
    }
    n
}

/// Driver task body: everything the transport receives goes into `queue`.
pub async fn reader_to_queue<R: embedded_io_async::Read, const N: usize>(
    mut rx: R,
    queue: &ByteQueue<N>,
    counters: &Counters,
) -> ! {
    let mut buf = [0u8; config::UART_READ_CHUNK];
    loop {
        match rx.read(&mut buf).await {
            Ok(n) => push_bytes(queue, &buf[..n], counters),
            Err(_) => counters.update(|s| s.io_errors = s.io_errors.wrapping_add(1)),
        }
    }
}

/// Driver task body: the ground uplink, transport bytes to TCs.
pub async fn uplink_task<R: embedded_io_async::Read>(mut rx: R, tcs: &TcChannel, counters: &Counters) -> ! {
    let mut deframer: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    let mut buf = [0u8; config::UART_READ_CHUNK];
    loop {
        match rx.read(&mut buf).await {
            Ok(n) => uplink_bytes(&mut deframer, &buf[..n], tcs, counters),
            Err(_) => counters.update(|s| s.io_errors = s.io_errors.wrapping_add(1)),
        }
    }
}

/// Driver task body: whatever is queued goes out on the transport, in order.
pub async fn queue_to_writer<W: embedded_io_async::Write, const N: usize>(
    queue: &ByteQueue<N>,
    mut tx: W,
    counters: &Counters,
) -> ! {
    let mut buf = [0u8; config::UART_READ_CHUNK];
    loop {
        let n = queue.read(&mut buf).await;
        if tx.write_all(&buf[..n]).await.is_err() {
            counters.update(|s| s.io_errors = s.io_errors.wrapping_add(1));
        }
    }
}

/// Whether this build of fw-core holds [`BarePackets`] (feature `bare-link`); board A's
/// image refuses to build when it does.
pub const BARE_LINK_BUILT: bool = cfg!(feature = "bare-link");

/// A bare-packet ground link for test harnesses only (feature `bare-link`, enabled by the
/// QEMU tests and fw-core's host tests, never by an image): one space packet per COBS
/// frame each way, no authentication. The control-period and OBSW tests that are not
/// about the link use it to reach `Obsw::handle_tc` without building transfer frames.
/// Issue 22: the bare-packet link is never in firmware; the images run
/// [`crate::spacelink::FrameLink`].
#[cfg(feature = "bare-link")]
#[derive(Clone, Copy, Debug, Default)]
pub struct BarePackets;

#[cfg(feature = "bare-link")]
impl crate::cycle::GroundLink for BarePackets {
    /// Every packet to the OBSW: the file service takes nothing unauthenticated.
    fn receive<S: obsw_core::tm::TmStore, F: crate::files::FileService, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut obsw_core::obsw::Obsw<S>,
        _files: &mut F,
        tcs: &TcChannel,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        let mut sink = crate::cycle::GroundSink {
            link: self,
            queue: tm,
            counters: tm_stats,
        };
        while let Ok(tc) = tcs.try_receive() {
            obsw.handle_tc(now, &tc, &mut sink);
        }
    }
    fn send_tm<const N: usize>(&mut self, packet: &[u8], tm: &ByteQueue<N>, tm_stats: &Counters) {
        downlink_packet(tm, packet, tm_stats);
    }
    /// One COBS frame per packet: at most 3 + 1 per 254 bytes more than the packet, a
    /// fifth of the smallest (20-byte) packet; one largest frame kept for realtime TM.
    fn replay_room<const N: usize>(&self, tm: &ByteQueue<N>) -> usize {
        tm.free_capacity().saturating_sub(crate::config::GROUND_FRAME_MAX) * 4 / 5
    }
    fn end_period<S: obsw_core::tm::TmStore, const N: usize>(
        &mut self,
        _now: u64,
        _obsw: &mut obsw_core::obsw::Obsw<S>,
        _tm: &ByteQueue<N>,
        _tm_stats: &Counters,
    ) {
    }
}
