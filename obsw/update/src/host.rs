//! The host's slots: the otadata partition and the two application slots are files of one
//! folder, NOR flashes in files ([`FileFlash`]) of the board's sizes. The boot launcher
//! `obsw-boot` and the host obsw open the same folder through this one layout.

use std::path::{Path, PathBuf};

use mib::update::{ota, PUBLIC_KEY_LEN};

use crate::flash::FileFlash;
use crate::image::UpdateKey;

/// Size of each slot file (the board's application slot).
pub const SLOT_BYTES: u32 = mib::memory::OTA_0.size;

/// The files of a slots folder.
pub struct SlotFiles {
    pub dir: PathBuf,
    pub otadata: FileFlash,
    pub slots: [FileFlash; 2],
}

impl SlotFiles {
    /// Opens (and creates, erased) `dir/otadata`, `dir/ota_0` and `dir/ota_1`.
    pub fn open(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        Ok(SlotFiles {
            dir: dir.to_path_buf(),
            otadata: FileFlash::open(&dir.join("otadata"), ota::PARTITION_BYTES)?,
            slots: [
                FileFlash::open(&dir.join("ota_0"), SLOT_BYTES)?,
                FileFlash::open(&dir.join("ota_1"), SLOT_BYTES)?,
            ],
        })
    }
}

/// Reads an update public key file: 64 hexadecimal digits (the 32 bytes of an Ed25519
/// public key), surrounding white space ignored.
pub fn read_key(path: &Path) -> Result<UpdateKey, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bytes = hex32(text.trim()).ok_or_else(|| format!("{}: not 64 hexadecimal digits", path.display()))?;
    UpdateKey::from_bytes(&bytes).ok_or_else(|| format!("{}: not an Ed25519 public key", path.display()))
}

/// 64 hexadecimal digits as 32 bytes.
pub fn hex32(s: &str) -> Option<[u8; PUBLIC_KEY_LEN]> {
    if s.len() != 64 || !s.is_ascii() {
        return None;
    }
    let mut b = [0u8; 32];
    for (i, o) in b.iter_mut().enumerate() {
        *o = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(b)
}

/// A file as an image source.
pub struct FileSource {
    file: std::fs::File,
    len: u32,
}

impl FileSource {
    pub fn open(path: &Path) -> std::io::Result<Self> {
        let file = std::fs::File::open(path)?;
        let len = u32::try_from(file.metadata()?.len()).unwrap_or(u32::MAX);
        Ok(FileSource { file, len })
    }
}

impl crate::image::Source for FileSource {
    fn len(&self) -> u32 {
        self.len
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), crate::image::ReadError> {
        use std::os::unix::fs::FileExt;
        self.file
            .read_exact_at(buf, u64::from(offset))
            .map_err(|_| crate::image::ReadError)
    }
}
