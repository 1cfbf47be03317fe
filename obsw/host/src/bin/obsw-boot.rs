//! `obsw-boot`: the host's stand-in for ESP-IDF's second-stage bootloader (docs/update.md).
//!
//! It reads the otadata of a slots folder with the robot's own code (`mmic_update::otadata`):
//! an image found PENDING_VERIFY (started once, never confirmed) is marked ABORTED and the
//! other slot chosen, one found NEW becomes PENDING_VERIFY; the chosen slot's image is
//! verified (header, SHA-256, Ed25519: the host's stand-in for secure boot), its payload —
//! the start file — written out and executed in place of this process, with the obsw's
//! arguments. The obsw resets by executing this launcher again.
//!
//! ```text
//! obsw-boot --slots DIR --update-key FILE [--init IMAGE] -- OBSW-ARGS...
//! ```
//! `--init IMAGE` writes IMAGE into slot 0 when slot 0 holds no verified image (what
//! `espflash` does for the board). Exit codes: 2 usage, 3 no bootable image.

use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::PathBuf;

use clap::Parser;
use mib::update::{target, HEADER_LEN};
use mmic_update::flash::Flash;
use mmic_update::host::{read_key, FileSource, SlotFiles};
use mmic_update::image;
use mmic_update::otadata;

#[derive(Parser, Debug)]
#[command(
    name = "obsw-boot",
    about = "Boot launcher of the host obsw: otadata, rollback, signed slots"
)]
struct Args {
    /// The slots folder: otadata, ota_0, ota_1 (created erased if missing).
    #[arg(long, value_name = "DIR")]
    slots: PathBuf,
    /// The ground's update public key (64 hexadecimal digits).
    #[arg(long, value_name = "FILE")]
    update_key: PathBuf,
    /// A signed image written into slot 0 when slot 0 holds no verified image.
    #[arg(long, value_name = "IMAGE")]
    init: Option<PathBuf>,
    /// The obsw's arguments.
    #[arg(last = true)]
    obsw_args: Vec<String>,
}

fn main() {
    let args = Args::parse();
    let code = match run(&args) {
        Ok(never) => match never {},
        Err(e) => {
            eprintln!("obsw-boot: error: {e}");
            3
        }
    };
    std::process::exit(code);
}

enum Never {}

fn run(a: &Args) -> Result<Never, String> {
    let key = read_key(&a.update_key)?;
    let mut f = SlotFiles::open(&a.slots).map_err(|e| format!("--slots {}: {e}", a.slots.display()))?;
    if let Some(init) = &a.init {
        if image::verify_slot(&mut f.slots[0], &key, target::HOST).is_err() {
            let mut src = FileSource::open(init).map_err(|e| format!("--init {}: {e}", init.display()))?;
            let h = image::install(&mut src, &mut f.slots[0], &key, target::HOST)
                .map_err(|e| format!("--init {}: {e}", init.display()))?;
            eprintln!(
                "obsw-boot: slot 0 written from {} (version {:06x})",
                init.display(),
                h.version
            );
        }
    }
    let boot = otadata::boot(&mut f.otadata).map_err(|e| format!("{}/otadata: {e}", a.slots.display()))?;
    if let Some(s) = boot.aborted {
        eprintln!("obsw-boot: slot {s} was never confirmed: ABORTED, rolling back");
    }
    let slot = usize::from(boot.slot);
    let h = image::verify_slot(&mut f.slots[slot], &key, target::HOST)
        .map_err(|e| format!("slot {slot} ({}/ota_{slot}): {e}", a.slots.display()))?;
    eprintln!(
        "obsw-boot: booting slot {slot}, version {:06x}, otadata state {:?}",
        h.version, boot.state
    );
    // The start file: the payload, written beside and renamed into place, executable.
    let mut payload = vec![0u8; h.length as usize];
    f.slots[slot]
        .read(HEADER_LEN as u32, &mut payload)
        .map_err(|e| format!("slot {slot}: {e}"))?;
    let run = a.slots.join(format!("run-{slot}"));
    let tmp = a.slots.join(format!(".run-{slot}.new"));
    std::fs::write(&tmp, &payload).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o755))
        .map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, &run).map_err(|e| format!("{}: {e}", run.display()))?;
    drop(f);
    let me = std::env::current_exe().map_err(|e| format!("own path: {e}"))?;
    let own_args: Vec<String> = std::env::args().skip(1).collect();
    let e = std::process::Command::new(&run)
        .args(&a.obsw_args)
        .env("OBSW_SLOTS", &a.slots)
        .env("OBSW_UPDATE_KEY", &a.update_key)
        .env("OBSW_BOOT", &me)
        .env("OBSW_BOOT_ARGS", own_args.join("\u{1f}"))
        .exec();
    Err(format!("exec {}: {e}", run.display()))
}
