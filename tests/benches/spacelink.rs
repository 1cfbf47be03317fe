//! Space-link benchmark (docs/space-link.md): PUS 17 ping round trip through TC/TM frames, COP-1 and
//! SDLS (the `ground-link` library against the real `obsw --frame-udp`) side by side with
//! the same ping as a bare UDP packet to a second obsw on the lab link
//! (`--lab-bare-packets`) and a bare UDP echo, alternating in one run. Each obsw runs one
//! link only, as deployed: an obsw with both links sends every TM on both, so each
//! ping would also pay for the other link's sends. Run: `cargo bench -p e2e-tests --bench
//! spacelink` (release build of the obsw).
//!
//! Both ends persist SDLS counters in state files on the temp directory's file system:
//! the receive counter of every frame is written and `fdatasync`ed before the frame is
//! used, which is part of what is measured (`BENCH_STATE_DIR` moves the files, e.g. to a
//! tmpfs, to see the file system's share).

use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use e2e_tests::{request_of, tc, Obsw, Tm};
use ground_link::{create_key_file, Config, GroundFrameLink};
use mmic_link::fop::{FopConfig, FopState};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};

fn stats(name: &str, mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let p = |q: f64| v[((v.len() as f64 - 1.0) * q).round() as usize];
    let med = p(0.5);
    println!("{name}: median {med:.1} us, p99 {:.1} us, n {}", p(0.99), v.len());
    med
}

/// A ping asking only for the completion report: TM[17,2] and TM[1,7], the latter
/// carrying the request ID (so a late reply to an earlier ping is not taken for this one).
fn ping(apid: u16, seq: u16) -> Vec<u8> {
    let mut raw = tc(apid, mib::headers::SeqCount::new(seq).get(), 17, 1, &[]);
    raw[6] = (raw[6] & 0xF0) | 0x01;
    let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&raw[..raw.len() - 2]);
    let l = raw.len();
    raw[l - 2..].copy_from_slice(&crc.to_be_bytes());
    raw
}

fn main() {
    let n: usize = std::env::var("BENCH_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    if std::env::var_os("LINK_BENCH_ECHO").is_some() {
        let echo = UdpSocket::bind("127.0.0.1:0").unwrap();
        println!("{}", echo.local_addr().unwrap());
        let mut b = [0u8; 2048];
        while let Ok((k, from)) = echo.recv_from(&mut b) {
            let _ = echo.send_to(&b[..k], from);
        }
        return;
    }
    let mut echo_proc = std::process::Command::new(std::env::current_exe().unwrap())
        .env("LINK_BENCH_ECHO", "1")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("echo server");
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(echo_proc.stdout.take().unwrap()),
        &mut line,
    )
    .unwrap();
    let echo_addr: SocketAddr = line.trim().parse().unwrap();

    let base = std::env::var_os("BENCH_STATE_DIR").map_or_else(std::env::temp_dir, PathBuf::from);
    let dir = base.join(format!("spacelink-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (tck, tmk) = (dir.join("TEST-KEY-tc-spi1.key"), dir.join("TEST-KEY-tm-spi17.key"));
    create_key_file(&tck, &TEST_KEY_TC_A).unwrap();
    create_key_file(&tmk, &TEST_KEY_TM_A).unwrap();
    let frame = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let mut cfg = Config::from_key_files(
        frame,
        SocketAddr::from(([127, 0, 0, 1], 0)),
        &tck,
        &tmk,
        &dir.join("ground.state"),
    )
    .unwrap();
    cfg.fop = FopConfig::mission();
    let mut g = GroundFrameLink::open(cfg).unwrap();
    let s = |p: &PathBuf| p.display().to_string();
    let o = Obsw::start(&[
        "--frame-udp",
        &frame.to_string(),
        "--frame-tm-to",
        &g.local_addr().unwrap().to_string(),
        "--tc-key",
        &s(&tck),
        "--tm-key",
        &s(&tmk),
        "--link-state",
        &s(&dir.join("obsw.state")),
    ]);
    // The bare-packet lab link, in an obsw of its own.
    let o_bare = Obsw::start(&[]);
    let until = Instant::now() + Duration::from_secs(10);
    while g.fop_state() != FopState::Active && Instant::now() < until {
        g.recv(Duration::from_millis(20)).unwrap();
    }
    assert_eq!(g.fop_state(), FopState::Active, "COP-1 initialised");
    let cli = UdpSocket::bind("127.0.0.1:0").unwrap();
    cli.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let bare_sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    bare_sock.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut b = [0u8; 2048];
    let (mut echo, mut bare, mut framed) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let p = ping(o_bare.apid, i as u16);
        let t = Instant::now();
        cli.send_to(&p, echo_addr).unwrap();
        cli.recv(&mut b).unwrap();
        echo.push(t.elapsed().as_secs_f64() * 1e6);

        let t = Instant::now();
        bare_sock.send_to(&p, o_bare.udp).unwrap();
        loop {
            let k = bare_sock.recv(&mut b).expect("bare ping reply");
            if Tm::parse(&b[..k]).is_some_and(|t| t.subservice == 7 && t.request() == Some(request_of(&p))) {
                break;
            }
        }
        bare.push(t.elapsed().as_secs_f64() * 1e6);

        let p = ping(o.apid, i as u16);
        let t = Instant::now();
        g.send_packet(&p).unwrap();
        'wait: loop {
            for pkt in g.recv(Duration::from_secs(2)).unwrap() {
                if Tm::parse(&pkt).is_some_and(|t| t.subservice == 7 && t.request() == Some(request_of(&p))) {
                    break 'wait;
                }
            }
            assert!(t.elapsed() < Duration::from_secs(5), "framed ping reply");
        }
        framed.push(t.elapsed().as_secs_f64() * 1e6);
    }
    let e = stats("udp_echo_rtt", echo);
    let b = stats("pus17_bare_udp_rtt", bare);
    let f = stats("pus17_frames_sdls_rtt", framed);
    println!("frames_vs_bare_pus_ratio: {:.2}", f / b);
    println!("frames_vs_udp_echo_ratio: {:.2}", f / e);
    // The floor of any ping through the obsw: the bare ping over the same echo.
    println!("bare_vs_udp_echo_ratio: {:.2}", b / e);
    println!(
        "ground: {} AD frames, {} retransmissions",
        g.counters.ad_frames_sent, g.counters.retransmissions
    );
    drop(o);
    drop(o_bare);
    let _ = echo_proc.kill();
    let _ = echo_proc.wait();
    let _ = std::fs::remove_dir_all(&dir);
}
