//! Links to OBSWs: UDP (one space packet per datagram) or TCP (COBS frames delimited
//! by 0x00, as sat-rs's TCP server frames them). Each link has a reader thread that
//! pushes every received packet, with its arrival time, into one channel.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::Sender;

use crate::pus;

/// Poll interval of the reader threads (how fast they notice a stop).
const READ_POLL: Duration = Duration::from_millis(100);

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Transport {
    Udp,
    Tcp,
}

/// A packet (or undecodable chunk) received from a robot's link.
#[derive(Clone, Debug)]
pub struct Incoming {
    pub robot: u8,
    pub t_ms: i64,
    pub bytes: Vec<u8>,
}

enum Io {
    Udp(UdpSocket),
    Tcp(Mutex<TcpStream>),
}

/// An open link to one robot's OBSW.
pub struct Link {
    pub robot: u8,
    pub addr: SocketAddr,
    io: Arc<Io>,
    stop: Arc<AtomicBool>,
    /// Set by the reader when a TCP connection ends (EOF or error).
    closed: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
}

/// Splits a buffer of concatenated space packets (a UDP datagram or a COBS frame).
/// Bytes that do not start a plausible packet are passed on as one chunk so that the
/// decoder counts them as corrupt.
pub fn split_packets(mut b: &[u8], mut out: impl FnMut(&[u8])) {
    while !b.is_empty() {
        match pus::packet_len(b) {
            Ok(n) => {
                out(&b[..n]);
                b = &b[n..];
            }
            Err(_) => {
                out(b);
                return;
            }
        }
    }
}

/// COBS-encodes a packet with a 0x00 sentinel before and after (sat-rs framing).
pub fn cobs_frame(packet: &[u8]) -> Vec<u8> {
    let mut buf = vec![0u8; cobs::max_encoding_length(packet.len()) + 2];
    let n = cobs::encode_including_sentinels(packet, &mut buf);
    buf.truncate(n);
    buf
}

/// Feeds TCP bytes; calls `out` with each decoded frame. Keeps a partial frame.
#[derive(Default)]
pub struct CobsSplitter {
    acc: Vec<u8>,
}

impl CobsSplitter {
    pub fn push(&mut self, data: &[u8], mut out: impl FnMut(Result<Vec<u8>, Vec<u8>>)) {
        for &b in data {
            if b == 0 {
                if !self.acc.is_empty() {
                    let mut dec = vec![0u8; self.acc.len()];
                    match cobs::decode(&self.acc, &mut dec) {
                        Ok(rep) => {
                            dec.truncate(rep.frame_size());
                            out(Ok(dec));
                        }
                        Err(_) => out(Err(std::mem::take(&mut self.acc))),
                    }
                    self.acc.clear();
                }
            } else if self.acc.len() < 2 * mib::config::MAX_PACKET_LEN {
                self.acc.push(b);
            } else {
                // A frame longer than any packet: give it up as corrupt.
                out(Err(std::mem::take(&mut self.acc)));
            }
        }
    }
}

impl Link {
    pub fn open(robot: u8, addr: SocketAddr, transport: Transport, tx: Sender<Incoming>) -> io::Result<Link> {
        let stop = Arc::new(AtomicBool::new(false));
        let closed = Arc::new(AtomicBool::new(false));
        let io = match transport {
            Transport::Udp => {
                let bind: SocketAddr = if addr.ip().is_loopback() {
                    (std::net::Ipv4Addr::LOCALHOST, 0).into()
                } else if addr.is_ipv6() {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                } else {
                    (std::net::Ipv4Addr::UNSPECIFIED, 0).into()
                };
                let s = UdpSocket::bind(bind)?;
                s.connect(addr)?;
                s.set_read_timeout(Some(READ_POLL))?;
                Io::Udp(s)
            }
            Transport::Tcp => {
                let s = TcpStream::connect_timeout(&addr, Duration::from_secs(2))?;
                s.set_nodelay(true)?;
                s.set_read_timeout(Some(READ_POLL))?;
                Io::Tcp(Mutex::new(s))
            }
        };
        let io = Arc::new(io);
        let reader = {
            let io = io.clone();
            let stop = stop.clone();
            let closed = closed.clone();
            let reader_stream = match &*io {
                Io::Tcp(m) => Some(m.lock().map_err(|_| io::Error::other("lock"))?.try_clone()?),
                Io::Udp(_) => None,
            };
            std::thread::Builder::new()
                .name(format!("link-{robot}"))
                .spawn(move || {
                    reader_loop(robot, &io, reader_stream, &stop, &tx);
                    if !stop.load(Ordering::Relaxed) {
                        closed.store(true, Ordering::Relaxed);
                    }
                })?
        };
        Ok(Link {
            robot,
            addr,
            io,
            stop,
            closed,
            reader: Some(reader),
        })
    }

    /// True once a TCP connection ended (the peer closed it or it failed).
    pub fn closed(&self) -> bool {
        self.closed.load(Ordering::Relaxed)
    }

    /// Sends one packet.
    pub fn send(&self, packet: &[u8]) -> io::Result<()> {
        match &*self.io {
            Io::Udp(s) => s.send(packet).map(|_| ()),
            Io::Tcp(m) => {
                let frame = cobs_frame(packet);
                m.lock()
                    .map_err(|_| io::Error::other("link lock poisoned"))?
                    .write_all(&frame)
            }
        }
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Io::Tcp(m) = &*self.io {
            if let Ok(s) = m.lock() {
                let _ = s.shutdown(std::net::Shutdown::Both);
            }
        }
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
    }
}

fn reader_loop(robot: u8, io: &Io, tcp: Option<TcpStream>, stop: &AtomicBool, tx: &Sender<Incoming>) {
    let mut buf = vec![0u8; 65536];
    let emit = |bytes: &[u8]| {
        let _ = tx.send(Incoming {
            robot,
            t_ms: crate::archive::now_ms(),
            bytes: bytes.to_vec(),
        });
    };
    match (io, tcp) {
        (Io::Udp(s), _) => {
            while !stop.load(Ordering::Relaxed) {
                match s.recv(&mut buf) {
                    Ok(n) => split_packets(&buf[..n], emit),
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::WouldBlock
                                | io::ErrorKind::TimedOut
                                | io::ErrorKind::ConnectionRefused
                                | io::ErrorKind::Interrupted
                        ) => {}
                    Err(_) => std::thread::sleep(READ_POLL),
                }
            }
        }
        (Io::Tcp(_), Some(mut s)) => {
            let mut split = CobsSplitter::default();
            while !stop.load(Ordering::Relaxed) {
                match s.read(&mut buf) {
                    Ok(0) => return,
                    Ok(n) => split.push(&buf[..n], |f| match f {
                        Ok(frame) => split_packets(&frame, emit),
                        Err(bad) => emit(&bad),
                    }),
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                        ) => {}
                    Err(_) => return,
                }
            }
        }
        (Io::Tcp(_), None) => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: DD-LINK-01
    #[test]
    fn cobs_frames_round_trip_across_partial_reads() {
        let p1 = vec![0x19, 0x01, 0x00, 0x05, 0x00, 0x00, 0x07];
        let p2 = vec![1, 2, 3];
        let mut stream = cobs_frame(&p1);
        stream.extend(cobs_frame(&p2));
        let f1 = cobs_frame(&p1);
        assert_eq!((f1[0], f1[f1.len() - 1]), (0, 0));
        assert!(!f1[1..f1.len() - 1].contains(&0));
        let mut sp = CobsSplitter::default();
        let mut got = Vec::new();
        for chunk in stream.chunks(3) {
            sp.push(chunk, |f| got.push(f.unwrap()));
        }
        assert_eq!(got, vec![p1, p2]);
    }

    // verifies: DD-LINK-01
    #[test]
    fn datagram_with_two_packets_splits() {
        let t = [0x40, 0, 1, 0, 0, 0, 0];
        let a = pus::build_tm(0x101, 1, 17, 2, 0, &t, &[]);
        let mut d = a.clone();
        d.extend_from_slice(&a);
        d.extend_from_slice(&[9, 9]);
        let mut parts = Vec::new();
        split_packets(&d, |p| parts.push(p.to_vec()));
        assert_eq!(parts, vec![a.clone(), a, vec![9, 9]]);
    }
}
