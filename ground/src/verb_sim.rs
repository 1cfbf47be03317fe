//! `ground sim`: one line to a simulator's control port, its reply for the operator.

use std::net::SocketAddr;
use std::time::Duration;

use anyhow::Result;
use ground::ops;

use crate::exit::{self, coded};
use crate::output::out;
use clap::Args;

/// Sends one line to a simulator control port and returns the reply.
pub(crate) fn sim_command(addr: SocketAddr, line: &str, timeout: Duration) -> Result<String> {
    let sock = std::net::UdpSocket::bind((std::net::Ipv4Addr::LOCALHOST, 0))?;
    sock.connect(addr)?;
    sock.set_read_timeout(Some(timeout))?;
    let mut buf = [0u8; 2048];
    for _ in 0..3 {
        sock.send(format!("{line}\n").as_bytes())?;
        match sock.recv(&mut buf) {
            Ok(n) => return Ok(String::from_utf8_lossy(&buf[..n]).trim().to_string()),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {
                return Err(coded(
                    exit::NO_ANSWER,
                    format!("no simulator at {addr} (connection refused)"),
                ))
            }
            Err(e) => return Err(e.into()),
        }
    }
    Err(coded(exit::NO_ANSWER, format!("no reply from the simulator at {addr}")))
}

/// Simulator control address of robot `n`.
pub(crate) fn sim_addr(n: u8) -> SocketAddr {
    (
        std::net::Ipv4Addr::LOCALHOST,
        mib::host_config::SIM_CTL_BASE_PORT + n as u16,
    )
        .into()
}

pub(crate) fn sim(a: &SimArgs) -> Result<u8> {
    let (addr, who) = match (a.addr, a.robot) {
        (Some(addr), Some(r)) => (addr, format!("robot {r} (simulator at {addr})")),
        (Some(addr), None) => (addr, format!("simulator at {addr}")),
        (None, Some(r)) => (sim_addr(r), format!("robot {r}")),
        (None, None) => return Err(coded(exit::USAGE, "give --robot N or --addr HOST:PORT")),
    };
    let line = a.line.join(" ");
    let reply = sim_command(addr, &line, Duration::from_millis(500))?;
    let ok = reply.starts_with("ok");
    for (i, l) in sim_reply_lines(&line, &reply).iter().enumerate() {
        if i == 0 {
            out(&format!("{who}: {l}"))?;
        } else {
            out(l)?;
        }
    }
    Ok(if ok { exit::OK } else { exit::FAILED })
}

/// Faults `clear NAME` removes (the simulator's fault names).
pub(crate) const SIM_FAULTS: &[&str] = &[
    "stuck-arm",
    "obstacle",
    "battery-sag",
    "dead-hip-encoder",
    "cut-cable",
    "misplaced-voxel",
    "fastener-jam",
];

/// The simulator's reply for the operator: `status` (a structure) as one `name: value`
/// line per field, a `clear` of something that is not a fault said as such.
pub(crate) fn sim_reply_lines(line: &str, reply: &str) -> Vec<String> {
    let mut words = line.split_whitespace();
    let cmd = words.next().unwrap_or("").to_ascii_lowercase();
    let arg = words.next();
    if let (true, Some(x), false) = (cmd == "clear", arg, reply.starts_with("ok")) {
        if !SIM_FAULTS.iter().any(|f| f.eq_ignore_ascii_case(x)) {
            let hint = if x.starts_with("link-") {
                format!(" (end {x} with `{x} 0`)")
            } else {
                ops::policy::suggest(x, SIM_FAULTS.iter().copied())
                    .map_or(String::new(), |s| format!(" — did you mean {s}?"))
            };
            return vec![format!(
                "error: '{x}' is not a fault; `clear` takes one of {}{hint}",
                SIM_FAULTS.join(", ")
            )];
        }
    }
    match reply.strip_prefix("ok ") {
        Some(body) if cmd == "status" && body.contains('{') => {
            let mut v = vec!["ok".to_string()];
            v.extend(
                debug_fields(body)
                    .into_iter()
                    .map(|(depth, t)| format!("{}{}", "  ".repeat(depth + 1), unwrap_some(&t))),
            );
            v
        }
        _ => vec![reply.to_string()],
    }
}

/// `Some(x)` written as `x`, `None` as `-` (Rust's optional values, for the operator).
pub(crate) fn unwrap_some(t: &str) -> String {
    let mut out = String::with_capacity(t.len());
    let mut open = Vec::new(); // per '(': whether it belonged to a Some
    let mut rest = t;
    while let Some(c) = rest.chars().next() {
        if let Some(r) = rest.strip_prefix("Some(") {
            open.push(true);
            rest = r;
            continue;
        }
        if let Some(r) = rest.strip_prefix("None") {
            if !r.starts_with(|c: char| c.is_alphanumeric() || c == '_') {
                out.push('-');
                rest = r;
                continue;
            }
        }
        match c {
            '(' => {
                open.push(false);
                out.push(c);
            }
            ')' => {
                if !open.pop().unwrap_or(false) {
                    out.push(c);
                }
            }
            c => out.push(c),
        }
        rest = &rest[c.len_utf8()..];
    }
    out
}

/// Splits a `Name { a: 1, b: Inner { c: 2 } }` structure into indented `a: 1` lines.
pub(crate) fn debug_fields(s: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let (mut depth, mut nest, mut cur) = (0usize, 0usize, String::new());
    let flush = |cur: &mut String, depth: usize, out: &mut Vec<(usize, String)>| {
        let t = cur.trim().trim_end_matches(',').trim().to_string();
        if !t.is_empty() {
            out.push((depth.saturating_sub(1), t));
        }
        cur.clear();
    };
    for ch in s.chars() {
        match ch {
            '[' | '(' => {
                nest += 1;
                cur.push(ch);
            }
            ']' | ')' => {
                nest = nest.saturating_sub(1);
                cur.push(ch);
            }
            '{' if nest == 0 => {
                // "field: Type {" -> "field:" heads a nested block; the top type name goes.
                let head = cur.trim().to_string();
                let name = head.rsplit_once(' ').map_or(head.as_str(), |(f, _)| f).to_string();
                cur.clear();
                if depth > 0 {
                    out.push((depth - 1, name));
                }
                depth += 1;
            }
            '}' if nest == 0 => {
                flush(&mut cur, depth, &mut out);
                depth = depth.saturating_sub(1);
            }
            ',' if nest == 0 => flush(&mut cur, depth, &mut out),
            c => cur.push(c),
        }
    }
    flush(&mut cur, depth, &mut out);
    out
}

#[derive(Args, Debug)]
pub(crate) struct SimArgs {
    /// Robot number (control port 127.0.0.1:7400+N unless --addr).
    #[arg(long, short = 'r', required_unless_present = "addr")]
    robot: Option<u8>,
    /// Simulator control address.
    #[arg(long)]
    addr: Option<SocketAddr>,
    /// The command, e.g. `stuck-arm a`, `battery-sag 9.5`, `clear`.
    #[arg(required = true, num_args = 1..)]
    line: Vec<String>,
}
