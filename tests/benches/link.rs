//! Link benchmark of the real `obsw` binary (run: `cargo bench -p e2e-tests --bench link`).
//!
//! 1. PUS 17 round trip over UDP loopback (TC[17,1] out, TM[17,2] back), median and
//!    p99, side by side with a bare UDP echo measured in the same run.
//! 2. Sustained TC rate: pings sent as fast as the OBSW verifies them (windowed), as TCs
//!    per second fully verified (TM[1,7] received).
//! 3. HK period jitter at 10 Hz: arrival spacing of TM[3,25] SID 1 against 100 ms.
//!
//! Figures are printed as `name: value`; the build must be `--release` for the OBSW
//! (`cargo build --release -p obsw`), which is what `OBSW_BIN` or target/release finds.

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use e2e_tests::{tc, Client, Obsw, Tm};

fn pct(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() as f64 - 1.0) * p).round() as usize]
}

fn stats(name: &str, mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let med = pct(&v, 0.5);
    println!(
        "{name}: median {:.1} us, p99 {:.1} us, n {}",
        med,
        pct(&v, 0.99),
        v.len()
    );
    med
}

fn main() {
    let n: usize = std::env::var("BENCH_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5000);
    // Bare UDP echo baseline, in its own process like the OBSW, so both see the same
    // cross-process wake-up costs (this benchmark re-runs itself as the echo server).
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
    let echo_addr: std::net::SocketAddr = line.trim().parse().unwrap();
    let cli = UdpSocket::bind("127.0.0.1:0").unwrap();
    cli.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let ping_bytes = tc(0x101, 1, 17, 1, &[]);
    let mut b = [0u8; 2048];

    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let sock = match &c.link {
        e2e_tests::Link::Udp(s, _) => s.try_clone().unwrap(),
        _ => unreachable!(),
    };
    sock.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    // Echo and PUS round trips alternate, so both see the same machine state (this
    // machine's wake-up latency swings by 20x between idle and busy).
    let mut echo_rtt = Vec::with_capacity(n);
    let mut pus_rtt = Vec::with_capacity(n);
    for i in 0..n {
        let t = Instant::now();
        cli.send_to(&ping_bytes, echo_addr).unwrap();
        cli.recv(&mut b).unwrap();
        echo_rtt.push(t.elapsed().as_secs_f64() * 1e6);

        // The benchmark TC asks for no verification reports: TM[17,2] is the only reply.
        let mut raw = tc(o.apid, mib::headers::SeqCount::new(i as u16).get(), 17, 1, &[]);
        raw[6] &= 0xF0;
        let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&raw[..raw.len() - 2]);
        let l = raw.len();
        raw[l - 2..].copy_from_slice(&crc.to_be_bytes());
        let t = Instant::now();
        sock.send_to(&raw, o.udp).unwrap();
        loop {
            let k = sock.recv(&mut b).expect("ping reply");
            if Tm::parse(&b[..k]).is_some_and(|t| t.service == 17) {
                break;
            }
        }
        pus_rtt.push(t.elapsed().as_secs_f64() * 1e6);
    }
    let e = stats("udp_echo_rtt", echo_rtt);
    let p = stats("pus17_rtt", pus_rtt);
    println!("pus17_vs_echo_ratio: {:.2}", p / e);

    // Sustained verified TC rate, 64 TCs in flight.
    let total = n * 4;
    let window = 64usize;
    let start = Instant::now();
    let (mut sent, mut done, mut lost) = (0usize, 0usize, 0usize);
    let mut last_progress = Instant::now();
    sock.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    while done + lost < total && start.elapsed() < Duration::from_secs(60) {
        while sent < total && sent - done - lost < window {
            let raw = tc(o.apid, mib::headers::SeqCount::new(sent as u16).get(), 17, 1, &[]);
            sock.send_to(&raw, o.udp).unwrap();
            sent += 1;
        }
        if let Ok(k) = sock.recv(&mut b) {
            if Tm::parse(&b[..k]).is_some_and(|t| t.service == 1 && t.subservice == 7) {
                done += 1;
                last_progress = Instant::now();
            }
        }
        // A completion that never comes (a datagram dropped by a full socket buffer)
        // must not stall the window: after 200 ms without progress the rest of the
        // window counts as lost.
        if last_progress.elapsed() > Duration::from_millis(200) {
            lost = sent - done;
            last_progress = Instant::now();
        }
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "verified_tc_per_s_over_udp: {:.0} ({} of {} completed, {} reports lost)",
        done as f64 / secs,
        done,
        total,
        lost
    );
    drop(c.log.drain(..));

    // HK jitter at 10 Hz.
    let o2 = Obsw::start(&[]);
    let mut h = Client::udp(&o2);
    let raw = h.send("HK_SET_INTERVAL", &[1, 100]);
    h.wait_done(&raw, Duration::from_secs(2)).expect("interval");
    let secs: u64 = std::env::var("BENCH_HK_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let got = h.recv_for(Duration::from_secs(secs));
    let times: Vec<Instant> = got.iter().filter(|t| t.sid() == Some(1)).map(|t| t.at).collect();
    let jitter: Vec<f64> = times
        .windows(2)
        .map(|w| ((w[1] - w[0]).as_secs_f64() * 1e3 - 100.0).abs() * 1e3)
        .collect();
    stats("hk_10hz_period_jitter", jitter);
    let _ = echo_proc.kill();
    let _ = echo_proc.wait();
}
