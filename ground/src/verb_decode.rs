//! `ground decode`: a file of TC and TM space packets, decoded with the MIB.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use ground::pus;

use crate::exit;
use crate::output::err_line;

#[derive(Args, Debug)]
pub(crate) struct DecodeArgs {
    /// File of concatenated space packets ("-" for standard input).
    file: PathBuf,
    /// One JSON object per line.
    #[arg(long)]
    json: bool,
    /// Only decode and count (no per-packet output).
    #[arg(long)]
    summary: bool,
    /// Exit with code 3 if any corrupt bytes were found.
    #[arg(long)]
    strict: bool,
}

pub(crate) fn decode(a: &DecodeArgs) -> Result<u8> {
    use ground::pus::out::{Format, RawItem, RawStream, Writer};
    let data = if a.file.as_os_str() == "-" {
        let mut v = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut v)?;
        v
    } else {
        std::fs::read(&a.file).with_context(|| format!("cannot read {}", a.file.display()))?
    };
    // Counters: packets by type, bodies that do not follow the MIB (undefined kind or
    // wrong structure), corrupt stretches.
    let (mut tc, mut tm, mut bad_body, mut stretches, mut corrupt_bytes) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let t0 = Instant::now();
    let mut o = std::io::stdout().lock();
    let mut w = Writer::new(if a.json { Format::Json } else { Format::Text });
    for item in RawStream::new(&data) {
        match &item {
            RawItem::Tm { offset, packet } => {
                tm += 1;
                if a.summary {
                    bad_body += u64::from(pus::decode_tm(&data[*offset..*offset + packet.primary.len]).is_err());
                } else {
                    bad_body += u64::from(w.tm(*offset, packet).is_err());
                }
            }
            RawItem::Tc { offset, packet } => {
                tc += 1;
                if a.summary {
                    bad_body += u64::from(pus::decode_tc(&data[*offset..*offset + packet.primary.len]).is_err());
                } else {
                    bad_body += u64::from(w.tc(*offset, packet).is_err());
                }
            }
            RawItem::Corrupt { offset, len, reason } => {
                stretches += 1;
                corrupt_bytes += *len as u64;
                if !a.summary {
                    w.corrupt(*offset, *len, reason);
                }
            }
        }
        w.flush_if_full(&mut o)?;
    }
    w.flush(&mut o)?;
    o.flush()?;
    drop(o);
    let secs = t0.elapsed().as_secs_f64();
    let n = tc + tm;
    err_line!(
        "{n} packets ({tc} TC, {tm} TM), {bad_body} with a body not matching the MIB, {stretches} corrupt stretches ({corrupt_bytes} bytes); {:.0} packets/s",
        if secs > 0.0 { n as f64 / secs } else { 0.0 }
    );
    Ok(if a.strict && (corrupt_bytes > 0 || bad_body > 0) {
        exit::INVALID
    } else {
        exit::OK
    })
}
