//! The file store in a host directory (the host obsw's `--files DIR`, the ground's local
//! folder): one regular file per name, nothing else in the directory is seen (names that
//! fail the store's checks are skipped in listings). Free space is the store's capacity less
//! the bytes of its files, so the host behaves like the board's fixed flash area.

use std::fs::{self, File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::store::{FileName, FlatStore, StoreError};

/// A directory as a flat store of `capacity` bytes.
pub struct DirStore {
    dir: PathBuf,
    capacity: u64,
}

impl DirStore {
    /// The store in `dir` (created if missing).
    pub fn open(dir: &Path, capacity: u64) -> std::io::Result<DirStore> {
        fs::create_dir_all(dir)?;
        Ok(DirStore {
            dir: dir.to_path_buf(),
            capacity,
        })
    }

    pub fn path(&self, name: &FileName) -> PathBuf {
        // A FileName has no separator, no "..", no leading '.': it stays inside `dir`.
        self.dir.join(name.as_str())
    }
}

fn io(e: std::io::Error) -> StoreError {
    match e.kind() {
        std::io::ErrorKind::NotFound => StoreError::NotFound,
        std::io::ErrorKind::AlreadyExists => StoreError::Exists,
        _ => StoreError::Io,
    }
}

impl FlatStore for DirStore {
    fn len(&self, name: &FileName) -> Result<Option<u64>, StoreError> {
        match fs::symlink_metadata(self.path(name)) {
            Ok(m) if m.is_file() => Ok(Some(m.len())),
            // A directory or a symbolic link under a valid name is not a file of the store.
            Ok(_) => Err(StoreError::Io),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io(e)),
        }
    }

    fn create(&self, name: &FileName) -> Result<(), StoreError> {
        File::create(self.path(name)).map(|_| ()).map_err(io)
    }

    fn read(&self, name: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        let mut f = File::open(self.path(name)).map_err(io)?;
        f.seek(SeekFrom::Start(offset)).map_err(io)?;
        f.read_exact(buf).map_err(io)
    }

    fn write(&self, name: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        let mut f = OpenOptions::new().write(true).open(self.path(name)).map_err(io)?;
        f.seek(SeekFrom::Start(offset)).map_err(io)?;
        f.write_all(data).map_err(io)
    }

    fn remove(&self, name: &FileName) -> Result<(), StoreError> {
        self.len(name)?.ok_or(StoreError::NotFound)?;
        fs::remove_file(self.path(name)).map_err(io)
    }

    fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.len(from)?.ok_or(StoreError::NotFound)?;
        if self.len(to)?.is_some() {
            return Err(StoreError::Exists);
        }
        fs::rename(self.path(from), self.path(to)).map_err(io)
    }

    /// `rename(2)` replaces the target in one step.
    fn replace(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.len(from)?.ok_or(StoreError::NotFound)?;
        if from == to {
            return Ok(());
        }
        // A directory or link under the target's name is not a file of the store.
        self.len(to)?;
        fs::rename(self.path(from), self.path(to)).map_err(io)
    }

    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError> {
        let mut files = Vec::new();
        for e in fs::read_dir(&self.dir).map_err(io)? {
            let e = e.map_err(io)?;
            let Some(n) = e.file_name().to_str().and_then(|s| FileName::new(s).ok()) else {
                continue;
            };
            if let Ok(m) = fs::symlink_metadata(e.path()) {
                if m.is_file() {
                    files.push((n, m.len()));
                }
            }
        }
        files.sort();
        for (n, l) in &files {
            f(n, *l);
        }
        Ok(())
    }

    fn free(&self) -> Result<u64, StoreError> {
        let mut used = 0;
        self.list(&mut |_, l| used += l)?;
        Ok(self.capacity.saturating_sub(used))
    }
}
