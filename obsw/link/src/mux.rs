//! Space packets into fixed-length TM frames and back (CCSDS 132.0-B-3 §4.1.4.2, packet
//! service).
//!
//! [`PacketMux`] fills one virtual channel's packet zone: packets are appended in order and
//! may span frames; a frame is emitted when its zone is full, or on [`PacketMux::flush`]
//! (the rest is filled with an idle packet, APID 0x7FF). The first header pointer gives the
//! offset of the first packet that starts in the frame, 0x7FF when none does.
//!
//! [`PacketDemux`] extracts packets again. It follows the VC frame counter; on a gap (or any
//! doubt) it drops the partial packet, counts it, and resynchronises on the next frame's first
//! header pointer. Packet lengths come from the space packet primary header; a length beyond
//! the mission's largest packet is treated as corruption (dropped, resynchronise).

use heapless::Vec;

/// Largest space packet the demultiplexer reassembles (TM packets are far smaller; a TC
/// frame carries at most `mib::link::tc_frame::MAX_PACKET_LEN`).
pub const MAX_PACKET: usize = 4096;

const PRIMARY_HEADER: usize = 6;
const IDLE_APID: u16 = 0x7FF;

/// Length of the space packet starting at `b` (needs 6 bytes).
fn packet_len(b: &[u8]) -> Option<usize> {
    if b.len() < PRIMARY_HEADER {
        return None;
    }
    Some(usize::from(u16::from_be_bytes([b[4], b[5]])) + 7)
}

/// Writes an idle packet of exactly `n` bytes (n ≥ 7) into `out`; for 1..=6 bytes, which
/// cannot hold a packet, the bytes are 0xFF fill that the demultiplexer skips only because
/// the next frame's first header pointer tells it where the next packet starts.
fn idle_fill(out: &mut [u8]) {
    let n = out.len();
    if n >= 7 {
        let hdr = [0x07, 0xFF, 0xC0, 0x00];
        out[..4].copy_from_slice(&hdr);
        out[4..6].copy_from_slice(&((n - 7) as u16).to_be_bytes());
        out[6..].fill(0x55);
    } else {
        out.fill(0xFF);
    }
}

/// Why a packet could not be queued.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MuxError {
    /// Not a space packet (shorter than its header says or than 7 bytes).
    NotAPacket,
}

/// One virtual channel's multiplexer with a packet zone of `Z` bytes (or fewer, chosen at
/// run time with [`PacketMux::with_len`]).
#[derive(Debug)]
pub struct PacketMux<const Z: usize> {
    zone: [u8; Z],
    /// The zone length in use (≤ Z).
    len: usize,
    fill: usize,
    /// Offset of the first packet header in this zone, if any.
    first: Option<usize>,
}

impl<const Z: usize> Default for PacketMux<Z> {
    fn default() -> Self {
        PacketMux {
            zone: [0; Z],
            len: Z,
            fill: 0,
            first: None,
        }
    }
}

/// A full packet zone and its first header pointer.
pub struct Zone<'a> {
    pub data: &'a [u8],
    pub fhp: crate::tm::FirstHeaderPointer,
}

impl<const Z: usize> PacketMux<Z> {
    /// A multiplexer with a packet zone of `len` bytes (at most Z; 1 at least).
    pub fn with_len(len: usize) -> Self {
        PacketMux {
            len: len.clamp(1, Z),
            ..PacketMux::default()
        }
    }

    /// The packet zone length.
    pub fn zone_len(&self) -> usize {
        self.len
    }

    /// Appends `packet`; calls `emit` with each zone that fills up (a packet can fill several).
    pub fn push(&mut self, packet: &[u8], mut emit: impl FnMut(Zone<'_>)) -> Result<(), MuxError> {
        if packet_len(packet) != Some(packet.len()) {
            return Err(MuxError::NotAPacket);
        }
        if self.first.is_none() {
            self.first = Some(self.fill);
        }
        let mut rest = packet;
        while !rest.is_empty() {
            let n = rest.len().min(self.len - self.fill);
            self.zone[self.fill..self.fill + n].copy_from_slice(&rest[..n]);
            self.fill += n;
            rest = &rest[n..];
            if self.fill == self.len {
                self.emit_zone(&mut emit);
            }
        }
        Ok(())
    }

    /// Bytes the current zone still takes before it fills.
    pub fn free(&self) -> usize {
        self.len - self.fill
    }

    /// Whether bytes are waiting.
    pub fn pending(&self) -> bool {
        self.fill > 0
    }

    /// Pads the current zone with idle data and emits it (nothing when empty).
    pub fn flush(&mut self, mut emit: impl FnMut(Zone<'_>)) {
        if self.fill == 0 {
            return;
        }
        // The idle packet is a packet: when no other starts in this zone, the first header
        // pointer locates it (132.0-B-3 §4.1.2.7; 0xFF fill of 1..=6 bytes is no packet).
        if self.first.is_none() && self.len - self.fill >= 7 {
            self.first = Some(self.fill);
        }
        idle_fill(&mut self.zone[self.fill..self.len]);
        self.emit_zone(&mut emit);
    }

    fn emit_zone(&mut self, emit: &mut impl FnMut(Zone<'_>)) {
        use crate::tm::FirstHeaderPointer as F;
        let fhp = match self.first {
            Some(o) => F::Offset(o as u16),
            None => F::NoPacketStart,
        };
        emit(Zone {
            data: &self.zone[..self.len],
            fhp,
        });
        self.fill = 0;
        self.first = None;
    }
}

/// What the demultiplexer dropped, for HK.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DemuxCounters {
    pub packets: u32,
    pub idle_packets: u32,
    /// Frames missing according to the VC frame counter.
    pub frames_lost: u32,
    /// Partial packets dropped (a gap cut them).
    pub partial_dropped: u32,
    /// Frames whose continuation bytes were skipped while resynchronising.
    pub resync_skips: u32,
    /// Packet headers with a length beyond `MAX_PACKET` or a bad first header pointer.
    pub corrupt: u32,
}

/// Extracts packets from one virtual channel's frames.
#[derive(Debug)]
pub struct PacketDemux {
    buf: Vec<u8, MAX_PACKET>,
    /// Whether the byte stream position is known (false after a gap until a first header
    /// pointer).
    in_sync: bool,
    next_vc_count: Option<u8>,
    pub counters: DemuxCounters,
}

impl Default for PacketDemux {
    fn default() -> Self {
        PacketDemux {
            buf: Vec::new(),
            in_sync: false,
            next_vc_count: None,
            counters: DemuxCounters::default(),
        }
    }
}

impl PacketDemux {
    /// Feeds one frame's packet zone; calls `out` with each complete packet (idle packets are
    /// counted, not passed on).
    pub fn feed(&mut self, vc_count: u8, fhp: crate::tm::FirstHeaderPointer, zone: &[u8], mut out: impl FnMut(&[u8])) {
        use crate::tm::FirstHeaderPointer as F;
        if let Some(expected) = self.next_vc_count {
            if vc_count != expected {
                self.counters.frames_lost += u32::from(vc_count.wrapping_sub(expected));
                self.drop_partial();
            }
        }
        self.next_vc_count = Some(vc_count.wrapping_add(1));
        let start = match fhp {
            F::IdleOnly => {
                self.drop_partial();
                return;
            }
            F::NoPacketStart => {
                if self.in_sync {
                    self.consume(zone, &mut out);
                } else {
                    self.counters.resync_skips += 1;
                }
                return;
            }
            F::Offset(o) => usize::from(o),
        };
        if start > zone.len() {
            self.counters.corrupt += 1;
            self.drop_partial();
            return;
        }
        if self.in_sync {
            // The bytes before the pointer must finish the packet in progress exactly.
            self.consume(&zone[..start], &mut out);
            if self.buf.first() == Some(&0xFF) {
                // The 0xFF fill of a flushed zone too short for an idle packet.
                self.buf.clear();
            } else if !self.buf.is_empty() {
                self.counters.corrupt += 1;
                self.drop_partial();
            }
        } else if start > 0 {
            self.counters.resync_skips += 1;
        }
        self.in_sync = true;
        self.consume(&zone[start..], &mut out);
    }

    fn drop_partial(&mut self) {
        if !self.buf.is_empty() {
            self.counters.partial_dropped += 1;
        }
        self.buf.clear();
        self.in_sync = false;
    }

    /// Appends bytes of the packet stream, emitting complete packets.
    fn consume(&mut self, mut bytes: &[u8], out: &mut impl FnMut(&[u8])) {
        while !bytes.is_empty() && self.in_sync {
            // Complete the header first.
            if self.buf.len() < PRIMARY_HEADER {
                let n = (PRIMARY_HEADER - self.buf.len()).min(bytes.len());
                // Capacity: the buffer holds at most MAX_PACKET ≥ 6 here.
                let _ = self.buf.extend_from_slice(&bytes[..n]);
                bytes = &bytes[n..];
                if self.buf.len() < PRIMARY_HEADER {
                    return;
                }
                // 0xFF fill (a zone tail too short for an idle packet): stop until the next
                // first header pointer.
                if self.buf[..2] == [0xFF, 0xFF] {
                    self.buf.clear();
                    self.in_sync = false;
                    return;
                }
            }
            let total = packet_len(&self.buf).unwrap_or(0);
            if total > MAX_PACKET {
                self.counters.corrupt += 1;
                self.buf.clear();
                self.in_sync = false;
                return;
            }
            let n = (total - self.buf.len()).min(bytes.len());
            let _ = self.buf.extend_from_slice(&bytes[..n]);
            bytes = &bytes[n..];
            if self.buf.len() == total {
                let apid = u16::from_be_bytes([self.buf[0], self.buf[1]]) & 0x7FF;
                if apid == IDLE_APID {
                    self.counters.idle_packets += 1;
                } else {
                    self.counters.packets += 1;
                    out(&self.buf);
                }
                self.buf.clear();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tm::FirstHeaderPointer as F;
    use proptest::prelude::*;

    fn packet(apid: u16, seq: u16, len: usize) -> std::vec::Vec<u8> {
        let mut p = vec![0u8; len.max(7)];
        p[0..2].copy_from_slice(&(0x0800 | apid).to_be_bytes());
        p[2..4].copy_from_slice(&(0xC000 | mib::headers::SeqCount::new(seq).get()).to_be_bytes());
        let n = p.len();
        p[4..6].copy_from_slice(&((n - 7) as u16).to_be_bytes());
        for (i, b) in p[6..].iter_mut().enumerate() {
            *b = (i as u8) ^ (seq as u8);
        }
        p
    }

    type Frame = (u8, F, std::vec::Vec<u8>);

    fn mux_all(packets: &[std::vec::Vec<u8>]) -> std::vec::Vec<Frame> {
        let mut m = PacketMux::<64>::default();
        let mut frames = vec![];
        let mut vc = 0u8;
        let mut emit = |z: Zone<'_>| {
            frames.push((vc, z.fhp, z.data.to_vec()));
            vc = vc.wrapping_add(1);
        };
        for p in packets {
            m.push(p, &mut emit).unwrap();
        }
        m.flush(&mut emit);
        frames
    }

    // verifies: LINK-TM-02
    #[test]
    fn packets_span_frames_and_come_back() {
        let ps = vec![packet(1, 0, 10), packet(2, 1, 150), packet(3, 2, 7), packet(4, 3, 60)];
        let frames = mux_all(&ps);
        assert_eq!(frames[0].1, F::Offset(0));
        assert_eq!(frames[1].1, F::NoPacketStart); // inside the 150-byte packet
        assert_eq!(frames[2].1, F::Offset(32)); // the 7-byte packet at 160 = 128 + 32
        let mut d = PacketDemux::default();
        let mut got = vec![];
        for (vc, fhp, z) in &frames {
            d.feed(*vc, *fhp, z, |p| got.push(p.to_vec()));
        }
        assert_eq!(got, ps);
        assert_eq!(d.counters.packets, 4);
        assert_eq!(d.counters.frames_lost, 0);
    }

    // verifies: LINK-TM-02
    #[test]
    fn lost_frame_drops_the_cut_packet_and_resyncs_on_fhp() {
        let ps = vec![packet(1, 0, 10), packet(2, 1, 150), packet(3, 2, 7), packet(4, 3, 60)];
        let frames = mux_all(&ps);
        let mut d = PacketDemux::default();
        let mut got = vec![];
        for (i, (vc, fhp, z)) in frames.iter().enumerate() {
            if i == 1 {
                continue;
            }
            d.feed(*vc, *fhp, z, |p| got.push(p.to_vec()));
        }
        assert_eq!(got, vec![ps[0].clone(), ps[2].clone(), ps[3].clone()]);
        assert_eq!(d.counters.frames_lost, 1);
        assert_eq!(d.counters.partial_dropped, 1);
    }

    // verifies: LINK-TM-02
    #[test]
    fn idle_only_frames_and_bad_pointers_are_counted() {
        let mut d = PacketDemux::default();
        let mut n = 0;
        d.feed(0, F::IdleOnly, &[0; 64], |_| n += 1);
        d.feed(1, F::Offset(65), &[0; 64], |_| n += 1);
        assert_eq!(d.counters.corrupt, 1);
        // A header claiming 65535 + 7 bytes.
        let mut z = [0u8; 64];
        z[..6].copy_from_slice(&[0x08, 0x01, 0xC0, 0, 0xFF, 0xFF]);
        d.feed(2, F::Offset(0), &z, |_| n += 1);
        assert_eq!(d.counters.corrupt, 2);
        assert_eq!(n, 0);
        let mut m = PacketMux::<64>::default();
        assert_eq!(m.push(&[1, 2, 3], |_| {}), Err(MuxError::NotAPacket));
    }

    proptest! {
        // verifies: LINK-TM-02
        #[test]
        fn mux_demux_with_random_loss_never_corrupts(
            lens in proptest::collection::vec(7usize..200, 1..40),
            lost in proptest::collection::vec(any::<bool>(), 200),
        ) {
            let ps: std::vec::Vec<_> = lens.iter().enumerate().map(|(i, l)| packet(5, i as u16, *l)).collect();
            let frames = mux_all(&ps);
            let mut d = PacketDemux::default();
            let mut got = vec![];
            for (i, (vc, fhp, z)) in frames.iter().enumerate() {
                if lost[i % lost.len()] && i % 3 != 0 { continue; }
                d.feed(*vc, *fhp, z, |p| got.push(p.to_vec()));
            }
            // Every packet out is one that went in, in order, unchanged.
            let mut it = ps.iter();
            for g in &got {
                prop_assert!(it.any(|p| p == g), "corrupted or reordered packet");
            }
        }

        // verifies: LINK-RX-02
        #[test]
        fn demux_random_bytes_never_panic(
            zones in proptest::collection::vec((any::<u8>(), any::<u16>(), proptest::collection::vec(any::<u8>(), 0..80)), 0..20)
        ) {
            let mut d = PacketDemux::default();
            for (vc, fhp, z) in zones {
                d.feed(vc, F::from(fhp), &z, |_| {});
            }
        }
    }
}
