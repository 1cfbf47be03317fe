//! Ground link of the host OBSW: TCs arrive on UDP datagrams and on TCP streams framed
//! with COBS (a 0x00 after each frame); TM goes to every TCP client and to the last UDP
//! sender. Each socket has its own reader thread, so a TC is handled the moment it
//! arrives, not at the next poll.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::thread;

use mib::config::MAX_PACKET_LEN;

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

/// Where TM goes.
#[derive(Clone)]
pub struct Downlink {
    udp: Arc<UdpSocket>,
    udp_peer: Arc<Mutex<Option<SocketAddr>>>,
    tcp_clients: Arc<Mutex<Vec<TcpStream>>>,
    frame: Vec<u8>,
    /// Live TM packets that could not be sent (UDP send errors, dropped TCP clients).
    pub tm_dropped: u32,
}

impl Downlink {
    pub fn set_udp_peer(&self, peer: SocketAddr) {
        if let Ok(mut p) = self.udp_peer.lock() {
            *p = Some(peer);
        }
    }
}

impl obsw_core::tm::TmSink for Downlink {
    fn send_tm(&mut self, packet: &[u8]) {
        if let Ok(p) = self.udp_peer.lock() {
            if let Some(peer) = *p {
                // A full socket buffer or an unreachable peer must not stop the OBSW;
                // the on-board store keeps the packet for a later downlink.
                if self.udp.send_to(packet, peer).is_err() {
                    self.tm_dropped = self.tm_dropped.wrapping_add(1);
                }
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

/// Binds the UDP and TCP TC ports and starts their reader threads.
pub fn start(
    udp_addr: SocketAddr,
    tcp_addr: SocketAddr,
    tx: Sender<Input>,
) -> anyhow::Result<(Downlink, SocketAddr, SocketAddr)> {
    let udp = UdpSocket::bind(udp_addr).map_err(|e| anyhow::anyhow!("cannot bind UDP {udp_addr}: {e}"))?;
    let tcp = TcpListener::bind(tcp_addr).map_err(|e| anyhow::anyhow!("cannot bind TCP {tcp_addr}: {e}"))?;
    let (udp_local, tcp_local) = (udp.local_addr()?, tcp.local_addr()?);
    let udp = Arc::new(udp);
    let down = Downlink {
        udp: udp.clone(),
        udp_peer: Arc::new(Mutex::new(None)),
        tcp_clients: Arc::new(Mutex::new(Vec::new())),
        frame: Vec::new(),
        tm_dropped: 0,
    };

    let utx = tx.clone();
    thread::Builder::new().name("udp-tc".into()).spawn(move || {
        let mut buf = vec![0u8; 65_536];
        loop {
            match udp.recv_from(&mut buf) {
                Ok((n, from)) => {
                    if utx.send(Input::Tc(buf[..n].to_vec(), Origin::Udp(from))).is_err() {
                        return;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                // ICMP port-unreachable from an old peer shows up as a receive error
                // on some systems: keep serving.
                Err(_) => {}
            }
        }
    })?;

    let clients = down.tcp_clients.clone();
    thread::Builder::new().name("tcp-accept".into()).spawn(move || {
        for stream in tcp.incoming().flatten() {
            let _ = stream.set_nodelay(true);
            // A client that stops reading must not stall the OBSW: a write that cannot
            // complete in this time drops the client (its TM stays in the on-board store).
            let _ = stream.set_write_timeout(Some(std::time::Duration::from_millis(
                mib::config::TCP_WRITE_TIMEOUT_MS as u64,
            )));
            let Ok(reader) = stream.try_clone() else { continue };
            if let Ok(mut c) = clients.lock() {
                c.push(stream);
            }
            let ttx = tx.clone();
            let _ = thread::Builder::new()
                .name("tcp-tc".into())
                .spawn(move || read_cobs(reader, ttx));
        }
    })?;
    Ok((down, udp_local, tcp_local))
}

/// Reads COBS frames from a TCP stream until it closes.
fn read_cobs(mut s: TcpStream, tx: Sender<Input>) {
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
            if tx.send(input).is_err() {
                return;
            }
        }
    }
}

/// Binds the simulator control channel (separate from the flight TC path).
pub fn start_sim_ctl(addr: SocketAddr, tx: Sender<Input>) -> anyhow::Result<(Arc<UdpSocket>, SocketAddr)> {
    let sock =
        Arc::new(UdpSocket::bind(addr).map_err(|e| anyhow::anyhow!("cannot bind simulator control UDP {addr}: {e}"))?);
    let local = sock.local_addr()?;
    let rx = sock.clone();
    thread::Builder::new().name("sim-ctl".into()).spawn(move || {
        let mut buf = [0u8; 512];
        loop {
            if let Ok((n, from)) = rx.recv_from(&mut buf) {
                let line = String::from_utf8_lossy(&buf[..n]).trim().to_string();
                if tx.send(Input::SimCtl(line, from)).is_err() {
                    return;
                }
            }
        }
    })?;
    Ok((sock, local))
}
