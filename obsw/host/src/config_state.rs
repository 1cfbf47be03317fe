//! The host's store of the module configuration the ground accepted (docs/modules.md):
//! `--config-state FILE` holds [`AcceptedConfig::to_bytes`] (116 bytes: magic, hash, the
//! module identities by slot, CRC-32). Written like `--team-state`: a temporary file beside
//! it, synced, renamed over the old one, the directory synced, so a crash leaves either
//! the old or the new acceptance, never a torn one. Read at start: a missing, unreadable
//! or corrupt file means "nothing accepted" (logged, and event CONFIG_STATE_LOST once the
//! obsw has booted), never an error that stops the obsw.

use std::path::Path;

use obsw_core::obsw::Obsw;
use obsw_core::services::modules::{AcceptedConfig, StateLost};
use obsw_core::tm::{TmSink, TmStore};

/// Reads the accepted configuration: `Ok` with it, or why there is none (with a line
/// for the log).
pub fn load(p: &Path) -> Result<AcceptedConfig, (StateLost, String)> {
    let bytes = match std::fs::read(p) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err((
                StateLost::Missing,
                format!("--config-state {}: no file yet, no configuration accepted", p.display()),
            ))
        }
        Err(e) => {
            return Err((
                StateLost::Unreadable,
                format!("--config-state {}: {e}; no configuration accepted", p.display()),
            ))
        }
    };
    AcceptedConfig::from_bytes(&bytes).map_err(|e| {
        (
            StateLost::Corrupt,
            format!(
                "--config-state {}: corrupt ({e}); no configuration accepted",
                p.display()
            ),
        )
    })
}

/// Writes `a` durably (temporary file, sync, rename, directory sync).
pub fn store(p: &Path, a: &AcceptedConfig) -> std::io::Result<()> {
    crate::durable::replace(p, &a.to_bytes())
}

/// Persists an acceptance the obsw made since the last call (ACCEPT_CONFIG), if any. With
/// no state file the acceptance holds until the process ends. A failed write is logged and
/// raises CONFIG_STATE_LOST(WRITE_FAILED): the acceptance holds in memory until a restart.
pub fn persist<S: TmStore>(obsw: &mut Obsw<S>, path: Option<&Path>, now: u64, sink: &mut impl TmSink) {
    let Some(a) = obsw.take_accepted_update() else {
        return;
    };
    let Some(p) = path else { return };
    match store(p, &a) {
        Ok(()) => log::info!(
            "--config-state {}: configuration {:#010x} accepted and stored",
            p.display(),
            a.hash
        ),
        Err(e) => {
            log::error!(
                "--config-state {}: cannot store the accepted configuration {:#010x}: {e}",
                p.display(),
                a.hash
            );
            obsw.config_state_lost(now, StateLost::WriteFailed, sink);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modules::default_set;

    // verifies: MOD-PERSIST-01, MOD-PERSIST-03
    #[test]
    fn the_state_file_round_trips_and_missing_or_corrupt_is_nothing_accepted() {
        let dir = std::env::temp_dir().join(format!("obsw-config-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("config.state");
        let _ = std::fs::remove_file(&p);
        assert!(matches!(load(&p), Err((StateLost::Missing, _))));
        let a = AcceptedConfig::of(&default_set(1000));
        store(&p, &a).unwrap();
        assert_eq!(load(&p), Ok(a));
        assert!(!p.with_extension("tmp").exists(), "the temporary file was renamed");
        // A second acceptance replaces the first.
        let b = AcceptedConfig::of(&default_set(2000));
        store(&p, &b).unwrap();
        assert_eq!(load(&p), Ok(b));
        // Corrupt: one byte changed, truncated, garbage.
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[20] ^= 0x10;
        std::fs::write(&p, &bytes).unwrap();
        let e = load(&p).unwrap_err();
        assert_eq!(e.0, StateLost::Corrupt);
        assert!(e.1.contains("CRC") && e.1.contains("config.state"), "{}", e.1);
        std::fs::write(&p, &bytes[..50]).unwrap();
        assert_eq!(load(&p).unwrap_err().0, StateLost::Corrupt);
        std::fs::write(&p, "term 7\n").unwrap();
        assert_eq!(load(&p).unwrap_err().0, StateLost::Corrupt);
        // A directory where the file should be: unreadable.
        let d = dir.join("is-a-dir");
        std::fs::create_dir_all(&d).unwrap();
        assert_eq!(load(&d).unwrap_err().0, StateLost::Unreadable);
        // Storing into a missing directory fails (the caller logs it and raises the event).
        assert!(store(&dir.join("no/such/dir/config.state"), &a).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
