//! Splitting a byte stream of concatenated space packets, resynchronising after bytes
//! that are not a packet.

use serde::Serialize;

use super::{decode_packet, DecodeError, Packet, TmBody};

/// One item of a packet stream.
#[derive(Clone, Debug, PartialEq)]
pub enum StreamItem {
    Packet {
        offset: usize,
        packet: Packet,
    },
    /// A stretch of bytes that did not decode; `reason` is why the first attempt failed.
    Corrupt {
        offset: usize,
        len: usize,
        reason: DecodeError,
    },
}

/// Splits a byte stream of concatenated space packets. After a packet that does not
/// decode, it scans byte by byte for the next offset where a packet with a valid header
/// and CRC starts, and reports the skipped bytes as one corrupt stretch.
pub struct StreamDecoder<'a> {
    split: Splitter<'a, StreamItem>,
}

impl<'a> StreamDecoder<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        StreamDecoder {
            split: Splitter::new(buf),
        }
    }
}

impl Iterator for StreamDecoder<'_> {
    type Item = StreamItem;
    fn next(&mut self) -> Option<StreamItem> {
        let item = self.split.next_with(|b, offset| {
            decode_packet(b).map(|packet| {
                let len = match &packet {
                    Packet::Tc(t) => t.len,
                    Packet::Tm(t) => t.len,
                };
                (StreamItem::Packet { offset, packet }, len)
            })
        })?;
        Some(match item {
            Split::Item(i) => i,
            Split::Skipped { offset, len, reason } => StreamItem::Corrupt { offset, len, reason },
        })
    }
}

/// What [`Splitter::next_with`] found next.
pub(super) enum Split<T, E> {
    Item(T),
    /// Bytes that are not a packet, up to the next one that parses (or the end); `reason`
    /// is why the first attempt failed.
    Skipped {
        offset: usize,
        len: usize,
        reason: E,
    },
}

/// The resynchronising walk over concatenated packets that [`StreamDecoder`] and
/// `out::RawStream` share; what counts as a packet is the caller's `parse`.
pub(super) struct Splitter<'a, T> {
    buf: &'a [u8],
    pos: usize,
    pending: Option<T>,
}

impl<'a, T> Splitter<'a, T> {
    pub(super) fn new(buf: &'a [u8]) -> Self {
        Splitter {
            buf,
            pos: 0,
            pending: None,
        }
    }

    /// The next packet or skipped stretch. `parse(bytes, offset)` reads the packet at
    /// the start of `bytes` (found at `offset` in the stream) and returns it with its
    /// length.
    pub(super) fn next_with<E>(
        &mut self,
        parse: impl Fn(&'a [u8], usize) -> Result<(T, usize), E>,
    ) -> Option<Split<T, E>> {
        if let Some(p) = self.pending.take() {
            return Some(Split::Item(p));
        }
        if self.pos >= self.buf.len() {
            return None;
        }
        let start = self.pos;
        let first_err = match parse(&self.buf[start..], start) {
            Ok((item, len)) => {
                self.pos += len;
                return Some(Split::Item(item));
            }
            Err(e) => e,
        };
        // Resynchronise: find the next offset where a packet parses.
        let mut off = start + 1;
        while off < self.buf.len() {
            if let Ok((item, len)) = parse(&self.buf[off..], off) {
                self.pending = Some(item);
                self.pos = off + len;
                return Some(Split::Skipped {
                    offset: start,
                    len: off - start,
                    reason: first_err,
                });
            }
            off += 1;
        }
        self.pos = self.buf.len();
        Some(Split::Skipped {
            offset: start,
            len: self.buf.len() - start,
            reason: first_err,
        })
    }
}

/// Counters of a stream decode.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StreamStats {
    pub tc: u64,
    pub tm: u64,
    /// Packets whose service/subservice (or function) the MIB does not define.
    pub unknown: u64,
    pub corrupt_stretches: u64,
    pub corrupt_bytes: u64,
}

impl StreamStats {
    pub fn add(&mut self, item: &StreamItem) {
        match item {
            StreamItem::Packet { packet, .. } => match packet {
                Packet::Tc(t) => {
                    self.tc += 1;
                    if t.name.is_none() {
                        self.unknown += 1;
                    }
                }
                Packet::Tm(t) => {
                    self.tm += 1;
                    if matches!(t.body, TmBody::Unknown { .. }) {
                        self.unknown += 1;
                    }
                }
            },
            StreamItem::Corrupt { len, .. } => {
                self.corrupt_stretches += 1;
                self.corrupt_bytes += *len as u64;
            }
        }
    }
}
