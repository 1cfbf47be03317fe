//! `relay`: the project's lossy link between a ground and an `obsw` (see `e2e_tests::relay`).
//!
//! Prints `RELAY udp=ADDR tcp=ADDR` when ready (plus ` tm_frames=ADDR` with
//! `--tm-frames-to`), the counts when it stops (after `--lifetime` or `--idle` seconds, or
//! end of input on stdin).
//!
//! Frames: point `--to-udp` at the obsw's `--frame-udp` port, and give the obsw the
//! printed `tm_frames` address as `--frame-tm-to`; the relay forwards TM frames to
//! `--tm-frames-to` (the ground's TM frame address).

use std::net::SocketAddr;
use std::time::Duration;

use clap::Parser;
use e2e_tests::relay::{Config, Faults, Relay};

#[derive(Parser, Debug)]
#[command(name = "relay", about = "Lossy UDP/TCP relay between a ground and an obsw (seeded)")]
struct Args {
    /// The obsw's UDP TC address.
    #[arg(long)]
    to_udp: SocketAddr,
    /// The obsw's TCP TC address [default: same as --to-udp].
    #[arg(long)]
    to_tcp: Option<SocketAddr>,
    /// Where grounds send UDP [default: a free loopback port].
    #[arg(long, default_value = "127.0.0.1:0")]
    udp: SocketAddr,
    /// Where grounds connect on TCP [default: a free loopback port].
    #[arg(long, default_value = "127.0.0.1:0")]
    tcp: SocketAddr,
    /// Probability of dropping a packet, both directions.
    #[arg(long, default_value_t = 0.0)]
    drop: f64,
    /// Probability of duplicating a packet, both directions.
    #[arg(long, default_value_t = 0.0)]
    duplicate: f64,
    /// Probability of flipping one bit of a packet, both directions.
    #[arg(long, default_value_t = 0.0)]
    corrupt: f64,
    /// Uplink (ground → obsw) only: overrides --drop/--duplicate/--corrupt as "D,U,C".
    #[arg(long)]
    up: Option<String>,
    /// Downlink (obsw → ground) only: "D,U,C".
    #[arg(long)]
    down: Option<String>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seconds until the relay stops in any case.
    #[arg(long, default_value_t = 600.0)]
    lifetime: f64,
    /// Seconds without traffic until the relay stops.
    #[arg(long, default_value_t = 60.0)]
    idle: f64,
    /// TM frames: the ground's address; the relay listens on --tm-frames-listen for the
    /// obsw's TM frames (its --frame-tm-to) and forwards them here with the downlink faults.
    #[arg(long)]
    tm_frames_to: Option<SocketAddr>,
    /// Where the relay takes the obsw's TM frames [default: a free loopback port].
    #[arg(long, default_value = "127.0.0.1:0")]
    tm_frames_listen: SocketAddr,
    /// Write one line per UDP datagram relayed to this file: `UNIX_US up|down LEN FATE
    /// HEAD` (FATE `drop`, or `o`/`x` per copy sent, intact/corrupted; HEAD the first 6
    /// bytes in hex).
    #[arg(long)]
    trace: Option<std::path::PathBuf>,
}

fn triple(s: &str) -> Result<Faults, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [d, u, c] => Ok(Faults::new(d, u, c)),
        _ => Err(format!("{s:?}: expected DROP,DUPLICATE,CORRUPT")),
    }
}

fn secs(name: &str, v: f64) -> Result<Duration, String> {
    Duration::try_from_secs_f64(v).map_err(|_| format!("--{name} {v}: must be a non-negative number of seconds"))
}

fn run(a: Args) -> Result<(), String> {
    let both = Faults::new(a.drop, a.duplicate, a.corrupt);
    let cfg = Config {
        listen_udp: a.udp,
        listen_tcp: a.tcp,
        target_udp: a.to_udp,
        target_tcp: a.to_tcp.unwrap_or(a.to_udp),
        up: a.up.as_deref().map(triple).transpose()?.unwrap_or(both),
        down: a.down.as_deref().map(triple).transpose()?.unwrap_or(both),
        seed: a.seed,
        lifetime: secs("lifetime", a.lifetime)?,
        idle: secs("idle", a.idle)?,
    };
    let mut relay = Relay::start(cfg)?;
    if let Some(path) = &a.trace {
        let f = std::fs::File::create(path).map_err(|e| format!("--trace {}: {e}", path.display()))?;
        relay.trace_to(f);
    }
    let frames = match a.tm_frames_to {
        Some(to) => format!(" tm_frames={}", relay.add_downlink_route(a.tm_frames_listen, to)?),
        None => String::new(),
    };
    println!("RELAY udp={} tcp={}{frames}", relay.udp, relay.tcp);
    while relay.running() {
        std::thread::sleep(Duration::from_millis(100));
    }
    relay.stop();
    println!("{}", relay.counts);
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("relay: error: {e}");
        std::process::exit(2);
    }
}
