//! Inter-robot team packets on the target (docs/team.md): the transport board A's leader
//! selection talks through.
//!
//! The radio itself is future work; the firmware's team code only sees
//! [`TeamTransport`]: one packet per datagram, to one robot of the roster or to every
//! other one (`mmic_team::Dest`, as the host's UDP link), received one packet at a time.
//! The QEMU tests implement it with a mock air interface (`qemu-tests/src/mock.rs`),
//! the host with UDP sockets (`obsw --team-udp`). A packet is opaque here: what it
//! carries (the team message, its authentication) is the team layer's business.
//!
//! Nothing is dropped silently: a packet a transport cannot take or deliver is refused
//! with a [`TransportError`] and counted by [`TeamIo`].

use mmic_team::Dest;

/// Why a transport refused or lost a packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportError {
    /// The packet is longer than the transport's datagram (or the receive buffer).
    TooLong { len: usize, max: usize },
    /// No room in the transmit queue (sending) or a receive queue overflowed.
    Full,
    /// The destination robot is not reachable through this transport.
    NoRoute { robot: u8 },
    /// The radio (driver) failed.
    Radio,
}

impl core::fmt::Display for TransportError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TransportError::TooLong { len, max } => write!(f, "team packet of {len} bytes, at most {max}"),
            TransportError::Full => f.write_str("team transport queue full"),
            TransportError::NoRoute { robot } => write!(f, "no route to robot {robot}"),
            TransportError::Radio => f.write_str("team radio error"),
        }
    }
}

impl core::error::Error for TransportError {}

/// The inter-robot link as the firmware sees it.
pub trait TeamTransport {
    /// Largest packet one datagram carries.
    const MAX_PACKET: usize;
    /// Queues one packet for `to` (one robot, or every other robot of the roster).
    fn send(&mut self, to: Dest, packet: &[u8]) -> Result<(), TransportError>;
    /// Copies the next received packet into `buf` and returns its length; `Ok(None)`
    /// when none is waiting. A packet longer than `buf` is consumed and refused
    /// ([`TransportError::TooLong`]).
    fn receive(&mut self, buf: &mut [u8]) -> Result<Option<usize>, TransportError>;
}

/// Counters of one robot's team traffic (nothing dropped without a count).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TeamCounters {
    pub sent: u32,
    pub received: u32,
    pub send_errors: u32,
    pub receive_errors: u32,
}

/// A transport with counters: what the firmware's team code calls.
pub struct TeamIo<T> {
    pub transport: T,
    pub counters: TeamCounters,
}

impl<T: TeamTransport> TeamIo<T> {
    pub const fn new(transport: T) -> Self {
        Self {
            transport,
            counters: TeamCounters {
                sent: 0,
                received: 0,
                send_errors: 0,
                receive_errors: 0,
            },
        }
    }

    /// Sends one packet; a refusal is counted and returned.
    pub fn send(&mut self, to: Dest, packet: &[u8]) -> Result<(), TransportError> {
        let r = self.transport.send(to, packet);
        match r {
            Ok(()) => self.counters.sent = self.counters.sent.wrapping_add(1),
            Err(_) => self.counters.send_errors = self.counters.send_errors.wrapping_add(1),
        }
        r
    }

    /// Hands every waiting packet to `deliver`, in arrival order; receive errors are
    /// counted and skipped. Returns the number delivered. At most `limit` packets are
    /// taken per call, so a flooding peer cannot hold the control period.
    pub fn poll(&mut self, buf: &mut [u8], limit: usize, mut deliver: impl FnMut(&[u8])) -> usize {
        let mut n = 0;
        for _ in 0..limit {
            match self.transport.receive(buf) {
                Ok(Some(len)) => {
                    self.counters.received = self.counters.received.wrapping_add(1);
                    deliver(&buf[..len.min(buf.len())]);
                    n += 1;
                }
                Ok(None) => break,
                Err(_) => self.counters.receive_errors = self.counters.receive_errors.wrapping_add(1),
            }
        }
        n
    }
}
