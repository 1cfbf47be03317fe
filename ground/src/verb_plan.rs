//! `ground plan check` and `ground plan encode`: plan files validated against the MIB, or
//! turned into the TC stream per robot. `ground plan suspend|resume|abort|skip|status`:
//! the PUS 18 control of one robot's on-board plan (docs/plan-format.md, "On board").

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use clap::{Args, Subcommand};
use ground::ops::{self, Session, Update};
use ground::plan;

use crate::exit::{self, coded};
use crate::links::{close_archive, open_one, Links};
use crate::output::{err_line, out};
use crate::verb_live::{no_answer_error, policy_error, send_and_follow};
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
    /// Suspend a robot's on-board plan (PLAN_SUSPEND): the running step finishes, no
    /// further step starts. Prints the plan status after.
    Suspend(ControlArgs),
    /// Resume a suspended on-board plan where it stopped (PLAN_RESUME; a failed step runs
    /// again). Hazardous: needs --confirm.
    Resume(ControlArgs),
    /// Abort a robot's on-board plan (PLAN_ABORT): nothing further starts; a running
    /// action is stopped as a ground STOP would.
    Abort(ControlArgs),
    /// Skip the next step of a suspended on-board plan (PLAN_SKIP; counted as completed,
    /// also for the other robots' dependencies). Hazardous: needs --confirm.
    Skip {
        /// The step to skip (0-based, in the robot's own image): the plan's next step.
        step: u8,
        #[command(flatten)]
        control: ControlArgs,
    },
    /// Report a robot's on-board plan status (PLAN_STATUS_REQUEST).
    Status(ControlArgs),
}

#[derive(Args, Debug)]
pub(crate) struct ControlArgs {
    #[command(flatten)]
    links: Links,
    /// Longest wait for the TC's completion and the status report (seconds).
    #[arg(long, default_value_t = 30.0)]
    timeout: f64,
    /// Confirm a hazardous TC (the MIB's hazard flag: PLAN_RESUME, PLAN_SKIP).
    #[arg(long)]
    confirm: bool,
    /// Print the status report as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs a plan control verb: its TC (none for `status`), then the status report.
pub(crate) fn plan_control(cmd: &PlanCmd, archive_path: Option<&Path>) -> Result<u8> {
    let (tc, args, c) = match cmd {
        PlanCmd::Suspend(c) => (Some("PLAN_SUSPEND"), vec![], c),
        PlanCmd::Resume(c) => (Some("PLAN_RESUME"), vec![], c),
        PlanCmd::Abort(c) => (Some("PLAN_ABORT"), vec![], c),
        PlanCmd::Skip { step, control } => (Some("PLAN_SKIP"), vec![i64::from(*step)], control),
        PlanCmd::Status(c) => (None, vec![], c),
        PlanCmd::Check { .. } | PlanCmd::Encode { .. } => return Err(anyhow!("not a plan control verb")),
    };
    let def = match tc {
        Some(name) => {
            let def = ops::policy::tc_by_name(name).map_err(policy_error)?;
            ops::policy::check_confirmed(def, c.confirm, "add --confirm").map_err(policy_error)?;
            Some(def)
        }
        None => None,
    };
    let timeout = Duration::from_secs_f64(c.timeout.max(0.0));
    let (robot, mut s, arch) = open_one(&c.links, archive_path)?;
    let r = (|| -> Result<u8> {
        let code = match def {
            Some(def) => send_and_follow(&mut s, robot, def, &args, true, timeout)?,
            None => exit::OK,
        };
        let st = plan_status(&mut s, robot, timeout)?;
        if c.json {
            out(&serde_json::json!({
                "robot": robot,
                "plan_id": st.plan_id,
                "state": state_name(st.state),
                "steps": st.steps,
                "next_step": st.next_step,
                "done": st.done,
                "wait_robot": st.wait_robot,
                "wait_step": st.wait_step,
            })
            .to_string())?;
        } else {
            out(&format!("robot {robot}: {}", status_line(&st)))?;
        }
        Ok(code)
    })();
    drop(s);
    close_archive(arch)?;
    r
}

/// The name of a plan state code (the MIB's list).
fn state_name(code: u8) -> String {
    match &mib::plan::STATE_NAMES {
        mib::layout::Names::List(l) => l
            .iter()
            .find(|(v, _)| *v == i64::from(code))
            .map_or_else(|| format!("UNKNOWN({code})"), |(_, n)| n.to_string()),
        _ => format!("{code}"),
    }
}

/// One line for a status report, e.g. `plan 0x1234ABCD SUSPENDED at step 1 of 5 (1 done)`.
fn status_line(st: &mib_wire::tm::PlanStatus) -> String {
    let mut l = format!(
        "plan 0x{:08X} {} at step {} of {} ({} done)",
        st.plan_id,
        state_name(st.state),
        st.next_step,
        st.steps,
        st.done
    );
    if st.wait_robot != 0 {
        l.push_str(&format!(
            ", waiting for robot {}'s step {}",
            st.wait_robot, st.wait_step
        ));
    }
    l
}

/// Asks `robot` for its plan status and waits for the report.
fn plan_status(s: &mut Session, robot: u8, timeout: Duration) -> Result<mib_wire::tm::PlanStatus> {
    let def = mib::tc::by_name("PLAN_STATUS_REQUEST").ok_or_else(|| anyhow!("PLAN_STATUS_REQUEST not in the MIB"))?;
    s.watch_links();
    let tc = s.send(robot, def, &[], Some(0), None)?;
    let t0 = Instant::now();
    while t0.elapsed() < timeout {
        for u in s.poll(Duration::from_millis(100)) {
            match u {
                Update::Tm { robot: r, tm } if r == robot => {
                    if let Some(mib_wire::Tm::PlanStatus(st)) = tm.body.report() {
                        return Ok(st.clone());
                    }
                }
                Update::Verification { v, .. }
                    if v.request.seq() == tc.seq && v.request.apid() == tc.apid && !v.success =>
                {
                    return Err(coded(
                        exit::FAILED,
                        format!(
                            "robot {robot}: PLAN_STATUS_REQUEST {} FAILED{}",
                            v.stage.name(),
                            v.failure.as_ref().map_or(String::new(), |f| format!(": {f}"))
                        ),
                    ));
                }
                Update::LinkLost { .. } => return Err(no_answer_error(s, robot, "")),
                _ => {}
            }
        }
    }
    Err(no_answer_error(
        s,
        robot,
        &format!(
            "PLAN_STATUS_REQUEST seq {}: no PLAN_STATUS report within {:.0} s",
            tc.seq,
            timeout.as_secs_f64()
        ),
    ))
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
