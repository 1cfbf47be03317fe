//! `FlatStore::replace`: a received file takes the place of the file under its name — in
//! one step on the flash store (`tests/flash.rs` cuts the power in it) and the host
//! directory (`rename(2)`), in two on a store that has only the trait's default.

use mmic_cfdp::flash::FlashStore;
use mmic_cfdp::store::{Checked, FlatStore, MemStore, StoreError};
use mmic_cfdp::FileName;

fn n(s: &str) -> FileName {
    FileName::new(s).unwrap()
}

fn put(s: &impl FlatStore, name: &str, data: &[u8]) {
    s.create(&n(name)).unwrap();
    s.write(&n(name), 0, data).unwrap();
}

fn get(s: &impl FlatStore, name: &str) -> Option<Vec<u8>> {
    let len = s.len(&n(name)).unwrap()? as usize;
    let mut v = vec![0; len];
    s.read(&n(name), 0, &mut v).unwrap();
    Some(v)
}

/// The same behaviour from every store.
fn replaces(s: &impl FlatStore) {
    put(s, "plan.toml", b"the old plan");
    put(s, "partial-0-3", b"the new plan, longer");
    s.replace(&n("partial-0-3"), &n("plan.toml")).unwrap();
    assert_eq!(get(s, "plan.toml").as_deref(), Some(&b"the new plan, longer"[..]));
    assert_eq!(get(s, "partial-0-3"), None);
    // No file under the target's name: a rename.
    s.replace(&n("plan.toml"), &n("plan-2.toml")).unwrap();
    assert_eq!(get(s, "plan-2.toml").as_deref(), Some(&b"the new plan, longer"[..]));
    assert_eq!(s.replace(&n("gone"), &n("plan-2.toml")), Err(StoreError::NotFound));
    assert!(get(s, "plan-2.toml").is_some(), "a refused replace changes nothing");
    s.replace(&n("plan-2.toml"), &n("plan-2.toml")).unwrap();
    assert!(get(s, "plan-2.toml").is_some(), "onto itself: nothing");
}

// verifies: FILE-STORE-09
#[test]
fn a_file_replaces_the_file_under_its_name_in_every_store() {
    std::thread::Builder::new()
        .stack_size(16 << 20)
        .spawn(|| {
            replaces(&MemStore::<8, 256>::new(10_000));
            let flash = Ram(vec![0xFF; 16 * 4096]);
            replaces(&FlashStore::open(flash, 0..16 * 4096).unwrap());
            #[cfg(feature = "std")]
            {
                let dir = std::env::temp_dir().join(format!("cfdp-replace-{}", std::process::id()));
                replaces(&mmic_cfdp::dir::DirStore::open(&dir, 1 << 20).unwrap());
                std::fs::remove_dir_all(&dir).unwrap();
            }
            // Through the checks: a refusal counted like any other.
            let c = Checked::new(MemStore::<8, 256>::new(10_000));
            assert_eq!(c.replace(&n("a"), &n("b")), Err(StoreError::NotFound));
        })
        .unwrap()
        .join()
        .unwrap();
}

/// A RAM NOR flash (reads and writes of words; a write only clears bits).
struct Ram(Vec<u8>);

#[derive(Debug)]
struct Refused;

impl embedded_storage::nor_flash::NorFlashError for Refused {
    fn kind(&self) -> embedded_storage::nor_flash::NorFlashErrorKind {
        embedded_storage::nor_flash::NorFlashErrorKind::Other
    }
}

impl embedded_storage::nor_flash::ErrorType for Ram {
    type Error = Refused;
}

impl embedded_storage::nor_flash::ReadNorFlash for Ram {
    const READ_SIZE: usize = 4;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Refused> {
        let o = offset as usize;
        bytes.copy_from_slice(self.0.get(o..o + bytes.len()).ok_or(Refused)?);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.0.len()
    }
}

impl embedded_storage::nor_flash::NorFlash for Ram {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 4096;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Refused> {
        self.0.get_mut(from as usize..to as usize).ok_or(Refused)?.fill(0xFF);
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Refused> {
        let o = offset as usize;
        let m = self.0.get_mut(o..o + bytes.len()).ok_or(Refused)?;
        if m.iter().zip(bytes).any(|(m, b)| b & !m != 0) {
            return Err(Refused);
        }
        m.copy_from_slice(bytes);
        Ok(())
    }
}

impl embedded_storage::nor_flash::MultiwriteNorFlash for Ram {}
