//! The host obsw's part of software update (docs/update.md): its slots are the files of the
//! boot launcher's folder (`mmic_update::host`), its images come from the file store
//! (`--files DIR`), its update key from `--update-key`. A reset is an `exec` of the launcher,
//! which reads otadata again, as board A's bootloader does after a reset.
//!
//! Interface: [`attach`] gives the obsw's update component these slots (`Slots`); the main
//! loop calls [`reset_if_requested`] after each batch of inputs and each period.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use mib::update::target;
use mmic_update::flash::Flash;
use mmic_update::host::{read_key, FileSource, SlotFiles};
use mmic_update::image::{self, Header, Refusal, UpdateKey};
use obsw_core::services::update::Slots;

/// Environment the launcher gives the obsw (besides `OBSW_SLOTS` and `OBSW_UPDATE_KEY`,
/// read as `--slots` and `--update-key`): how to start the launcher again, its path, then
/// its arguments separated by U+001F.
pub const ENV_BOOT: &str = "OBSW_BOOT";
pub const ENV_BOOT_ARGS: &str = "OBSW_BOOT_ARGS";
/// Fault injection for the tests: an image whose start file sets it fails its self-test.
pub const ENV_SELF_TEST_FAIL: &str = "OBSW_SELF_TEST_FAIL";
/// Self-test check code of the host: the fault injected by [`ENV_SELF_TEST_FAIL`].
pub const CHECK_INJECTED: u8 = 2;
/// Self-test check code of the host: the file store folder is missing.
pub const CHECK_FILE_STORE: u8 = 3;

/// How long the obsw keeps sending before a reset: the activation's reports and the CLCW
/// that acknowledges its frame leave in the TM frames of this time.
pub const RESET_DELAY: std::time::Duration = std::time::Duration::from_millis(200);

/// The host's slots and file store.
pub struct HostSlots {
    files: SlotFiles,
    store: Option<PathBuf>,
    key: Option<UpdateKey>,
}

impl Slots for HostSlots {
    fn target(&self) -> u8 {
        target::HOST
    }
    fn key(&self) -> Option<UpdateKey> {
        self.key
    }
    fn otadata(&mut self) -> &mut dyn Flash {
        &mut self.files.otadata
    }
    fn slot(&mut self, n: u8) -> &mut dyn Flash {
        &mut self.files.slots[usize::from(n.min(1))]
    }
    fn install(&mut self, name: &[u8], n: u8, key: &UpdateKey) -> Result<Header, Refusal> {
        // Only a checked store name reaches the file system (no path, no "..").
        let name = std::str::from_utf8(name).map_err(|_| Refusal::NoFile)?;
        let name = mmic_cfdp::FileName::new(name).map_err(|_| Refusal::NoFile)?;
        let store = self.store.as_ref().ok_or(Refusal::NoFile)?;
        let path = store.join(name.as_str());
        if !std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
            return Err(Refusal::NoFile);
        }
        let mut src = FileSource::open(&path).map_err(|_| Refusal::NoFile)?;
        image::install(
            &mut src,
            &mut self.files.slots[usize::from(n.min(1))],
            key,
            target::HOST,
        )
    }
    fn self_test(&mut self) -> Result<(), u8> {
        if std::env::var_os(ENV_SELF_TEST_FAIL).is_some() {
            return Err(CHECK_INJECTED);
        }
        if self.store.as_ref().is_some_and(|d| !d.is_dir()) {
            return Err(CHECK_FILE_STORE);
        }
        Ok(())
    }
}

/// The slots the launcher named, if the obsw was started by it (`None`: no update service).
pub fn attach(
    slots: Option<&Path>,
    key: Option<&Path>,
    store: Option<&Path>,
) -> Result<Option<&'static mut HostSlots>> {
    let Some(dir) = slots else { return Ok(None) };
    let files = SlotFiles::open(dir).with_context(|| format!("--slots {}", dir.display()))?;
    let key = match key {
        Some(p) => Some(read_key(p).map_err(anyhow::Error::msg).context("--update-key")?),
        None => None,
    };
    Ok(Some(Box::leak(Box::new(HostSlots {
        files,
        store: store.map(Path::to_path_buf),
        key,
    }))))
}

/// After an activation or a failed self-test: the launcher again, in this process (the
/// same process ID; every socket closes on exec). Returns only if the exec failed.
pub fn reset() -> anyhow::Error {
    use std::os::unix::process::CommandExt;
    let Some(boot) = std::env::var_os(ENV_BOOT) else {
        return anyhow::anyhow!("reset requested but {ENV_BOOT} is not set (not started by obsw-boot)");
    };
    let args: Vec<String> = std::env::var(ENV_BOOT_ARGS)
        .unwrap_or_default()
        .split('\u{1f}')
        .filter(|a| !a.is_empty())
        .map(str::to_string)
        .collect();
    eprintln!("obsw: reset: starting the boot launcher again");
    let e = std::process::Command::new(&boot).args(&args).exec();
    anyhow::anyhow!("exec {}: {e}", Path::new(&boot).display())
}
