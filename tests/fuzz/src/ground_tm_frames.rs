//! The ground's TM frame receiver (`ground_link::GroundFrameLink` over a byte stream: COBS
//! deframing, TM frame checks, SDLS, packet demultiplexing, the CLCW into FOP-1), fed the
//! bytes of board A's serial ground link through a socket pair, as `ground` runs against a
//! board or QEMU. A ping TC is queued first, so FOP-1 has a frame to send once the link
//! initiates.
//!
//! Records:
//! - tag % 4 == 0: raw bytes on the line (an attacker's bytes, a replayed capture);
//! - 1: the robot's framer (`mmic_link::downlink::TmFramer`, TM test key) sends a packet:
//!   body = CLCW word (4 bytes), flags, packet; flags bit 0: replay VC; bit 1: wrap the
//!   packet in a TM space-packet header; the frames go on the line COBS-encoded;
//! - 2: an idle frame carrying the CLCW word of the body's first 4 bytes;
//! - 3: time passes (the body's first two bytes, ms).
//!
//! After every record the ground polls. Invariants: nothing panics; every packet the ground
//! hands up is one the robot's framer sent with the key (raw bytes on the line never
//! become packets); the ground still accepts a fresh, authentic frame afterwards.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;

use ground_link::{Config, GroundFrameLink, TmSecurity, RESYNC_SETTLE_MS};
use mmic_link::clcw::Clcw;
use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::fop::FopConfig;
use mmic_link::sdls::{MemoryIvStore, TxSa};
use mmic_link::stream::port::Port;
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};

/// The ground's SDLS state file: on a RAM file system where there is one (the store
/// writes with `O_DSYNC`), fresh for every input.
fn state_file() -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("mmic-fuzz-ground-{}.state", std::process::id()))
}

/// A CLCW from four fuzzed bytes (the marker bit and version forced to a CLCW's).
fn clcw(b: &[u8]) -> Clcw {
    let w = u32::from_be_bytes([
        b.first().copied().unwrap_or(0),
        b.get(1).copied().unwrap_or(0),
        b.get(2).copied().unwrap_or(0),
        b.get(3).copied().unwrap_or(0),
    ]);
    Clcw::parse(w & 0x1FFF_FFFF).expect("marker and version cleared")
}

/// Wraps `body` in a TM space-packet primary header whose length field fits it.
pub fn tm_packet(body: &[u8]) -> Vec<u8> {
    let body: &[u8] = if body.is_empty() { &[0] } else { body };
    let n = (body.len() - 1) as u16;
    let mut p = vec![0x09, 0x01, 0xC0, 0x00];
    p.extend_from_slice(&n.to_be_bytes());
    p.extend_from_slice(body);
    p
}

struct Robot {
    dl: TmFramer,
    sa: TxSa,
    store: MemoryIvStore,
    line: UnixStream,
}

/// `0x00, COBS(frame), 0x00`, byte for byte what `mmic_link::stream::encode` writes, with
/// the search for zeros in the standard library's precompiled `memchr` (through
/// `CStr::from_bytes_until_nul`), which the fuzzer's instrumentation does not trace. The
/// robot's side is not the code under test; encoding each ~1 kB frame through the traced
/// byte-by-byte encoder took a quarter of this target's time.
pub fn cobs_frame(frame: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(frame.len() + frame.len() / 254 + 3);
    out.push(0);
    let mut rest = frame;
    loop {
        let window = &rest[..rest.len().min(254)];
        match std::ffi::CStr::from_bytes_until_nul(window) {
            Ok(c) => {
                let i = c.to_bytes().len();
                out.push(i as u8 + 1);
                out.extend_from_slice(&rest[..i]);
                rest = &rest[i + 1..];
            }
            Err(_) if window.len() == 254 => {
                out.push(255);
                out.extend_from_slice(window);
                rest = &rest[254..];
                if rest.is_empty() {
                    break;
                }
            }
            Err(_) => {
                out.push(window.len() as u8 + 1);
                out.extend_from_slice(window);
                break;
            }
        }
    }
    out.push(0);
    out
}

/// Frames encoded so far by this process whose [`cobs_frame`] was compared with the
/// project's encoder (the first [`CHECK_FRAMES`]).
static CHECKED: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
const CHECK_FRAMES: u32 = 2_000;

impl Robot {
    fn put_frame(&mut self, frame: &[u8]) {
        let enc = cobs_frame(frame);
        if CHECKED.fetch_add(1, std::sync::atomic::Ordering::Relaxed) < CHECK_FRAMES {
            let mut want = vec![0u8; mmic_link::stream::encoded_len(frame.len())];
            let n = mmic_link::stream::encode(frame, &mut want).expect("buffer of encoded_len");
            assert_eq!(
                enc,
                want[..n],
                "the harness's COBS differs from the project's for {frame:02x?}"
            );
        }
        self.line.write_all(&enc).expect("socket pair takes the frame");
    }

    /// Sends `packet`; returns whether the framer took it.
    fn send(&mut self, vc: TmVc, clcw: Clcw, packet: &[u8]) -> bool {
        let mut frames: Vec<Vec<u8>> = Vec::new();
        let sent = self.dl.send(vc, packet, clcw, &mut self.sa, &mut self.store, |f| {
            frames.push(f.to_vec())
        });
        let flushed = self
            .dl
            .flush(vc, clcw, &mut self.sa, &mut self.store, |f| frames.push(f.to_vec()));
        for f in &frames {
            self.put_frame(f);
        }
        sent.is_ok() && flushed.is_ok()
    }

    /// Reads (and forgets) what the ground sent, so the socket never fills.
    fn drain(&mut self) {
        let mut buf = [0u8; 4096];
        while matches!(self.line.read(&mut buf), Ok(n) if n > 0) {}
    }
}

pub fn run(data: &[u8]) {
    let state = state_file();
    let _ = std::fs::remove_file(&state);
    let (ground_end, robot_end) = UnixStream::pair().expect("socket pair");
    robot_end.set_nonblocking(true).expect("non-blocking");
    let addr = "127.0.0.1:9".parse().expect("address");
    let cfg = Config {
        robot: addr,
        listen: addr,
        tc_spi: mib::link::sdls::TC_SPIS[0],
        tc_key: TEST_KEY_TC_A,
        tm_key: TEST_KEY_TM_A,
        tm_spare_key: None,
        tm_security: TmSecurity::Encrypt,
        state: state.clone(),
        fop: FopConfig::mission(),
        settle_ms: RESYNC_SETTLE_MS,
    };
    let mut link = GroundFrameLink::open_port(cfg, Port::from_unix(ground_end).expect("port")).expect("link opens");
    let _ = link.send_packet(&crate::pus_tc::tc(1, 17, 1, &[]));
    let mut robot = Robot {
        dl: TmFramer::mission(),
        sa: TxSa::resume(mib::link::sdls::TM_SPIS[0], &TEST_KEY_TM_A, 0),
        store: MemoryIvStore::default(),
        line: robot_end,
    };
    let mut sent: Vec<Vec<u8>> = Vec::new();
    let mut now = 0u64;
    for (tag, body) in crate::records(data, 48) {
        now += 10;
        match tag % 4 {
            0 => robot.line.write_all(body).expect("socket pair takes the bytes"),
            1 => {
                let (word, flags, rest) = match body {
                    [a, b, c, d, f, rest @ ..] => ([*a, *b, *c, *d], *f, rest),
                    _ => continue,
                };
                let vc = if flags & 1 != 0 { TmVc::Replay } else { TmVc::Realtime };
                let packet = if flags & 2 != 0 { tm_packet(rest) } else { rest.to_vec() };
                if robot.send(vc, clcw(&word), &packet) {
                    sent.push(packet);
                }
            }
            2 => {
                let mut frame = [0u8; mib::link::tm_frame::LEN];
                robot.dl.idle(clcw(body), &mut frame);
                robot.put_frame(&frame);
            }
            _ => {
                now += u64::from(u16::from_be_bytes([
                    body.first().copied().unwrap_or(0),
                    body.get(1).copied().unwrap_or(0),
                ]))
            }
        }
        for p in link.poll(now).expect("the link keeps running") {
            assert!(sent.contains(&p), "a packet no key sealed reached the ground: {p:02x?}");
        }
        robot.drain();
    }
    // Whatever came before, a fresh authentic packet still gets through.
    let probe = tm_packet(b"still listening");
    let ok = robot.send(TmVc::Realtime, clcw(&[0, 0, 0, 0]), &probe);
    assert!(ok, "the framer takes the probe");
    let got = link.poll(now + 10).expect("the link keeps running");
    assert!(got.contains(&probe), "the ground stopped accepting authentic frames");
    let _ = std::fs::remove_file(&state);
}

#[cfg(test)]
mod tests {
    use super::cobs_frame;

    // The harness's own check (not a requirement's test: the fuzz crate is outside the
    // workspace); scripts/fuzz-ci.sh runs it with `cargo +nightly test --lib`.
    #[test]
    fn the_harness_cobs_is_the_projects_at_every_block_boundary() {
        let mut cases: Vec<Vec<u8>> = vec![vec![], vec![0], vec![0, 0], vec![1, 0, 2]];
        for n in [1usize, 253, 254, 255, 507, 508, 509, 1024] {
            let nz: Vec<u8> = (0..n).map(|i| (i % 255) as u8 + 1).collect();
            cases.push(nz.clone());
            let mut z = nz.clone();
            z.push(0);
            cases.push(z);
            let mut z2 = vec![0];
            z2.extend_from_slice(&nz);
            cases.push(z2);
        }
        for f in cases {
            let mut want = vec![0u8; mmic_link::stream::encoded_len(f.len())];
            let n = mmic_link::stream::encode(&f, &mut want).unwrap();
            assert_eq!(cobs_frame(&f), want[..n], "frame of {} bytes", f.len());
        }
    }
}
