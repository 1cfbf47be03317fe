//! The host's flash for the PUS 15 store: a file the size of the store partition
//! (`mib::memory::store::SIZE`) under the NOR rules of `obsw_core::flash_store::Nor` —
//! the same rules the QEMU board's flash file follows. The store's code is the flight
//! code (`obsw_core::flash_store`); only this I/O is the host's.
//! Writes go to the file at once, so a killed process loses nothing written; a host
//! power cut may lose what the kernel had not written back yet.

use std::fs::{File, OpenOptions};
use std::os::unix::fs::FileExt;
use std::path::Path;

use anyhow::{bail, Context, Result};
use mib::memory::store;
use obsw_core::flash_store::{Medium, Nor};

/// The store's flash: the NOR rules of `obsw_core::flash_store` over the host's bytes.
pub type HostFlash = Nor<HostMedium>;

/// Where the bytes are: a file, or memory when no store file is configured.
pub enum HostMedium {
    File(File),
    Memory(Vec<u8>),
}

const SIZE: usize = store::SIZE as usize;

/// Opens the store file at `path`, creating it erased (all 0xFF) if missing. A file of
/// another size is refused (it is not this store).
pub fn open(path: &Path) -> Result<HostFlash> {
    let f = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .with_context(|| format!("--tm-store {}", path.display()))?;
    let len = f.metadata()?.len();
    if len == 0 {
        f.write_all_at(&vec![0xFF; SIZE], 0)?;
        f.sync_all()?;
    } else if len != SIZE as u64 {
        bail!("--tm-store {}: {len} bytes, a store file has {SIZE}", path.display());
    }
    Ok(Nor::new(HostMedium::File(f), store::SIZE))
}

/// A store in memory, erased: lost when the process ends.
pub fn memory() -> HostFlash {
    Nor::new(HostMedium::Memory(vec![0xFF; SIZE]), store::SIZE)
}

impl Medium for HostMedium {
    type Error = std::io::ErrorKind;
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), Self::Error> {
        let at = at as usize;
        match self {
            HostMedium::File(f) => f.read_exact_at(out, at as u64).map_err(|e| e.kind()),
            HostMedium::Memory(m) => {
                out.copy_from_slice(m.get(at..at + out.len()).ok_or(std::io::ErrorKind::UnexpectedEof)?);
                Ok(())
            }
        }
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = at as usize;
        match self {
            HostMedium::File(f) => f.write_all_at(bytes, at as u64).map_err(|e| e.kind()),
            HostMedium::Memory(m) => {
                m.get_mut(at..at + bytes.len())
                    .ok_or(std::io::ErrorKind::UnexpectedEof)?
                    .copy_from_slice(bytes);
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};
    use obsw_core::flash_store::NorError;

    fn temp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("obsw-store-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: PUS-15-05
    #[test]
    fn the_store_file_keeps_the_nor_flash_it_holds() {
        let p = temp("nor");
        let mut f = open(&p).unwrap();
        assert_eq!(
            std::fs::metadata(&p).unwrap().len(),
            SIZE as u64,
            "created erased, full size"
        );
        let mut b = [0u8; 8];
        f.read(4096, &mut b).unwrap();
        assert_eq!(b, [0xFF; 8]);
        f.write(4096, &[0xF0, 0x0F, 0xFF, 0x00]).unwrap();
        // Clearing more bits of the same word is allowed; setting one is not.
        f.write(4096, &[0x00, 0x0F, 0xFF, 0x00]).unwrap();
        assert!(matches!(
            f.write(4096, &[0x01, 0x0F, 0xFF, 0x00]),
            Err(NorError::SetsBits)
        ));
        assert!(matches!(f.write(4097, &[0; 4]), Err(NorError::NotAligned)));
        assert!(matches!(f.write(SIZE as u32, &[0; 4]), Err(NorError::OutOfBounds)));
        drop(f);
        let mut f = open(&p).unwrap();
        f.read(4096, &mut b[..4]).unwrap();
        assert_eq!(b[..4], [0x00, 0x0F, 0xFF, 0x00], "kept in the file");
        f.erase(4096, 8192).unwrap();
        f.read(4096, &mut b[..4]).unwrap();
        assert_eq!(b[..4], [0xFF; 4], "an erase sets the sector");
        assert!(matches!(f.erase(100, 4096), Err(NorError::NotAligned)));
        std::fs::write(&p, b"short").unwrap();
        assert!(open(&p).is_err(), "a file of another size is refused");
        let _ = std::fs::remove_file(&p);
    }
}
