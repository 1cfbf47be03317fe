//! `ground plan check` and `ground plan encode`: plan files validated against the MIB, or
//! turned into the TC stream per robot.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use clap::Subcommand;
use ground::plan;

use crate::exit::{self, coded};
use crate::output::{err_line, out};
use crate::verb_run::unconfirmed;

#[derive(Subcommand, Debug)]
pub(crate) enum PlanCmd {
    /// Validate plans against the MIB; every error with file:line:column.
    Check {
        #[arg(required = true)]
        plans: Vec<PathBuf>,
        /// Print the parsed plan (or the errors) as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Write the TC stream per robot (one raw file per APID) and a listing.
    Encode {
        plan: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
}

pub(crate) fn load_plan(path: &Path) -> Result<plan::Plan> {
    plan::load(path).map_err(|e| match e.diagnostics() {
        Some(_) => coded(exit::INVALID, e.to_string()),
        None => anyhow!(e),
    })
}

pub(crate) fn plan_check(plans: &[PathBuf], json: bool) -> Result<u8> {
    let mut bad = 0;
    for p in plans {
        let bytes = std::fs::read(p).with_context(|| format!("cannot read {}", p.display()))?;
        let src = match String::from_utf8(bytes) {
            Ok(s) => s,
            Err(e) => {
                bad += 1;
                err_line!(
                    "{}: error: not a plan: not UTF-8 text (invalid byte at offset {})",
                    p.display(),
                    e.utf8_error().valid_up_to()
                );
                continue;
            }
        };
        match plan::parse(&src) {
            Ok(pl) if !unconfirmed(&pl).is_empty() => {
                bad += 1;
                let list = unconfirmed(&pl);
                for (st, e) in &list {
                    let (line, col) = plan::line_col(&src, st.span.start);
                    err_line!("{}:{line}:{col}: error: step \"{}\": {e}", p.display(), st.id);
                }
                err_line!("{}: {} error(s)", p.display(), list.len());
            }
            Ok(pl) => {
                if json {
                    out(&serde_json::to_string_pretty(&pl)?)?;
                } else {
                    let robots: Vec<String> = pl.robots.iter().map(|r| r.number.to_string()).collect();
                    out(&format!(
                        "{}: ok — plan \"{}\", robots {}, {} steps",
                        p.display(),
                        pl.name,
                        robots.join(", "),
                        pl.steps.len()
                    ))?;
                }
            }
            Err(errs) => {
                bad += 1;
                let d = plan::diagnostics(&p.display().to_string(), &src, &errs);
                if json {
                    out(&serde_json::to_string_pretty(&d)?)?;
                } else {
                    for x in &d {
                        err_line!("{x}");
                    }
                    err_line!("{}: {} error(s)", p.display(), d.len());
                }
            }
        }
    }
    Ok(if bad > 0 { exit::INVALID } else { exit::OK })
}

pub(crate) fn plan_encode(path: &Path, dir: &Path) -> Result<u8> {
    let pl = load_plan(path)?;
    let enc = plan::encode(&pl).map_err(|e| coded(exit::INVALID, e.to_string()))?;
    let files = plan::write_encoded(&pl, &enc, dir).with_context(|| format!("writing {}", dir.display()))?;
    for f in files {
        out(&f.display().to_string())?;
    }
    Ok(exit::OK)
}
