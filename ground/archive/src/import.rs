//! `ground archive import FILE --robot N`: a raw packet stream (a capture, a store dump)
//! into the archive. The file is split and decoded on this thread while the writer
//! thread stores, so both cores work; packets already archived are counted, not stored.

use std::path::Path;

use serde::Serialize;

use super::{now_ms, Archive, ArchiveError, ArchiveStats, Record};
use ground_pus::{self as pus, Packet, StreamItem};

/// What an import did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ImportReport {
    pub bytes: u64,
    /// TM packets in the file.
    pub tm: u64,
    /// TC packets in the file (not archived: TCs are archived when sent).
    pub tc_skipped: u64,
    /// TM whose APID belongs to another robot than `--robot` (archived under theirs).
    pub other_robot: u64,
    pub corrupt_stretches: u64,
    pub corrupt_bytes: u64,
    pub archive: ArchiveStats,
    pub seconds: f64,
}

/// Imports `file` into the archive at `archive` (a path or URL).
pub fn import(archive: &Path, file: &Path, robot: u8) -> Result<ImportReport, ArchiveError> {
    let buf = std::fs::read(file)?;
    let start = std::time::Instant::now();
    let a = Archive::open_with(archive, Some(4 * super::BATCH_MAX))?;
    let tx = a.sender();
    let mut rep = ImportReport {
        bytes: buf.len() as u64,
        ..Default::default()
    };
    let t_ms = now_ms();
    let mut writer_gone = false;
    for item in pus::StreamDecoder::new(&buf) {
        match item {
            StreamItem::Packet {
                offset,
                packet: Packet::Tm(tm),
            } => {
                rep.tm += 1;
                if tm.robot.is_some_and(|r| r != robot) {
                    rep.other_robot += 1;
                }
                let raw = buf[offset..offset + tm.len].to_vec();
                if !tx.send(Record::Tm {
                    t_ms,
                    link_robot: Some(robot),
                    raw,
                    decoded: Ok(tm),
                }) {
                    writer_gone = true;
                    break;
                }
            }
            StreamItem::Packet {
                packet: Packet::Tc(_), ..
            } => rep.tc_skipped += 1,
            StreamItem::Corrupt { offset, len, reason } => {
                rep.corrupt_stretches += 1;
                rep.corrupt_bytes += len as u64;
                if !tx.send(Record::Tm {
                    t_ms,
                    link_robot: Some(robot),
                    raw: buf[offset..offset + len].to_vec(),
                    decoded: Err(reason),
                }) {
                    writer_gone = true;
                    break;
                }
            }
        }
    }
    drop(tx);
    let stats = a.close();
    if writer_gone && stats.is_ok() {
        return Err(ArchiveError::WriterGone);
    }
    rep.archive = stats?;
    rep.seconds = start.elapsed().as_secs_f64();
    Ok(rep)
}
