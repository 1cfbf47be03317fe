//! Concatenated packets split with headers and CRC checked (bodies are the writer's).

use mib_wire::header::{HeaderError, TcPacket, TmPacket};

use crate::stream::{Split, Splitter};

/// One item of a raw packet stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawItem<'a> {
    Tm {
        offset: usize,
        packet: TmPacket<'a>,
    },
    Tc {
        offset: usize,
        packet: TcPacket<'a>,
    },
    /// Bytes skipped until the next packet with valid headers and CRC.
    Corrupt {
        offset: usize,
        len: usize,
        reason: HeaderError,
    },
}

fn raw_packet(b: &[u8], offset: usize) -> Result<(RawItem<'_>, usize), HeaderError> {
    let p = mib_wire::header::check_primary(b)?;
    if p.is_tc {
        TcPacket::parse(b).map(|packet| (RawItem::Tc { offset, packet }, p.len))
    } else {
        TmPacket::parse(b).map(|packet| (RawItem::Tm { offset, packet }, p.len))
    }
}

/// Splits concatenated space packets (headers and CRC checked); after bytes that are
/// not a packet it scans byte by byte to the next valid packet and reports the stretch.
pub struct RawStream<'a> {
    split: Splitter<'a, RawItem<'a>>,
}

impl<'a> RawStream<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        RawStream {
            split: Splitter::new(buf),
        }
    }
}

impl<'a> Iterator for RawStream<'a> {
    type Item = RawItem<'a>;
    fn next(&mut self) -> Option<RawItem<'a>> {
        Some(match self.split.next_with(raw_packet)? {
            Split::Item(i) => i,
            Split::Skipped { offset, len, reason } => RawItem::Corrupt { offset, len, reason },
        })
    }
}
