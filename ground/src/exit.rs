//! Exit codes (the table in docs/operator-guide.md) and the error that carries one.

pub const OK: u8 = 0;
pub const ERROR: u8 = 1;
pub const USAGE: u8 = 2;
pub const INVALID: u8 = 3;
pub const FAILED: u8 = 4;
/// A robot heard, then lost (also: no simulator answering); see
/// `ground::ops::NoAnswer` for 5, 7 and 8.
pub const NO_ANSWER: u8 = 5;
/// `ground run` interrupted by Ctrl-C or SIGTERM: summary printed, `--resume` continues.
pub const INTERRUPTED: u8 = 6;
/// A second Ctrl-C: exit at once.
pub const INTERRUPTED_AGAIN: i32 = 130;

/// An error with its exit code.
#[derive(Debug)]
pub struct Coded(pub u8, pub String);
impl std::fmt::Display for Coded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.1)
    }
}
impl std::error::Error for Coded {}

pub fn coded(code: u8, msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Coded(code, msg.into()))
}
