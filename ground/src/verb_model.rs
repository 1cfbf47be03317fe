//! `ground model`: the robot's kinematic and dynamic model (URDF) from its module set and
//! the MIB's module database. The set comes from the robot itself (TC[210,1]
//! REPORT_MODULES, answered by the module report TM[210,3]) or from a module-set file
//! (`plans/modules/*.toml`, what the simulator builds a robot from). Both paths go through
//! the same checked report parse (lengths, descriptor CRCs, slots, configuration hash).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use clap::Args;
use ground::ops::Update;
use mib::modules::Board;

use crate::exit::{self, coded};
use crate::links::{close_archive, one_robot, open_one, Links};
use crate::output::{err_line, out};

#[derive(Args, Debug)]
pub(crate) struct ModelArgs {
    /// The live robot to ask for its module report (`--robot N=HOST:PORT`).
    #[command(flatten)]
    links: Links,
    /// A module-set file (e.g. plans/modules/locomotion-only.toml) instead of a live robot.
    #[arg(long)]
    modules: Option<PathBuf>,
    /// Root the model at this side's gripper: a or b.
    #[arg(long, default_value = "a")]
    root: String,
    /// Write the URDF here (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Longest wait for the module report (seconds).
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
}

pub(crate) fn model(a: &ModelArgs, archive_path: Option<&Path>) -> Result<u8> {
    let root = match a.root.to_ascii_lowercase().as_str() {
        "a" => Board::A,
        "b" => Board::B,
        other => return Err(coded(exit::USAGE, format!("--root {other}: a or b"))),
    };
    let (report, name) = match (&a.modules, a.links.robots.is_empty()) {
        (Some(file), true) => (report_of_file(file)?, format!("mmic_{}", stem(file))),
        (None, false) => {
            let (robot, _) = one_robot(&a.links)?;
            (report_of_robot(a, archive_path)?, format!("mmic_robot_{robot}"))
        }
        (Some(_), false) => return Err(coded(exit::USAGE, "give --modules FILE or --robot, not both")),
        (None, true) => return Err(coded(exit::USAGE, "give --modules FILE or --robot N=HOST:PORT")),
    };
    let urdf = mib_export::urdf::urdf_from_report(&report, root, &name)
        .map_err(|e| coded(exit::INVALID, format!("module report: {e}")))?;
    match &a.out {
        Some(p) => {
            std::fs::write(p, &urdf).with_context(|| format!("writing {}", p.display()))?;
            err_line!("URDF of {name} ({} bytes) written to {}", urdf.len(), p.display());
        }
        None => out(urdf.trim_end())?,
    }
    Ok(exit::OK)
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().replace(|c: char| !c.is_ascii_alphanumeric(), "_"))
        .unwrap_or_else(|| "robot".into())
}

/// What the robot built from `file` would report: the simulator's reading of the file,
/// then on-board discovery, then the report body.
fn report_of_file(file: &Path) -> Result<Vec<u8>> {
    let spec = mmic_sim::modules::ModuleSetSpec::load(file).map_err(|e| coded(exit::INVALID, e.to_string()))?;
    let d = spec.discovery_input().discover();
    let r = mmic_domain::discovery::report(&d, mmic_domain::discovery::Replacement::NoneAccepted);
    let mut buf = vec![0u8; mib::modules::report::MAX_REPORT_LEN];
    let n = r
        .emit(&mut buf)
        .map_err(|e| anyhow!("module report of {}: {e}", file.display()))?;
    buf.truncate(n);
    Ok(buf)
}

/// Asks the robot for its module report (TC[210,1]) and returns the report body.
fn report_of_robot(a: &ModelArgs, archive_path: Option<&Path>) -> Result<Vec<u8>> {
    let def = mib::tc::by_name("REPORT_MODULES").ok_or_else(|| anyhow!("REPORT_MODULES not in the MIB"))?;
    let (robot, mut s, arch) = open_one(&a.links, archive_path)?;
    s.watch_links();
    s.send(robot, def, &[], Some(0), None)?;
    let t0 = Instant::now();
    let mut asked = Instant::now();
    let mut found = None;
    'wait: while t0.elapsed() < Duration::from_secs_f64(a.timeout) {
        for u in s.poll(Duration::from_millis(100)) {
            match u {
                Update::Tm { robot: r, tm }
                    if r == robot
                        && (tm.service, tm.subservice)
                            == (
                                mib_wire::tm::ModuleReport::SERVICE,
                                mib_wire::tm::ModuleReport::SUBSERVICE,
                            ) =>
                {
                    if let Some(data) = ground::collect::onboard::module_report(&tm) {
                        // A robot that has just booted reports before its discovery has
                        // finished (hash 0, CONFIG_HASH's "not discovered"): its boot report
                        // follows within the discovery budget; ask again meanwhile.
                        let not_discovered = mib::modules::config::HASH_NOT_DISCOVERED.to_be_bytes();
                        if data.get(..4).is_some_and(|h| h != not_discovered) {
                            found = Some(data);
                            break 'wait;
                        }
                    }
                }
                Update::GaveUp { .. } | Update::LinkLost { .. } => break 'wait,
                _ => {}
            }
        }
        if found.is_none() && asked.elapsed() >= Duration::from_millis(500) {
            s.send(robot, def, &[], Some(0), None)?;
            asked = Instant::now();
        }
    }
    drop(s);
    close_archive(arch)?;
    found.ok_or_else(|| {
        coded(
            exit::NO_ANSWER,
            format!("robot {robot}: no module report (TM[210,3]) within {} s", a.timeout),
        )
    })
}
