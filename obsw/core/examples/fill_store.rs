//! Fills a host obsw's TM store file (`obsw --tm-store FILE`) with robot N's TM ending now:
//! housekeeping (TM[3,25] of the MIB's first structure, zeros after its SID) one a second,
//! every tenth packet a TM[17,2] instead (the report area), until `PACKETS` are stored. For
//! benches of a deep store: `TM_STORE=FILE ground/bench/lossy_link.sh ...` starts every run
//! from a copy of it, so each store retrieval has a full store behind it.
//!
//!   cargo run --release -p obsw-core --example fill_store -- FILE ROBOT PACKETS
//!
//! The file is written whole at the end (an existing one is replaced); the obsw that opens
//! it continues its sequence counts after the newest packet, as after a restart.
use std::cell::RefCell;
use std::time::{SystemTime, UNIX_EPOCH};

use mib::memory::store;
use obsw_core::flash_store::{Medium, MibFlashStore, Nor};
use obsw_core::time::OnboardTime;
use obsw_core::tm::{TmStore, TmWriter};

struct Ram(Vec<u8>);

impl Medium for Ram {
    type Error = String;
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), String> {
        let at = at as usize;
        out.copy_from_slice(self.0.get(at..at + out.len()).ok_or("read beyond the store")?);
        Ok(())
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), String> {
        let at = at as usize;
        self.0
            .get_mut(at..at + bytes.len())
            .ok_or("write beyond the store")?
            .copy_from_slice(bytes);
        Ok(())
    }
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, robot, packets] = args.as_slice() else {
        return Err("usage: fill_store FILE ROBOT PACKETS".into());
    };
    let robot: u8 = robot.parse().map_err(|e| format!("ROBOT {robot}: {e}"))?;
    let apid = mib::apid::robot_apid(robot).ok_or(format!("ROBOT {robot}: not 1..=254"))?;
    let packets: u64 = packets.parse().map_err(|e| format!("PACKETS {packets}: {e}"))?;
    let flash = RefCell::new(Nor::new(Ram(vec![0xFF; store::SIZE as usize]), store::SIZE));
    let mut st = MibFlashStore::open(&flash, 0).map_err(|e| format!("store: {e:?}"))?;
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_err(|e| e.to_string())?
        .as_millis() as u64;
    // One packet a second, the newest a second ago.
    let mut w = TmWriter::new(apid, OnboardTime::new(now - 1000 * packets));
    let hk = mib::hk::HK_STRUCTS.first().ok_or("the MIB has no HK structure")?;
    let mut data = vec![0u8; hk.data_len()];
    data[..2].copy_from_slice(&hk.sid.to_be_bytes());
    let mut buf = [0u8; mib::config::MAX_PACKET_LEN];
    let mut lost = 0u64;
    for k in 0..packets {
        let n = if k % 10 == 9 {
            w.build(1000 * k, 17, 2, &[], &mut buf)
        } else {
            w.build(1000 * k, 3, 25, &data, &mut buf)
        }
        .ok_or("a TM packet did not build")?;
        lost += u64::from(st.push(&buf[..n]));
    }
    let (hk_len, report_len) = st.lens();
    let bytes = flash.borrow().medium().0.clone();
    std::fs::write(file, bytes).map_err(|e| format!("{file}: {e}"))?;
    println!(
        "{file}: {packets} packets written (robot {robot}, APID {apid:#x}), {hk_len} HK and {report_len} others stored, {lost} overwritten"
    );
    Ok(())
}
