//! The host's inter-robot link and durable team state (issue 25): team packets as UDP
//! datagrams between obsw processes (`--team-udp`, `--peer N=ADDR`), the term and vote in
//! `--team-state` (written to a temporary file, synced, renamed over the old one and the
//! directory synced, before `persist` returns, so before any send of the same batch), and
//! the election randomness from the OS (`/dev/urandom`).

use std::fs::File;
use std::io::{Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mmic_team::{Dest, Persisted};
use obsw_core::services::team::TeamLink;

/// Parses `N=ADDR` (a `--peer` value).
pub fn parse_peer(s: &str) -> Result<(u8, SocketAddr)> {
    let (n, a) = s
        .split_once('=')
        .with_context(|| format!("--peer {s:?}: expected N=ADDR"))?;
    let n: u8 = n
        .trim()
        .parse()
        .with_context(|| format!("--peer {s:?}: robot number"))?;
    if mib::apid::robot_apid(n).is_none() {
        bail!(
            "--peer {s:?}: robot numbers are {}..={}",
            mib::apid::ROBOT_MIN,
            mib::apid::ROBOT_MAX
        );
    }
    let a: SocketAddr = a.trim().parse().with_context(|| format!("--peer {s:?}: address"))?;
    Ok((n, a))
}

pub struct TeamUdp {
    sock: UdpSocket,
    peers: Vec<(u8, SocketAddr)>,
    state: PathBuf,
    urandom: File,
    /// Team datagrams that could not be sent (added to HK IO_TM_DROPPED).
    pub send_errors: u32,
    /// Persists that failed (the core treats each as a reset).
    pub persist_errors: u32,
}

impl TeamUdp {
    /// Binds the team socket and reads the durable term and vote (none: term 0).
    pub fn open(listen: SocketAddr, peers: Vec<(u8, SocketAddr)>, state: PathBuf) -> Result<(TeamUdp, Persisted)> {
        let sock = UdpSocket::bind(listen).with_context(|| format!("--team-udp {listen}"))?;
        sock.set_nonblocking(true)?;
        let persisted = read_state(&state)?;
        let urandom = File::open("/dev/urandom").context("opening /dev/urandom")?;
        Ok((
            TeamUdp {
                sock,
                peers,
                state,
                urandom,
                send_errors: 0,
                persist_errors: 0,
            },
            persisted,
        ))
    }

    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.sock.local_addr()?)
    }

    /// A random number from the OS (election jitter).
    pub fn rand(&mut self) -> u32 {
        let mut b = [0u8; 4];
        match self.urandom.read_exact(&mut b) {
            Ok(()) => u32::from_ne_bytes(b),
            // Jitter only breaks ties; safety never depends on it.
            Err(_) => std::process::id(),
        }
    }

    /// The next datagram received, if any (non-blocking).
    pub fn recv(&mut self, buf: &mut [u8]) -> Option<usize> {
        loop {
            match self.sock.recv_from(buf) {
                Ok((n, _)) => return Some(n),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
                // ICMP port unreachable of an earlier send to a dead peer: skip it.
                Err(_) => continue,
            }
        }
    }
}

/// Reads `term voted_for` (voted_for 0 = none); a missing file is term 0.
fn read_state(p: &Path) -> Result<Persisted> {
    let text = match std::fs::read_to_string(p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Persisted::default()),
        Err(e) => return Err(e).with_context(|| format!("--team-state {}", p.display())),
    };
    let mut it = text.split_whitespace();
    let (Some(t), Some(v), None) = (it.next(), it.next(), it.next()) else {
        bail!(
            "--team-state {}: expected 'TERM VOTED_FOR', found {text:?}",
            p.display()
        );
    };
    let term: u32 = t
        .parse()
        .with_context(|| format!("--team-state {}: term", p.display()))?;
    let v: u8 = v
        .parse()
        .with_context(|| format!("--team-state {}: vote", p.display()))?;
    Ok(Persisted {
        term,
        voted_for: (v != 0).then_some(v),
    })
}

fn write_state(p: &Path, s: Persisted) -> std::io::Result<()> {
    let tmp = p.with_extension("tmp");
    {
        let mut f = File::create(&tmp)?;
        writeln!(f, "{} {}", s.term, s.voted_for.unwrap_or(0))?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, p)?;
    let dir = p
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    File::open(dir)?.sync_all()
}

impl TeamLink for TeamUdp {
    fn persist(&mut self, p: Persisted) -> bool {
        match write_state(&self.state, p) {
            Ok(()) => true,
            Err(e) => {
                self.persist_errors += 1;
                log::error!("team state {}: {e}", self.state.display());
                false
            }
        }
    }

    fn send(&mut self, to: Dest, packet: &[u8]) {
        for (n, addr) in &self.peers {
            if to == Dest::All || to == Dest::To(*n) {
                // An earlier send to a dead peer leaves an ICMP "port unreachable" pending
                // on the socket, which fails the next send (to any peer) once: try again.
                let sent = self
                    .sock
                    .send_to(packet, addr)
                    .or_else(|_| self.sock.send_to(packet, addr));
                if sent.is_err() {
                    self.send_errors = self.send_errors.wrapping_add(1);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: TEAM-OBSW-01
    #[test]
    fn the_state_file_round_trips_and_a_missing_one_is_term_0() {
        let dir = std::env::temp_dir().join(format!("obsw-team-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("team.state");
        let _ = std::fs::remove_file(&p);
        assert_eq!(read_state(&p).unwrap(), Persisted::default());
        let s = Persisted {
            term: 7,
            voted_for: Some(3),
        };
        write_state(&p, s).unwrap();
        assert_eq!(read_state(&p).unwrap(), s);
        std::fs::write(&p, "x").unwrap();
        assert!(read_state(&p).is_err(), "a corrupt state is an error, never term 0");
        assert!(parse_peer("2=127.0.0.1:9000").is_ok());
        assert!(parse_peer("0=127.0.0.1:9000").is_err());
        assert!(parse_peer("2:127.0.0.1").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
