//! Plan files: parsing (TOML, every value with its span), validation against the MIB
//! (collecting every error, each with file:line:column), and encoding to TC streams.
//!
//! The document is read with `toml`'s span-preserving parser (`toml::de::DeTable`,
//! recoverable, so every syntax error is reported too) and converted by hand into the
//! typed [`Plan`], so that one bad value does not hide the others. See
//! `docs/plan-format.md` for the format.
//!
//! - `values`: readers of single values (integers in range, states, sides, pairs, modes);
//! - `step`: one `[[step]]` table and its action's keys;
//! - `parse`: the document, then `validate`: ids, dependencies, each robot's walk;
//! - `action`: what a step does and the TC it sends; `diag`: errors placed in a file;
//! - `encode`: the TC streams and their listing.

mod action;
mod diag;
mod encode;
pub mod onboard;
mod parse;
mod step;
mod validate;
mod values;

#[cfg(test)]
mod tests;

use std::collections::{HashSet, VecDeque};
use std::fmt;
use std::ops::Range;

use serde::Serialize;

pub use action::{state_name, Action};
pub use diag::{diagnostics, line_col, Diagnostic, PlanError};
pub use encode::{encode, write_encoded, EncodedStep};
pub use parse::parse;

/// A robot taking part in the plan.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RobotDecl {
    pub number: u8,
    pub name: Option<String>,
    /// Ground's belief of the robot's state at the start of the plan.
    pub initial_state: Option<u8>,
    #[serde(skip)]
    pub span: Range<usize>,
}

/// One step of a plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Step {
    pub id: String,
    pub robot: u8,
    #[serde(flatten)]
    pub action: Action,
    /// Dependencies written in the file.
    pub after: Vec<String>,
    /// Every step this one waits for (indices into `Plan::steps`): the explicit ones
    /// plus the previous step of the same robot.
    pub deps: Vec<usize>,
    /// Longest wait for completion, seconds (`None`: the run's default).
    pub timeout_s: Option<f64>,
    /// `confirm = true`: the operator confirms the step's hazardous TC (the MIB's
    /// `hazard`); `ground run` refuses a hazardous step without it.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub confirm: bool,
    #[serde(skip)]
    pub span: Range<usize>,
}

/// A validated plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    pub name: String,
    pub description: String,
    pub robots: Vec<RobotDecl>,
    pub steps: Vec<Step>,
}

impl Plan {
    pub fn step_index(&self, id: &str) -> Option<usize> {
        self.steps.iter().position(|s| s.id == id)
    }

    /// Steps that (transitively) depend on step `i`.
    pub fn dependents(&self, i: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        let mut q = VecDeque::from([i]);
        while let Some(c) = q.pop_front() {
            for (j, s) in self.steps.iter().enumerate() {
                if s.deps.contains(&c) && seen.insert(j) {
                    out.push(j);
                    q.push_back(j);
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// Shortest primitive sequence from `from` to `to` (at most
/// `mib::config::MAX_RECONFIG_PRIMITIVES`), by the same breadth-first search over the MIB's
/// reconfiguration map. `Some(vec![])` if the states are equal.
pub fn reconfig_path(from: u8, to: u8) -> Option<Vec<u8>> {
    // One search for ground and board: the domain crate's (the OBSW runs the same code).
    mmic_domain::search::shortest_path(from, to).map(|p| p.to_vec())
}

/// Reads and parses a plan file; errors come back as diagnostics.
pub fn load(path: &std::path::Path) -> Result<Plan, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::Io(path.display().to_string(), e))?;
    let src = String::from_utf8(bytes).map_err(|e| {
        LoadError::Invalid(vec![Diagnostic {
            file: path.display().to_string(),
            line: 1,
            column: 1,
            message: format!(
                "not a plan: not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        }])
    })?;
    parse(&src).map_err(|errs| LoadError::Invalid(diagnostics(&path.display().to_string(), &src, &errs)))
}

/// Why a plan file cannot be loaded. Callers tell the cases apart by
/// [`LoadError::diagnostics`] and [`LoadError::io_error`] (it may grow).
#[derive(Debug)]
#[non_exhaustive]
pub enum LoadError {
    /// The file cannot be read (its path, the error).
    Io(String, std::io::Error),
    /// The file is not a valid plan.
    Invalid(Vec<Diagnostic>),
}

impl LoadError {
    /// What is wrong with the plan, when it was read but is not valid.
    pub fn diagnostics(&self) -> Option<&[Diagnostic]> {
        match self {
            LoadError::Invalid(d) => Some(d),
            LoadError::Io(..) => None,
        }
    }

    /// Why the file could not be read, when it could not.
    pub fn io_error(&self) -> Option<&std::io::Error> {
        match self {
            LoadError::Io(_, e) => Some(e),
            LoadError::Invalid(_) => None,
        }
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::Io(p, e) => write!(f, "cannot read {p}: {e}"),
            LoadError::Invalid(d) => {
                for x in d {
                    writeln!(f, "{x}")?;
                }
                write!(f, "{} error(s) in the plan", d.len())
            }
        }
    }
}

impl std::error::Error for LoadError {}
