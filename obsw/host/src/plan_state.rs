//! The host's store of the on-board plan (`--plan-state FILE`): the loaded image and how
//! far it got, so that a plan survives a restart of the obsw and its step in flight is
//! never run twice by itself (a plan that was running comes back suspended, cause
//! RESTART; the ground resumes or skips).
//!
//! File: `version 1 | state u8 | done u8 | image | CRC-32 of everything before`, written
//! like `--team-state` (temporary file, sync, rename, directory sync) after every control
//! period or TC that changed the plan's progress. Missing: no plan. Unreadable or corrupt:
//! no plan, logged.

use std::path::Path;

use mmic_plan::exec::Progress;
use mmic_plan::image::crc32;
use mmic_plan::State;
use obsw_core::obsw::Obsw;
use obsw_core::tm::{TmSink, TmStore};

const VERSION: u8 = 1;

fn encode(image: &[u8], p: Progress) -> Vec<u8> {
    let mut b = vec![VERSION, p.state.code(), p.done];
    b.extend_from_slice(image);
    let crc = crc32(&b);
    b.extend_from_slice(&crc.to_be_bytes());
    b
}

fn decode(b: &[u8]) -> Option<(&[u8], Progress)> {
    let (body, crc) = b.split_at_checked(b.len().checked_sub(4)?)?;
    if crc32(body).to_be_bytes() != crc || body.len() < 3 || body[0] != VERSION {
        return None;
    }
    let state = State::from_code(body[1])?;
    Some((
        &body[3..],
        Progress {
            state,
            next: body[2],
            done: body[2],
        },
    ))
}

/// Restores the plan stored in `p` at start (nothing when there is none).
pub fn restore<S: TmStore>(obsw: &mut Obsw<S>, p: &Path, sink: &mut impl TmSink) {
    let bytes = match std::fs::read(p) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return,
        Err(e) => return eprintln!("obsw: --plan-state {}: {e}; no plan restored", p.display()),
    };
    match decode(&bytes) {
        Some((image, progress)) if obsw.plan_restore(0, image, progress, sink) => eprintln!(
            "obsw: --plan-state {}: plan restored ({:?}, {} steps done)",
            p.display(),
            progress.state,
            progress.done
        ),
        _ => eprintln!(
            "obsw: --plan-state {}: corrupt or not this robot's; no plan restored",
            p.display()
        ),
    }
}

/// Stores the plan's progress if it changed since the last call.
pub fn persist<S: TmStore>(obsw: &mut Obsw<S>, p: Option<&Path>) {
    let Some(p) = p else { return };
    let Some((image, progress)) = obsw.plan.plan.take_record() else {
        return;
    };
    if let Err(e) = crate::durable::replace(p, &encode(image, progress)) {
        log::warn!("--plan-state {}: {e}; the plan's progress is not stored", p.display());
        eprintln!(
            "obsw: --plan-state {}: {e}; the plan's progress is not stored",
            p.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: PLAN-EXEC-03
    #[test]
    fn a_stored_plan_reads_back_and_a_flipped_bit_reads_as_none() {
        let p = Progress {
            state: State::Running,
            next: 2,
            done: 2,
        };
        let b = encode(&[1, 2, 3], p);
        assert_eq!(decode(&b), Some((&[1u8, 2, 3][..], p)));
        for i in 0..b.len() * 8 {
            let mut c = b.clone();
            c[i / 8] ^= 1 << (i % 8);
            assert_eq!(decode(&c), None, "bit {i}");
        }
        assert_eq!(decode(&[]), None);
    }
}
