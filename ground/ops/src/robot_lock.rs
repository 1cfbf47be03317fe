//! One commanding ground process per robot on this host.
//!
//! Two grounds on one robot would each keep their own TC sequence count on its APID (so a
//! command could be taken for a resend of another one) and, over frames, their own FOP-1
//! against the robot's one FARM-1. Every [`crate::link::Link`] therefore holds an exclusive
//! lock on a file named after the robot's address for its lifetime: `ground send`,
//! `run`, `watch`, `demo` and the collector alike. A second process that wants the same
//! robot is refused with a message naming the holder (its process ID and command line) —
//! a CLI command while `ground collect` follows the robot goes through the collector's
//! page or API instead. The operating system drops the lock when the holder exits, even
//! by `kill -9`.
//!
//! Scope: one user's processes on one host (the lock directory is
//! `$MMIC_GROUND_LOCK_DIR`, else `$XDG_RUNTIME_DIR/mmic-ground`, else
//! `/tmp/mmic-ground-locks-UID`; never `$TMPDIR`, which differs between shells), and the
//! robot given by the same address. Grounds on two
//! hosts are not seen; over frames, the robot's FARM-1 and SDLS anti-replay then refuse
//! the second one's frames (counted in HK SID 22), but nothing coordinates them.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{self, Read, Seek, Write};
use std::net::SocketAddr;
use std::path::PathBuf;

/// The held lock of one robot address (released when dropped or when the process ends).
#[derive(Debug)]
pub struct RobotLock {
    _file: File,
    pub path: PathBuf,
}

/// Where the lock files are.
pub fn lock_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("MMIC_GROUND_LOCK_DIR") {
        return PathBuf::from(d);
    }
    match std::env::var_os("XDG_RUNTIME_DIR") {
        Some(d) => PathBuf::from(d).join("mmic-ground"),
        None => PathBuf::from(format!("/tmp/mmic-ground-locks-{}", nix::unistd::getuid())),
    }
}

/// This process as the lock file names it.
fn holder() -> String {
    let args: Vec<String> = std::env::args().collect();
    let name = args
        .first()
        .and_then(|a| std::path::Path::new(a).file_name())
        .map_or_else(|| "ground".to_string(), |n| n.to_string_lossy().into_owned());
    let rest = args.get(1..).unwrap_or_default().join(" ");
    format!("pid {} `{name} {rest}`", std::process::id())
}

impl RobotLock {
    /// Takes robot `robot`'s lock at `addr`, or says who holds it.
    pub fn acquire(robot: u8, addr: SocketAddr) -> io::Result<RobotLock> {
        let dir = lock_dir();
        std::os::unix::fs::DirBuilderExt::mode(std::fs::DirBuilder::new().recursive(true), 0o700)
            .create(&dir)
            .map_err(|e| io::Error::new(e.kind(), format!("lock directory {}: {e}", dir.display())))?;
        let key: String = addr
            .to_string()
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '.' { c } else { '_' })
            .collect();
        let path = dir.join(format!("robot-at-{key}.lock"));
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("lock file {}: {e}", path.display())))?;
        match file.try_lock() {
            Ok(()) => {
                file.set_len(0)?;
                file.rewind()?;
                writeln!(file, "{}", holder())?;
                Ok(RobotLock { _file: file, path })
            }
            Err(TryLockError::WouldBlock) => {
                let mut who = String::new();
                let _ = file.read_to_string(&mut who);
                let who = who.trim();
                let who = if who.is_empty() { "another ground process" } else { who };
                Err(io::Error::new(
                    io::ErrorKind::AddrInUse,
                    format!(
                        "robot {robot} at {addr} is already commanded by {who} on this host; two grounds \
                         on one robot would share its sequence counts (and, over frames, its COP-1 \
                         window): command it through that process (the collector's page or API) or \
                         stop it first (lock {})",
                        path.display()
                    ),
                ))
            }
            Err(TryLockError::Error(e)) => Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: OPS-TWO-01
    #[test]
    fn a_second_lock_on_one_robot_is_refused_naming_the_holder_and_freed_on_drop() {
        let addr: SocketAddr = ([127, 0, 0, 1], 1).into();
        let first = RobotLock::acquire(1, addr).unwrap();
        let e = RobotLock::acquire(1, addr).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::AddrInUse);
        let m = e.to_string();
        assert!(m.contains("already commanded by pid"), "{m}");
        assert!(m.contains(&std::process::id().to_string()), "{m}");
        // Another robot is not held.
        let other = RobotLock::acquire(2, ([127, 0, 0, 1], 2).into()).unwrap();
        drop(first);
        let again = RobotLock::acquire(1, addr).unwrap();
        drop((other, again));
    }
}
