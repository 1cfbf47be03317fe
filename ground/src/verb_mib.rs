//! `ground mib export`: the MIB in the formats other ground systems read.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Subcommand;

use crate::exit::{self, coded};
use crate::output::out;

#[derive(Subcommand, Debug)]
pub(crate) enum MibCmd {
    /// Write SCOS-2000 tables, XTCE, JSON or a Yamcs instance.
    Export {
        /// scos, xtce, json, or yamcs[:ROBOTS] (a Yamcs instance, e.g. yamcs:1-3).
        #[arg(long)]
        format: String,
        #[arg(long)]
        out: PathBuf,
    },
}

pub(crate) fn mib_export(format: &str, dir: &Path) -> Result<u8> {
    let f: mib_export::Format = format
        .parse()
        .map_err(|e: mib_export::UnknownFormat| coded(exit::INVALID, e.to_string()))?;
    let files = mib_export::write_all(f, dir).with_context(|| format!("writing {}", dir.display()))?;
    for p in files {
        out(&p.display().to_string())?;
    }
    Ok(exit::OK)
}
