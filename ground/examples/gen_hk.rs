//! Writes a file of N TM[3,25] ROBOT_STATUS packets (robot 1, varying values) for the
//! decode benchmark, and prints the Python `struct` format of the HK source data so
//! that the Python side decodes the same structure.
//!
//! `cargo run --release -p ground --example gen_hk -- N FILE [START_MS]` (START_MS: Unix
//! time of the first packet, default 2026-01-01; packets are 100 ms apart).

use std::io::Write;

/// Raw value of parameter `id` in packet `i`: varying, and one of the MIB's named values
/// for enumerated parameters (so that decoders with enumerations, like XTCE, name them).
fn value(id: u16, i: usize) -> i64 {
    let v = (id as i64 * 131 + i as i64 * 7) % 4000;
    let names = mib::params::by_id(id).map_or(mib::layout::Names::None, |p| p.names());
    let mut named = Vec::new();
    names.for_each(|raw, _| named.push(raw));
    if named.is_empty() {
        v
    } else {
        named[v as usize % named.len()]
    }
}

fn main() -> anyhow::Result<()> {
    let mut a = std::env::args().skip(1);
    let n: usize = a.next().unwrap_or_else(|| "1000000".into()).parse()?;
    let path = a.next().unwrap_or_else(|| "hk.bin".into());
    let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).ok_or_else(|| anyhow::anyhow!("no ROBOT_STATUS"))?;
    let apid = mib::apid::robot_apid(1).ok_or_else(|| anyhow::anyhow!("no APID"))?;
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
    let mut src = [0u8; 512];
    let start_ms: i64 = match a.next() {
        Some(s) => s.parse()?,
        None => 1_767_225_600_000,
    };
    let t0 = ground::pus::CdsShort::from_unix_ms(start_ms);
    for i in 0..n {
        let len = mib_wire::codec::encode_hk(def, |id| value(id, i), &mut src)?;
        let t = ground::pus::CdsShort::from_unix_ms(t0.unix_ms() + i as i64 * 100).to_bytes();
        let p = ground::pus::build_tm(
            apid,
            mib::headers::SeqCount::new(i as u16).get(),
            3,
            25,
            i as u16,
            &t,
            &src[..len],
        );
        out.write_all(&p)?;
    }
    out.flush()?;
    let mut fmt = String::from(">H");
    for id in def.params {
        let p = mib::params::by_id(*id).ok_or_else(|| anyhow::anyhow!("param {id}"))?;
        fmt.push(match p.ptype {
            mib::PType::Bool | mib::PType::U8 => 'B',
            mib::PType::U16 => 'H',
            mib::PType::I16 => 'h',
            mib::PType::U32 => 'I',
            mib::PType::I32 => 'i',
        });
    }
    println!("{fmt}");
    Ok(())
}
