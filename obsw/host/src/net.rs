//! Ground link of the host OBSW: TCs arrive on UDP datagrams and on TCP streams framed
//! with COBS (a 0x00 after each frame); TM goes to every TCP client and to the last UDP
//! sender.
//!
//! The main thread waits in one `mio` poll on the UDP TC socket, the simulator-control
//! socket and a waker; a UDP TC wakes it directly, so it is handled the moment it
//! arrives, with no thread hop. TCP streams have reader threads that hand decoded
//! frames over a channel and ring the waker.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::os::fd::AsRawFd;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use mib::config::MAX_PACKET_LEN;
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token, Waker};
use timerfd::{ClockId, SetTimeFlags, TimerFd, TimerState};

/// Something for the main loop.
pub enum Input {
    /// A TC (raw space packet) and where it came from.
    Tc(Vec<u8>, Origin),
    /// A line on the simulator control channel and where to answer.
    SimCtl(String, SocketAddr),
    /// A malformed frame on a TCP stream (counted, then dropped).
    BadFrame,
}

#[derive(Clone, Copy, Debug)]
pub enum Origin {
    Udp(SocketAddr),
    Tcp,
}

const UDP: Token = Token(0);
const SIM_CTL: Token = Token(1);
const WAKE: Token = Token(2);
const TIMER: Token = Token(3);

/// Where TM goes.
pub struct Downlink {
    udp: Arc<UdpSocket>,
    udp_peer: Option<SocketAddr>,
    tcp_clients: Arc<Mutex<Vec<TcpStream>>>,
    frame: Vec<u8>,
    /// Live TM packets that could not be sent (UDP send errors, dropped TCP clients).
    pub tm_dropped: u32,
}

impl Downlink {
    pub fn set_udp_peer(&mut self, peer: SocketAddr) {
        self.udp_peer = Some(peer);
    }
}

impl obsw_core::tm::TmSink for Downlink {
    fn send_tm(&mut self, packet: &[u8]) {
        if let Some(peer) = self.udp_peer {
            // A full socket buffer or an unreachable peer must not stop the OBSW; the
            // on-board store keeps the packet for a later downlink.
            if !send_udp(&self.udp, packet, peer) {
                self.tm_dropped = self.tm_dropped.wrapping_add(1);
            }
        }
        let Ok(mut clients) = self.tcp_clients.lock() else {
            return;
        };
        if clients.is_empty() {
            return;
        }
        self.frame.resize(cobs::max_encoding_length(packet.len()) + 1, 0);
        let n = cobs::encode(packet, &mut self.frame);
        self.frame[n] = 0;
        let frame = &self.frame[..=n];
        let before = clients.len();
        clients.retain_mut(|c| c.write_all(frame).is_ok());
        self.tm_dropped = self.tm_dropped.wrapping_add((before - clients.len()) as u32);
    }
}

/// Sends one datagram on the non-blocking socket. A full send buffer (the ground reads
/// slower than the OBSW writes) is waited out for up to `TM_WRITE_TIMEOUT_MS`, so a
/// burst is paced rather than lost; an unreachable peer fails at once.
fn send_udp(sock: &UdpSocket, packet: &[u8], peer: SocketAddr) -> bool {
    let deadline = std::time::Instant::now() + Duration::from_millis(mib::config::TM_WRITE_TIMEOUT_MS as u64);
    loop {
        match sock.send_to(packet, peer) {
            Ok(_) => return true,
            Err(e) if e.kind() == ErrorKind::WouldBlock && std::time::Instant::now() < deadline => {
                thread::sleep(Duration::from_micros(50));
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
    udp: Arc<UdpSocket>,
    sim_ctl: UdpSocket,
    rx: Receiver<Input>,
    buf: Vec<u8>,
    /// epoll's timeout has millisecond resolution; a timerfd wakes the poll at the
    /// control period's deadline to the microsecond.
    timer: TimerFd,
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
) -> anyhow::Result<(Inputs, Downlink, Bound)> {
    let udp = UdpSocket::bind(udp_addr).map_err(|e| anyhow::anyhow!("cannot bind UDP {udp_addr}: {e}"))?;
    let tcp = TcpListener::bind(tcp_addr).map_err(|e| anyhow::anyhow!("cannot bind TCP {tcp_addr}: {e}"))?;
    let sim_ctl = UdpSocket::bind(sim_ctl_addr)
        .map_err(|e| anyhow::anyhow!("cannot bind simulator control UDP {sim_ctl_addr}: {e}"))?;
    let bound = Bound {
        udp: udp.local_addr()?,
        tcp: tcp.local_addr()?,
        sim_ctl: sim_ctl.local_addr()?,
    };
    udp.set_nonblocking(true)?;
    sim_ctl.set_nonblocking(true)?;
    let poll = Poll::new()?;
    poll.registry()
        .register(&mut SourceFd(&udp.as_raw_fd()), UDP, Interest::READABLE)?;
    poll.registry()
        .register(&mut SourceFd(&sim_ctl.as_raw_fd()), SIM_CTL, Interest::READABLE)?;
    let waker = Arc::new(Waker::new(poll.registry(), WAKE)?);
    let timer = TimerFd::new_custom(ClockId::Monotonic, true, true)?;
    poll.registry()
        .register(&mut SourceFd(&timer.as_raw_fd()), TIMER, Interest::READABLE)?;
    let (tx, rx) = std::sync::mpsc::channel();
    let udp = Arc::new(udp);
    let down = Downlink {
        udp: udp.clone(),
        udp_peer: None,
        tcp_clients: Arc::new(Mutex::new(Vec::new())),
        frame: Vec::new(),
        tm_dropped: 0,
    };
    let clients = down.tcp_clients.clone();
    thread::Builder::new().name("tcp-accept".into()).spawn(move || {
        for stream in tcp.incoming().flatten() {
            let _ = stream.set_nodelay(true);
            // A client that stops reading must not stall the OBSW: a write that cannot
            // complete in this time drops the client (its TM stays in the on-board store).
            let _ = stream.set_write_timeout(Some(Duration::from_millis(mib::config::TM_WRITE_TIMEOUT_MS as u64)));
            let Ok(reader) = stream.try_clone() else { continue };
            if let Ok(mut c) = clients.lock() {
                c.push(stream);
            }
            let (ttx, w) = (tx.clone(), waker.clone());
            let _ = thread::Builder::new()
                .name("tcp-tc".into())
                .spawn(move || read_cobs(reader, ttx, w));
        }
    })?;
    let inputs = Inputs {
        poll,
        events: Events::with_capacity(16),
        udp,
        sim_ctl,
        rx,
        buf: vec![0u8; 65_536],
        timer,
    };
    Ok((inputs, down, bound))
}

impl Inputs {
    /// The next input that is already waiting, if any (never blocks).
    pub fn next(&mut self) -> Option<Input> {
        loop {
            match self.udp.recv_from(&mut self.buf) {
                Ok((n, from)) => return Some(Input::Tc(self.buf[..n].to_vec(), Origin::Udp(from))),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // WouldBlock: nothing waiting. Other errors (an ICMP port-unreachable
                // from an old peer on some systems) are not fatal either.
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(_) => continue,
            }
        }
        if let Ok(input) = self.rx.try_recv() {
            return Some(input);
        }
        let mut line = [0u8; 512];
        if let Ok((n, from)) = self.sim_ctl.recv_from(&mut line) {
            return Some(Input::SimCtl(
                String::from_utf8_lossy(&line[..n]).trim().to_string(),
                from,
            ));
        }
        None
    }

    /// Waits until an input may be waiting or `timeout` passes.
    pub fn wait(&mut self, timeout: Duration) {
        if timeout.is_zero() {
            return;
        }
        self.timer
            .set_state(TimerState::Oneshot(timeout), SetTimeFlags::Default);
        // The timer ends the wait; the poll timeout is only a backstop. Interrupted or
        // failed waits just return: the caller drains and waits again.
        let _ = self
            .poll
            .poll(&mut self.events, Some(timeout + Duration::from_millis(2)));
        self.timer.read();
    }

    /// Answers a simulator-control line.
    pub fn reply_sim_ctl(&self, to: SocketAddr, text: &str) {
        let _ = self.sim_ctl.send_to(text.as_bytes(), to);
    }
}

/// Reads COBS frames from a TCP stream until it closes.
fn read_cobs(mut s: TcpStream, tx: Sender<Input>, waker: Arc<Waker>) {
    let mut chunk = [0u8; 4096];
    let mut frame: Vec<u8> = Vec::with_capacity(2 * MAX_PACKET_LEN);
    let mut overflow = false;
    loop {
        let n = match s.read(&mut chunk) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        for &b in &chunk[..n] {
            if b != 0 {
                if frame.len() < 2 * MAX_PACKET_LEN {
                    frame.push(b);
                } else {
                    overflow = true;
                }
                continue;
            }
            if frame.is_empty() && !overflow {
                continue;
            }
            let input = if overflow {
                Input::BadFrame
            } else {
                let mut out = vec![0u8; frame.len()];
                match cobs::decode(&frame, &mut out) {
                    Ok(r) => {
                        out.truncate(r.frame_size());
                        Input::Tc(out, Origin::Tcp)
                    }
                    Err(_) => Input::BadFrame,
                }
            };
            frame.clear();
            overflow = false;
            if tx.send(input).is_err() || waker.wake().is_err() {
                return;
            }
        }
    }
}
