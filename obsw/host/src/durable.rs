//! Durable replacement of a small state file: write a temporary file beside it, sync it,
//! rename it over the old one, sync the directory. A crash leaves the old file or the new
//! one, never a mix (used by `--config-state` and `--team-state`).

use std::fs::File;
use std::io::Write;
use std::path::Path;

/// Replaces `p` by `bytes` durably.
pub fn replace(p: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = p.with_extension("tmp");
    {
        let mut f = File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, p)?;
    let dir = p
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: MOD-PERSIST-01
    #[test]
    fn replace_writes_the_new_content_and_leaves_no_temporary_file() {
        let dir = std::env::temp_dir().join(format!("obsw-durable-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("state");
        replace(&p, b"one").unwrap();
        replace(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert!(!p.with_extension("tmp").exists());
        // A path in a missing directory is an error, not a panic.
        assert!(replace(&dir.join("missing/state"), b"x").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
