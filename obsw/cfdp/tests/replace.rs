//! `FlatStore::replace`: a received file takes the place of the file under its name — in
//! one step on the flash store (`tests/flash.rs` cuts the power in it) and the host
//! directory (`rename(2)`), in two on a store that has only the trait's default.

mod common;

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
            let flash = common::Nor::new(16 * common::SECTOR);
            replaces(&FlashStore::open(flash, 0..16 * common::SECTOR as u32).unwrap());
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
