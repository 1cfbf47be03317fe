//! Key directories: one per robot link, raw 32-byte key files (the format Yamcs'
//! `SecurityAssociationAes256Gcm128Factory` reads with `keyFile`), mode 0600, made from
//! the operating system's random number generator. Keys are never printed: [`describe`]
//! gives the SPI and a fingerprint (the first 8 hex digits of the key's SHA-256).
//!
//! ```text
//! DIR/robot-N/tc-spi1.key    TC (ground → robot), SPI 1 (in use)
//! DIR/robot-N/tc-spi2.key    TC, SPI 2 (spare, for a key change)
//! DIR/robot-N/tm-spi17.key   TM (robot → ground), SPI 17 (in use)
//! DIR/robot-N/tm-spi18.key   TM, SPI 18 (spare)
//! DIR/robot-N/ground-link.state   the ground's SDLS counters for this link
//! ```
//!
//! One directory per robot: two robots under one TC key would each count their IVs from
//! the same start — a GCM nonce reused under one key.

use std::path::{Path, PathBuf};

use ground_link::{create_key_file, Key};
use mib::link::sdls::{TC_SPIS, TM_SPIS};

use sha2::{Digest, Sha256};

/// A robot link's key directory inside a key directory.
pub fn robot_dir(base: &Path, robot: u8) -> PathBuf {
    base.join(format!("robot-{robot}"))
}

/// File name of the key of `spi` (TC SPIs `tc-spiN.key`, TM SPIs `tm-spiN.key`).
pub fn key_file_name(spi: u16) -> String {
    if TM_SPIS.contains(&spi) {
        format!("tm-spi{spi}.key")
    } else {
        format!("tc-spi{spi}.key")
    }
}

/// The TC key in use (SPI 1) of a robot's key directory.
pub fn tc_key_path(robot_dir: &Path) -> PathBuf {
    robot_dir.join(key_file_name(TC_SPIS[0]))
}

/// The TM key in use (SPI 17).
pub fn tm_key_path(robot_dir: &Path) -> PathBuf {
    robot_dir.join(key_file_name(TM_SPIS[0]))
}

/// The team key of a key directory: one key for all robots of a team
/// (`obsw --team-key`, docs/team.md), never a link key.
pub fn team_key_path(base: &Path) -> PathBuf {
    base.join(TEAM_KEY_FILE)
}

/// File name of the team key.
pub const TEAM_KEY_FILE: &str = "team.key";

/// The ground's SDLS counter state file of a robot link.
pub fn ground_state_path(robot_dir: &Path) -> PathBuf {
    robot_dir.join("ground-link.state")
}

/// What went wrong making keys.
#[derive(Debug)]
#[non_exhaustive]
pub enum KeyError {
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    /// Writing a key file (exists already, I/O).
    Persist(String),
    /// The operating system's random number generator failed.
    Random(getrandom::Error),
}

impl std::fmt::Display for KeyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            KeyError::Io { path, error } => write!(f, "{}: {error}", path.display()),
            KeyError::Persist(e) => write!(f, "{e}"),
            KeyError::Random(e) => write!(f, "random number generator: {e}"),
        }
    }
}

impl std::error::Error for KeyError {}

/// A fresh random key from the operating system.
pub fn random_key() -> Result<Key, KeyError> {
    let mut k = [0u8; 32];
    getrandom::fill(&mut k).map_err(KeyError::Random)?;
    Ok(k)
}

/// Creates `DIR/robot-N/` with a random key per SPI (TC 1, 2; TM 17, 18), mode 0600 files
/// in a 0700 directory. Refuses to overwrite an existing key file. Returns the files made.
pub fn create_robot_keys(base: &Path, robot: u8) -> Result<Vec<PathBuf>, KeyError> {
    let dir = robot_dir(base, robot);
    let mut b = std::fs::DirBuilder::new();
    b.recursive(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::DirBuilderExt;
        b.mode(0o700);
    }
    b.create(&dir).map_err(|error| KeyError::Io {
        path: dir.clone(),
        error,
    })?;
    let mut made = Vec::new();
    for spi in TC_SPIS.into_iter().chain(TM_SPIS) {
        let p = dir.join(key_file_name(spi));
        create_key_file(&p, &random_key()?).map_err(|e| KeyError::Persist(e.to_string()))?;
        made.push(p);
    }
    Ok(made)
}

/// Creates `DIR/team.key`: a random key, mode 0600, in a 0700 directory. Refuses to
/// overwrite an existing one. Returns the file made.
pub fn create_team_key(base: &Path) -> Result<PathBuf, KeyError> {
    let mut b = std::fs::DirBuilder::new();
    b.recursive(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::DirBuilderExt;
        b.mode(0o700);
    }
    b.create(base).map_err(|error| KeyError::Io {
        path: base.to_path_buf(),
        error,
    })?;
    let p = team_key_path(base);
    create_key_file(&p, &random_key()?).map_err(|e| KeyError::Persist(e.to_string()))?;
    Ok(p)
}

/// Which way a key protects frames (or, for the team key, robot-to-robot packets).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Tc,
    Tm,
    /// The team's packets between robots (SPI not applicable: shown as 0).
    Team,
}

/// A key file as [`describe`] shows it (never the key).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyInfo {
    pub path: PathBuf,
    pub direction: Direction,
    pub spi: u16,
    /// First 8 hex digits of SHA-256 of the key (`None`: not a 32-byte file).
    pub fingerprint: Option<String>,
    /// Its length when not 32 bytes.
    pub len: u64,
    /// Unix permission bits.
    pub mode: Option<u32>,
}

/// First 8 hex digits of SHA-256 of `key`.
pub fn fingerprint(key: &[u8]) -> String {
    Sha256::digest(key).iter().take(4).map(|b| format!("{b:02x}")).collect()
}

fn spi_of(name: &str) -> Option<(Direction, u16)> {
    if name == TEAM_KEY_FILE {
        return Some((Direction::Team, 0));
    }
    let stem = name.strip_suffix(".key")?;
    let (dir, n) = if let Some(n) = stem.strip_prefix("tc-spi") {
        (Direction::Tc, n)
    } else {
        (Direction::Tm, stem.strip_prefix("tm-spi")?)
    };
    Some((dir, n.parse().ok()?))
}

/// The key files under `dir` (itself and its `robot-N` subdirectories), sorted by path.
pub fn describe(dir: &Path) -> Result<Vec<KeyInfo>, KeyError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |error| KeyError::Io { path, error }
    };
    let mut dirs = vec![dir.to_path_buf()];
    for e in std::fs::read_dir(dir).map_err(io(dir))? {
        let e = e.map_err(io(dir))?;
        if e.file_type().map_err(io(&e.path()))?.is_dir() {
            dirs.push(e.path());
        }
    }
    let mut out = Vec::new();
    for d in dirs {
        for e in std::fs::read_dir(&d).map_err(io(&d))? {
            let e = e.map_err(io(&d))?;
            let name = e.file_name().to_string_lossy().into_owned();
            let Some((direction, spi)) = spi_of(&name) else {
                continue;
            };
            let path = e.path();
            let meta = std::fs::metadata(&path).map_err(io(&path))?;
            let bytes = std::fs::read(&path).map_err(io(&path))?;
            #[cfg(unix)]
            let mode = {
                use std::os::unix::fs::PermissionsExt;
                Some(meta.permissions().mode() & 0o777)
            };
            #[cfg(not(unix))]
            let mode = None;
            out.push(KeyInfo {
                fingerprint: (bytes.len() == 32).then(|| fingerprint(&bytes)),
                len: meta.len(),
                path,
                direction,
                spi,
                mode,
            });
        }
    }
    out.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: LINK-KEYS-01
    #[test]
    fn robot_keys_are_random_private_and_described_without_the_key() {
        let base = std::env::temp_dir().join(format!("ground-link-keys-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let made = create_robot_keys(&base, 2).unwrap();
        assert_eq!(made.len(), 4);
        let keys: Vec<Vec<u8>> = made.iter().map(|p| std::fs::read(p).unwrap()).collect();
        for (i, k) in keys.iter().enumerate() {
            assert_eq!(k.len(), 32);
            assert!(keys[i + 1..].iter().all(|o| o != k), "two equal keys");
        }
        // A second creation refuses to overwrite.
        assert!(create_robot_keys(&base, 2).is_err());
        let info = describe(&base).unwrap();
        assert_eq!(info.len(), 4);
        let spis: Vec<(Direction, u16)> = info.iter().map(|i| (i.direction, i.spi)).collect();
        assert_eq!(
            spis,
            vec![
                (Direction::Tc, 1),
                (Direction::Tc, 2),
                (Direction::Tm, 17),
                (Direction::Tm, 18)
            ]
        );
        for i in &info {
            let key = std::fs::read(&i.path).unwrap();
            assert_eq!(i.fingerprint.as_deref(), Some(fingerprint(&key).as_str()));
            #[cfg(unix)]
            assert_eq!(i.mode, Some(0o600));
        }
        assert_eq!(tc_key_path(&robot_dir(&base, 2)), made[0]);
        assert_eq!(tm_key_path(&robot_dir(&base, 2)), made[2]);
        let _ = std::fs::remove_dir_all(&base);
    }

    // verifies: LINK-KEYS-01
    #[test]
    fn fingerprint_is_the_start_of_sha256() {
        // SHA-256("abc") = ba7816bf 8f01cfea ...
        assert_eq!(fingerprint(b"abc"), "ba7816bf");
    }
}
