//! The simulator's module-set files (`mmic_sim::modules::ModuleSetSpec::parse`), and what
//! the flight code makes of the descriptor tables and probes they describe
//! (`DiscoveryInput::discover`, the on-board module discovery).
//!
//! The input is the file's text (not UTF-8: skipped, as the loader refuses it). Invariants:
//! nothing panics; an error's line lies inside the file; a parsed set's tables go through
//! discovery.

use std::path::Path;

use mmic_sim::modules::ModuleSetSpec;

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match ModuleSetSpec::parse(Path::new("fuzz.toml"), text) {
        Ok(spec) => {
            let _ = spec.discovery_input().discover();
        }
        Err(e) => {
            let lines = text.matches('\n').count() + 1;
            assert!(
                e.line.is_none_or(|l| l >= 1 && l <= lines),
                "error at line {:?} of {lines}",
                e.line
            );
        }
    }
}
