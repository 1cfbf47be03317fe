//! Ground link of the host OBSW: TCs arrive on UDP datagrams and on TCP streams framed
//! with the one stream framing, `mmic_link::stream` (`0x00, COBS(packet), 0x00`; a
//! receiver also takes frames with only the trailing 0x00), and TM goes out framed the
//! same way.
//!
//! TM goes to every connected TCP client and to every UDP *subscriber*: a UDP ground
//! subscribes by sending a TC that passes acceptance, and each accepted TC renews its
//! lease (`SUBSCRIPTION_LEASE_MS`). At most `MAX_SUBSCRIBERS` grounds subscribe at once (a
//! new one replaces the one whose lease is oldest). A rejected or malformed datagram
//! never changes who gets TM; its failure report goes to the current subscribers.
//!
//! Everything runs in the main thread, in one `mio` poll: the UDP TC socket, the
//! simulator-control socket, the TCP listener and every TCP connection. TCP is bounded:
//! at most `TCP_MAX_CONNECTIONS` (a further connection is closed at once and counted), at
//! most `TCP_INPUT_QUEUE` decoded TCs waiting per connection (when full, the connection is
//! not read until the queue drains, so the kernel's window holds the sender back), and at
//! most `TCP_TM_BACKLOG` bytes of TM waiting per client (a client that falls further
//! behind is disconnected and counted). Nothing grows with the traffic.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use mib::config::MAX_PACKET_LEN;
use mib::host_config::{
    MAX_SUBSCRIBERS, SIM_CTL_MAX_LINE, SUBSCRIPTION_LEASE_MS, TCP_INPUT_QUEUE, TCP_MAX_CONNECTIONS, TCP_TM_BACKLOG,
};
use mio::net::{TcpListener, TcpStream};
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};
use mmic_link::downlink::TmVc;
use mmic_link::stream::{encode, encoded_len, Deframer, StreamError};
use timerfd::{ClockId, SetTimeFlags, TimerFd, TimerState};

/// Something for the main loop.
#[derive(Debug)]
pub enum Input {
    /// A TC (raw space packet) and where it came from.
    Tc(Vec<u8>, Origin),
    /// A line on the simulator control channel and where to answer.
    SimCtl(String, SocketAddr),
    /// A simulator-control datagram longer than `SIM_CTL_MAX_LINE` (or not text).
    BadSimCtl(usize, SocketAddr),
    /// A malformed frame on a TCP stream (counted, then reported).
    BadFrame,
    /// A TCP frame longer than any packet (counted, then reported with TM[1,2]
    /// FRAME_TOO_LONG): its length and its first decoded bytes (the request ID if the
    /// COBS prefix gives it).
    OversizeFrame(usize, Vec<u8>),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    Udp(SocketAddr),
    Tcp,
}

const UDP: Token = Token(0);
const SIM_CTL: Token = Token(1);
const TIMER: Token = Token(3);
const LISTENER: Token = Token(4);
/// The space-link frame socket (read by the main loop through `TmDestinations::frames`).
const FRAMES: Token = Token(5);
/// Connection `i` has token `CONN0 + i`.
const CONN0: usize = 16;

/// Decoded bytes of an oversize frame kept to answer it (its request ID is in the first 6).
const OVERSIZE_HEAD: usize = 10;

/// Link counters (reported in HK through `IoCounters` and on stderr).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GroundLinkCounters {
    /// Live TM packets that could not be sent (UDP send errors, dropped TCP clients).
    pub tm_dropped: u32,
    /// TCP connections refused because `TCP_MAX_CONNECTIONS` were open.
    pub tcp_refused: u32,
    /// TCP clients disconnected because their TM backlog passed `TCP_TM_BACKLOG`.
    pub tcp_slow_dropped: u32,
    /// UDP subscribers replaced by a new one because `MAX_SUBSCRIBERS` were subscribed.
    pub subscribers_replaced: u32,
}

/// One TCP client.
struct Conn {
    stream: TcpStream,
    /// The one COBS deframer (`mmic_link::stream`), at most one packet decoded; counts
    /// what it drops (each drop is also an [`Input`], counted by the main loop).
    de: Box<Deframer<MAX_PACKET_LEN>>,
    /// Decoded inputs waiting for the main loop (bounded by `TCP_INPUT_QUEUE`).
    queue: VecDeque<Input>,
    /// TM frames not yet written (bounded by `TCP_TM_BACKLOG` bytes).
    backlog: VecDeque<u8>,
    /// The socket may have bytes to read (mio is edge-triggered).
    readable: bool,
    /// The peer closed its side or the socket failed: close once the queue is served.
    closed: bool,
}

/// A UDP ground receiving TM.
#[derive(Clone, Copy, Debug)]
struct Subscriber {
    addr: SocketAddr,
    until: Instant,
}

/// Where TM goes; also holds the TCP connections (their input and output sides).
pub struct TmDestinations {
    udp: UdpSocket,
    /// Fixed TM destinations (`--tm-dest`): always sent to, no lease.
    fixed: Vec<SocketAddr>,
    subscribers: Vec<Subscriber>,
    conns: Vec<Option<Conn>>,
    frame: Vec<u8>,
    pub counters: GroundLinkCounters,
    lease: Duration,
    /// `--tm-log`: every TM packet handed to the downlink, one hex line each.
    tm_log: Option<std::fs::File>,
    /// The sender of a refused datagram while its refusal is reported: it gets that
    /// report too (so a ground talking to the wrong robot learns why), without
    /// subscribing.
    reply_to: Option<SocketAddr>,
    /// The space-link frame endpoint (`--frame-udp`): every TM packet also goes out in TM
    /// frames to its fixed ground address.
    pub frames: Option<crate::frames::FrameEndpoint>,
    /// The bare-packet link (UDP subscribers, TCP clients) gets TM. Off when the obsw runs
    /// the frame link without `--lab-bare-packets`.
    pub bare: bool,
}

impl TmDestinations {
    /// Adds a fixed TM destination (`--tm-dest`), at most `MAX_SUBSCRIBERS` of them.
    pub fn add_fixed(&mut self, dest: SocketAddr) -> anyhow::Result<()> {
        if self.fixed.contains(&dest) {
            return Ok(());
        }
        if self.fixed.len() >= MAX_SUBSCRIBERS {
            anyhow::bail!("--tm-dest {dest}: at most {MAX_SUBSCRIBERS} fixed TM destinations");
        }
        self.fixed.push(dest);
        Ok(())
    }

    /// Subscribes `peer` (or renews its lease): called for every accepted UDP TC.
    pub fn subscribe(&mut self, peer: SocketAddr, now: Instant) {
        let until = now + self.lease;
        self.subscribers.retain(|s| s.until > now);
        if let Some(s) = self.subscribers.iter_mut().find(|s| s.addr == peer) {
            s.until = until;
            return;
        }
        if self.subscribers.len() >= MAX_SUBSCRIBERS {
            if let Some(i) = (0..self.subscribers.len()).min_by_key(|&i| self.subscribers[i].until) {
                let old = self.subscribers.remove(i);
                self.counters.subscribers_replaced = self.counters.subscribers_replaced.wrapping_add(1);
                log::warn!(
                    "downlink: {} replaces {} (at most {MAX_SUBSCRIBERS} UDP subscribers)",
                    peer,
                    old.addr
                );
            }
        }
        self.subscribers.push(Subscriber { addr: peer, until });
    }

    /// Writes every TM packet from now on to `file` (one line of hex per packet), so a
    /// test can judge from what the obsw really sent.
    pub fn log_tm_to(&mut self, file: std::fs::File) {
        self.tm_log = Some(file);
    }

    /// While `peer`'s refused datagram is reported, its reports go to `peer` as well.
    pub fn reply_to(&mut self, peer: Option<SocketAddr>) {
        self.reply_to = peer;
    }

    /// Current UDP subscribers (lease not over at `now`).
    #[cfg(test)]
    pub fn subscribers(&self, now: Instant) -> Vec<SocketAddr> {
        self.subscribers
            .iter()
            .filter(|s| s.until > now)
            .map(|s| s.addr)
            .collect()
    }

    fn conn_count(&self) -> usize {
        self.conns.iter().flatten().count()
    }

    /// Closes connection `i` (deregistering it).
    fn close(&mut self, i: usize, poll: &Poll) {
        if let Some(mut c) = self.conns[i].take() {
            let _ = poll.registry().deregister(&mut c.stream);
            let _ = c.stream.shutdown(std::net::Shutdown::Both);
        }
    }

    /// Writes as much of connection `i`'s backlog as the socket takes.
    fn flush(&mut self, i: usize) {
        let Some(c) = self.conns[i].as_mut() else { return };
        while !c.backlog.is_empty() {
            let (a, _) = c.backlog.as_slices();
            match c.stream.write(a) {
                Ok(0) => {
                    c.closed = true;
                    return;
                }
                Ok(n) => {
                    c.backlog.drain(..n);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) if e.kind() == ErrorKind::WouldBlock => return,
                Err(_) => {
                    c.closed = true;
                    c.backlog.clear();
                    return;
                }
            }
        }
    }
}

impl obsw_core::tm::TmSink for TmDestinations {
    fn send_tm(&mut self, packet: &[u8]) {
        self.send_on(packet, TmVc::Realtime);
    }

    fn send_replay(&mut self, packet: &[u8]) {
        self.send_on(packet, TmVc::Replay);
    }

    fn send_file(&mut self, packet: &[u8]) {
        self.send_on(packet, TmVc::Files);
    }
}

impl TmDestinations {
    /// One TM packet to every destination: over the space link on virtual channel `vc`.
    fn send_on(&mut self, packet: &[u8], vc: TmVc) {
        if let Some(f) = self.tm_log.as_mut() {
            let mut line = String::with_capacity(2 * packet.len() + 1);
            for b in packet {
                line.push_str(&format!("{b:02x}"));
            }
            line.push('\n');
            // A test tool: a failed write ends the log rather than the obsw.
            if f.write_all(line.as_bytes()).is_err() {
                self.tm_log = None;
            }
        }
        if let Some(f) = self.frames.as_mut() {
            f.send_packet(packet, vc);
        }
        if !self.bare {
            return;
        }
        let now = Instant::now();
        self.subscribers.retain(|s| s.until > now);
        if let Some(p) = self
            .reply_to
            .filter(|p| !self.subscribers.iter().any(|s| s.addr == *p) && !self.fixed.contains(p))
        {
            if !send_udp(&self.udp, packet, p) {
                self.counters.tm_dropped = self.counters.tm_dropped.wrapping_add(1);
            }
        }
        for d in &self.fixed {
            if !send_udp(&self.udp, packet, *d) {
                self.counters.tm_dropped = self.counters.tm_dropped.wrapping_add(1);
            }
        }
        // A subscriber that is also a fixed destination gets each packet once.
        for s in self.subscribers.iter().filter(|s| !self.fixed.contains(&s.addr)) {
            // A full socket buffer or an unreachable peer must not stop the OBSW; the
            // on-board store keeps the packet for a later downlink.
            if !send_udp(&self.udp, packet, s.addr) {
                self.counters.tm_dropped = self.counters.tm_dropped.wrapping_add(1);
            }
        }
        if self.conn_count() == 0 {
            return;
        }
        // The one stream framing: `0x00, COBS(packet), 0x00`.
        self.frame.resize(encoded_len(packet.len()), 0);
        let Ok(n) = encode(packet, &mut self.frame) else {
            // Unreachable (the buffer has just been sized for the packet); counted anyway.
            self.counters.tm_dropped = self.counters.tm_dropped.wrapping_add(1);
            return;
        };
        for i in 0..self.conns.len() {
            let Some(c) = self.conns[i].as_mut() else { continue };
            if c.closed {
                continue;
            }
            if c.backlog.len() + n > TCP_TM_BACKLOG {
                // Disconnected at the next poll round (the main loop owns the poll).
                c.closed = true;
                c.backlog.clear();
                self.counters.tcp_slow_dropped = self.counters.tcp_slow_dropped.wrapping_add(1);
                self.counters.tm_dropped = self.counters.tm_dropped.wrapping_add(1);
                log::warn!("TCP client {i}: TM backlog over {TCP_TM_BACKLOG} bytes, disconnecting it");
                continue;
            }
            c.backlog.extend(&self.frame[..n]);
            self.flush(i);
        }
    }
}

/// Sends one datagram on the non-blocking socket. A full send buffer (the ground reads
/// slower than the OBSW writes) is waited out for up to `TM_WRITE_TIMEOUT_MS`, so a
/// burst is paced rather than lost; an unreachable peer fails at once.
pub(crate) fn send_udp(sock: &UdpSocket, packet: &[u8], peer: SocketAddr) -> bool {
    let deadline = Instant::now() + Duration::from_millis(mib::host_config::TM_WRITE_TIMEOUT_MS as u64);
    loop {
        match sock.send_to(packet, peer) {
            Ok(_) => return true,
            Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                std::thread::sleep(Duration::from_micros(50));
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(_) => return false,
        }
    }
}

/// Every input source of the main loop.
pub struct Inputs {
    poll: Poll,
    events: Events,
    udp: UdpSocket,
    sim_ctl: UdpSocket,
    listener: TcpListener,
    /// The listener may have connections waiting.
    accept_ready: bool,
    buf: Vec<u8>,
    /// Round-robin position over the UDP socket (0) and the connections (1..).
    next_source: usize,
    /// epoll's timeout has millisecond resolution; a timerfd wakes the poll at the
    /// control period's deadline to the microsecond.
    timer: TimerFd,
    /// The deadline the timer is armed for and has not yet been seen to expire: a wait
    /// for the same deadline does not re-arm it (one `timerfd_settime` per control period,
    /// not per wake-up).
    timer_armed: Option<Instant>,
    /// The UDP TC socket and the simulator-control socket may have datagrams waiting: set
    /// by the poll's (edge-triggered) readiness, cleared when a read would block. An idle
    /// socket costs no system call per wake-up.
    udp_ready: bool,
    sim_ctl_ready: bool,
}

/// Addresses actually bound (ports may have been 0).
pub struct Bound {
    pub udp: SocketAddr,
    pub tcp: SocketAddr,
    pub sim_ctl: SocketAddr,
}

/// Binds the UDP and TCP TC ports and the simulator control port.
pub fn start(
    udp_addr: SocketAddr,
    tcp_addr: SocketAddr,
    sim_ctl_addr: SocketAddr,
) -> anyhow::Result<(Inputs, TmDestinations, Bound)> {
    start_with_lease(
        udp_addr,
        tcp_addr,
        sim_ctl_addr,
        Duration::from_millis(SUBSCRIPTION_LEASE_MS as u64),
    )
}

fn start_with_lease(
    udp_addr: SocketAddr,
    tcp_addr: SocketAddr,
    sim_ctl_addr: SocketAddr,
    lease: Duration,
) -> anyhow::Result<(Inputs, TmDestinations, Bound)> {
    let udp = UdpSocket::bind(udp_addr).map_err(|e| anyhow::anyhow!("cannot bind UDP {udp_addr}: {e}"))?;
    let mut listener = TcpListener::bind(tcp_addr).map_err(|e| anyhow::anyhow!("cannot bind TCP {tcp_addr}: {e}"))?;
    let sim_ctl = UdpSocket::bind(sim_ctl_addr)
        .map_err(|e| anyhow::anyhow!("cannot bind simulator control UDP {sim_ctl_addr}: {e}"))?;
    let bound = Bound {
        udp: udp.local_addr()?,
        tcp: listener.local_addr()?,
        sim_ctl: sim_ctl.local_addr()?,
    };
    udp.set_nonblocking(true)?;
    sim_ctl.set_nonblocking(true)?;
    let poll = Poll::new()?;
    poll.registry()
        .register(&mut SourceFd(&udp.as_raw_fd()), UDP, Interest::READABLE)?;
    poll.registry()
        .register(&mut SourceFd(&sim_ctl.as_raw_fd()), SIM_CTL, Interest::READABLE)?;
    poll.registry().register(&mut listener, LISTENER, Interest::READABLE)?;
    let timer = TimerFd::new_custom(ClockId::Monotonic, true, true)?;
    poll.registry()
        .register(&mut SourceFd(&timer.as_raw_fd()), TIMER, Interest::READABLE)?;
    let down = TmDestinations {
        udp: udp.try_clone()?,
        fixed: Vec::with_capacity(MAX_SUBSCRIBERS),
        subscribers: Vec::with_capacity(MAX_SUBSCRIBERS),
        conns: (0..TCP_MAX_CONNECTIONS).map(|_| None).collect(),
        frame: Vec::new(),
        counters: GroundLinkCounters::default(),
        lease,
        tm_log: None,
        reply_to: None,
        frames: None,
        bare: true,
    };
    let inputs = Inputs {
        poll,
        events: Events::with_capacity(64),
        udp,
        sim_ctl,
        listener,
        accept_ready: true,
        buf: vec![0u8; 65_536],
        next_source: 0,
        timer,
        timer_armed: None,
        udp_ready: true,
        sim_ctl_ready: true,
    };
    Ok((inputs, down, bound))
}

impl Inputs {
    /// The next input that is already waiting, if any (never blocks). Sources take turns,
    /// so that no client can hold back the others.
    pub fn next(&mut self, down: &mut TmDestinations) -> Option<Input> {
        self.service(down);
        let sources = 1 + down.conns.len();
        for k in 0..sources {
            let src = (self.next_source + k) % sources;
            let got = if src == 0 {
                self.next_udp()
            } else {
                self.next_tcp(down, src - 1)
            };
            if got.is_some() {
                self.next_source = (src + 1) % sources;
                return got;
            }
        }
        self.next_sim_ctl()
    }

    fn next_udp(&mut self) -> Option<Input> {
        while self.udp_ready {
            match self.udp.recv_from(&mut self.buf) {
                Ok((n, from)) => return Some(Input::Tc(self.buf[..n].to_vec(), Origin::Udp(from))),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // WouldBlock: nothing waiting until the poll says so. Other errors (an ICMP
                // port-unreachable from an old peer on some systems) are not fatal either.
                Err(e) if e.kind() == ErrorKind::WouldBlock => self.udp_ready = false,
                Err(_) => continue,
            }
        }
        None
    }

    fn next_tcp(&mut self, down: &mut TmDestinations, i: usize) -> Option<Input> {
        let c = down.conns[i].as_mut()?;
        let input = c.queue.pop_front();
        if c.queue.len() < TCP_INPUT_QUEUE && c.readable {
            read_conn(c, &mut self.buf);
        }
        input
    }

    fn next_sim_ctl(&mut self) -> Option<Input> {
        if !self.sim_ctl_ready {
            return None;
        }
        let mut line = [0u8; SIM_CTL_MAX_LINE + 1];
        let (n, from) = match self.sim_ctl.recv_from(&mut line) {
            Ok(r) => r,
            Err(e) => {
                // Would block: nothing until the poll says so. Other errors (an ICMP error
                // of an earlier reply): tried again at the next call.
                if e.kind() == ErrorKind::WouldBlock {
                    self.sim_ctl_ready = false;
                }
                return None;
            }
        };
        match std::str::from_utf8(&line[..n]) {
            Ok(text) if n <= SIM_CTL_MAX_LINE => Some(Input::SimCtl(text.trim().to_string(), from)),
            _ => Some(Input::BadSimCtl(n, from)),
        }
    }

    /// Accepts waiting connections and closes finished ones.
    fn service(&mut self, down: &mut TmDestinations) {
        while self.accept_ready {
            match self.listener.accept() {
                Ok((mut stream, peer)) => {
                    let Some(i) = down.conns.iter().position(Option::is_none) else {
                        down.counters.tcp_refused = down.counters.tcp_refused.wrapping_add(1);
                        log::warn!(
                            "TCP connection from {peer} refused: {TCP_MAX_CONNECTIONS} connections open ({} refused so far)",
                            down.counters.tcp_refused
                        );
                        let _ = stream.shutdown(std::net::Shutdown::Both);
                        continue;
                    };
                    let _ = stream.set_nodelay(true);
                    if self
                        .poll
                        .registry()
                        .register(&mut stream, Token(CONN0 + i), Interest::READABLE | Interest::WRITABLE)
                        .is_err()
                    {
                        continue;
                    }
                    down.conns[i] = Some(Conn {
                        stream,
                        de: Box::new(Deframer::new()),
                        queue: VecDeque::with_capacity(TCP_INPUT_QUEUE),
                        backlog: VecDeque::new(),
                        readable: true,
                        closed: false,
                    });
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => self.accept_ready = false,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // Out of descriptors and the like: try again at the next readiness.
                Err(_) => self.accept_ready = false,
            }
        }
        for i in 0..down.conns.len() {
            let Some(c) = down.conns[i].as_mut() else { continue };
            if c.readable && c.queue.len() < TCP_INPUT_QUEUE {
                read_conn(c, &mut self.buf);
            }
            if c.closed && c.queue.is_empty() {
                down.close(i, &self.poll);
            }
        }
    }

    /// Waits until an input may be waiting or `timeout` passes.
    #[cfg(test)]
    pub fn wait(&mut self, timeout: Duration, down: &mut TmDestinations) {
        self.wait_until(Instant::now() + timeout, down);
    }

    /// Waits until an input may be waiting or `due` comes. The timer is armed only when
    /// `due` differs from the deadline it already runs for, and read only when it expired.
    pub fn wait_until(&mut self, due: Instant, down: &mut TmDestinations) {
        let timeout = due.saturating_duration_since(Instant::now());
        if timeout.is_zero() {
            return;
        }
        if self.timer_armed != Some(due) {
            self.timer
                .set_state(TimerState::Oneshot(timeout), SetTimeFlags::Default);
            self.timer_armed = Some(due);
        }
        // The timer ends the wait; the poll timeout is only a backstop. Interrupted or
        // failed waits just return: the caller drains and waits again.
        let _ = self
            .poll
            .poll(&mut self.events, Some(timeout + Duration::from_millis(2)));
        for ev in self.events.iter() {
            match ev.token() {
                TIMER => {
                    self.timer.read();
                    self.timer_armed = None;
                }
                UDP => self.udp_ready = true,
                SIM_CTL => self.sim_ctl_ready = true,
                FRAMES => {
                    if let Some(f) = down.frames.as_mut() {
                        f.set_readable();
                    }
                }
                LISTENER => self.accept_ready = true,
                Token(t) if t >= CONN0 && t - CONN0 < down.conns.len() => {
                    let i = t - CONN0;
                    if let Some(c) = down.conns[i].as_mut() {
                        if ev.is_readable() || ev.is_read_closed() || ev.is_error() {
                            c.readable = true;
                        }
                    }
                    if ev.is_writable() {
                        down.flush(i);
                    }
                }
                Token(_) => {}
            }
        }
    }

    /// Wakes the poll when the frame endpoint's socket or serial line has input.
    pub fn register_frames(&mut self, fd: std::os::fd::RawFd) -> std::io::Result<()> {
        self.poll
            .registry()
            .register(&mut SourceFd(&fd), FRAMES, Interest::READABLE)
    }

    /// Answers a simulator-control line.
    pub fn reply_sim_ctl(&self, to: SocketAddr, text: &str) {
        let _ = self.sim_ctl.send_to(text.as_bytes(), to);
    }
}

/// Reads connection bytes into frames until the input queue is full or the socket has
/// nothing more. Bytes after the frame that filled the queue stay in the kernel buffer.
fn read_conn(c: &mut Conn, buf: &mut [u8]) {
    // Every input takes at least two bytes (one byte and the 0x00), so reading at most
    // twice the free room never produces more inputs than fit.
    while c.readable && !c.closed && c.queue.len() < TCP_INPUT_QUEUE {
        let want = buf.len().min(2 * (TCP_INPUT_QUEUE - c.queue.len()));
        match c.stream.read(&mut buf[..want]) {
            Ok(0) => {
                c.closed = true;
                c.readable = false;
            }
            Ok(n) => {
                for &b in &buf[..n] {
                    frame_byte(c, b);
                }
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) if e.kind() == ErrorKind::WouldBlock => c.readable = false,
            Err(_) => {
                c.closed = true;
                c.readable = false;
            }
        }
    }
}

/// Feeds one byte of a COBS stream to the connection's deframer; a frame completed or
/// dropped becomes an [`Input`].
fn frame_byte(c: &mut Conn, b: u8) {
    let garbage = c.de.counters.garbage_bytes;
    let input = match c.de.push(b) {
        None => return,
        Some(Ok(frame)) => Input::Tc(frame.to_vec(), Origin::Tcp),
        Some(Err(StreamError::Oversize)) => {
            // Its encoded length (the deframer counted it as garbage) and decoded head.
            let len = c.de.counters.garbage_bytes.saturating_sub(garbage) as usize;
            let head = c.de.oversize_head();
            Input::OversizeFrame(len, head[..head.len().min(OVERSIZE_HEAD)].to_vec())
        }
        Some(Err(StreamError::Corrupt | StreamError::BufferTooSmall)) => Input::BadFrame,
    };
    c.queue.push_back(input);
}

#[cfg(test)]
mod tests {
    use super::*;
    use obsw_core::tm::TmSink;

    fn local() -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], 0))
    }

    fn net(lease: Duration) -> (Inputs, TmDestinations, Bound) {
        start_with_lease(local(), local(), local(), lease).unwrap()
    }

    fn drain(inputs: &mut Inputs, down: &mut TmDestinations, until: Instant) -> Vec<Input> {
        let mut got = Vec::new();
        while Instant::now() < until {
            match inputs.next(down) {
                Some(i) => got.push(i),
                None => inputs.wait(Duration::from_millis(5), down),
            }
        }
        got
    }

    // verifies: DD-LINK-02
    #[test]
    fn subscribers_are_bounded_and_leases_expire() {
        let (_i, mut down, _b) = net(Duration::from_millis(200));
        let t0 = Instant::now();
        let addr = |p: u16| SocketAddr::from(([127, 0, 0, 1], p));
        for p in 0..MAX_SUBSCRIBERS as u16 + 2 {
            down.subscribe(addr(1000 + p), t0 + Duration::from_millis(p as u64));
        }
        let subs = down.subscribers(t0);
        assert_eq!(subs.len(), MAX_SUBSCRIBERS);
        assert!(
            !subs.contains(&addr(1000)) && !subs.contains(&addr(1001)),
            "oldest replaced"
        );
        assert_eq!(down.counters.subscribers_replaced, 2);
        // Renewing keeps one alive past the others' lease.
        down.subscribe(addr(1005), t0 + Duration::from_millis(150));
        assert_eq!(down.subscribers(t0 + Duration::from_millis(250)), vec![addr(1005)]);
        assert!(down.subscribers(t0 + Duration::from_millis(400)).is_empty());
    }

    // verifies: DD-LINK-02, DD-LINK-01
    #[test]
    fn every_subscriber_gets_tm() {
        let (_i, mut down, _b) = net(Duration::from_secs(10));
        let a = UdpSocket::bind(local()).unwrap();
        let b = UdpSocket::bind(local()).unwrap();
        for s in [&a, &b] {
            s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
            down.subscribe(s.local_addr().unwrap(), Instant::now());
        }
        down.send_tm(&[1, 2, 3]);
        let mut buf = [0u8; 16];
        for s in [&a, &b] {
            assert_eq!(s.recv(&mut buf).unwrap(), 3);
        }
    }

    // verifies: YAMCS-TM-01
    #[test]
    fn fixed_destinations_get_tm_without_a_lease_and_once() {
        let (_i, mut down, _b) = net(Duration::from_millis(50));
        let a = UdpSocket::bind(local()).unwrap();
        a.set_read_timeout(Some(Duration::from_millis(300))).unwrap();
        let addr = a.local_addr().unwrap();
        down.add_fixed(addr).unwrap();
        down.add_fixed(addr).unwrap();
        // Also a subscriber whose lease then ends: still exactly one copy per packet.
        down.subscribe(addr, Instant::now());
        let mut buf = [0u8; 16];
        down.send_tm(&[1]);
        assert_eq!(a.recv(&mut buf).unwrap(), 1);
        assert!(a.recv(&mut buf).is_err(), "one copy only");
        std::thread::sleep(Duration::from_millis(100));
        assert!(down.subscribers(Instant::now()).is_empty());
        down.send_tm(&[2, 2]);
        assert_eq!(a.recv(&mut buf).unwrap(), 2, "sent after the lease ended");
        for p in 0..MAX_SUBSCRIBERS as u16 {
            let _ = down.add_fixed(SocketAddr::from(([127, 0, 0, 1], 2000 + p)));
        }
        assert!(down.add_fixed(SocketAddr::from(([127, 0, 0, 1], 3000))).is_err());
    }

    // verifies: DD-LINK-02
    #[test]
    fn tcp_connections_are_capped_and_frames_bounded() {
        let (mut inputs, mut down, bound) = net(Duration::from_secs(10));
        let mut clients: Vec<std::net::TcpStream> = (0..TCP_MAX_CONNECTIONS + 3)
            .map(|_| std::net::TcpStream::connect(bound.tcp).unwrap())
            .collect();
        drain(&mut inputs, &mut down, Instant::now() + Duration::from_millis(200));
        assert_eq!(down.conn_count(), TCP_MAX_CONNECTIONS);
        assert_eq!(down.counters.tcp_refused, 3);
        // An oversize frame, a malformed one and a good one, in that order.
        let c = &mut clients[0];
        let mut big = vec![0u8; encoded_len(3 * MAX_PACKET_LEN)];
        let big_len = encode(&vec![0x55u8; 3 * MAX_PACKET_LEN], &mut big).unwrap();
        big.truncate(big_len);
        // OversizeFrame carries the COBS bytes of the frame, its two delimiters excluded.
        c.write_all(&big).unwrap();
        c.write_all(&[0x05, 1, 0]).unwrap();
        let mut f = [0u8; 8];
        let n = encode(&[9, 8, 7], &mut f).unwrap();
        c.write_all(&f[..n]).unwrap();
        let got = drain(&mut inputs, &mut down, Instant::now() + Duration::from_millis(300));
        assert!(
            matches!(&got[0], Input::OversizeFrame(n, h) if *n == big_len - 2 && h == &[0x55; OVERSIZE_HEAD]),
            "{got:?}"
        );
        assert!(matches!(got[1], Input::BadFrame), "{got:?}");
        assert!(
            matches!(&got[2], Input::Tc(b, Origin::Tcp) if b == &[9, 8, 7]),
            "{got:?}"
        );
    }

    // verifies: DD-LINK-02, DD-ROBUST-01
    #[test]
    fn a_flood_is_read_only_as_fast_as_it_is_served() {
        let (mut inputs, mut down, bound) = net(Duration::from_secs(10));
        let mut c = std::net::TcpStream::connect(bound.tcp).unwrap();
        c.set_nonblocking(true).unwrap();
        // Write frames until the kernel's buffers are full: the obsw does not take them.
        let frame = [0x02, 0x11, 0x00];
        drain(&mut inputs, &mut down, Instant::now() + Duration::from_millis(100));
        let mut written = 0usize;
        let until = Instant::now() + Duration::from_secs(5);
        while Instant::now() < until {
            inputs.wait(Duration::from_millis(1), &mut down);
            inputs.service(&mut down);
            let chunk = frame.repeat(20_000);
            match c.write(&chunk) {
                // Whole frames only, so the count below is exact.
                Ok(n) if n % frame.len() == 0 => written += n,
                Ok(n) => {
                    let rest = frame.len() - n % frame.len();
                    c.set_nonblocking(false).unwrap();
                    c.write_all(&chunk[n..n + rest]).unwrap();
                    c.set_nonblocking(true).unwrap();
                    written += n + rest;
                }
                Err(_) => break,
            }
        }
        let queued: usize = down.conns.iter().flatten().map(|c| c.queue.len()).sum();
        assert!(queued <= TCP_INPUT_QUEUE, "queue bounded: {queued}");
        assert!(
            written > 1000,
            "the sender was held back only after the kernel buffers: {written}"
        );
        // Everything written is eventually served, in order.
        let mut served = 0usize;
        let until = Instant::now() + Duration::from_secs(20);
        while served * frame.len() < written && Instant::now() < until {
            match inputs.next(&mut down) {
                Some(Input::Tc(b, _)) => {
                    assert_eq!(b, [0x11]);
                    served += 1;
                }
                Some(other) => panic!("{other:?}"),
                None => inputs.wait(Duration::from_millis(2), &mut down),
            }
        }
        assert_eq!(served * frame.len(), written);
    }

    // verifies: DD-LINK-02
    #[test]
    fn a_client_that_stops_reading_is_disconnected() {
        let (mut inputs, mut down, bound) = net(Duration::from_secs(10));
        let c = std::net::TcpStream::connect(bound.tcp).unwrap();
        drain(&mut inputs, &mut down, Instant::now() + Duration::from_millis(100));
        assert_eq!(down.conn_count(), 1);
        let packet = vec![0xAB; 1000];
        // The kernel's buffers take some megabytes first; then the backlog fills.
        let mut sent = 0;
        while down.counters.tcp_slow_dropped == 0 && sent < 100_000 {
            down.send_tm(&packet);
            sent += 1;
        }
        assert_eq!(down.counters.tcp_slow_dropped, 1);
        drain(&mut inputs, &mut down, Instant::now() + Duration::from_millis(50));
        assert_eq!(down.conn_count(), 0);
        drop(c);
    }
}
