//! `ground run`: a plan against running OBSWs, with its run ID, interruption and
//! `--resume`.

use std::path::Path;
use std::time::Duration;

use anyhow::{anyhow, Result};
use ground::archive;
use ground::ops::{self, RunOptions};
use ground::plan;
use ground::pus;

use crate::exit::{self, coded};
use crate::links::{close_archive, Links};
use crate::output::{err_line, out};
use crate::verb_archive::fmt_ms;
use crate::verb_plan::load_plan;
use clap::Args;
use std::path::PathBuf;

pub(crate) fn run_plan(a: &RunArgs, archive_path: Option<&Path>) -> Result<u8> {
    let pl = load_plan(&a.plan)?;
    // A --robot the plan does not use is a mistake in the command, not a robot to wait
    // for: refused before anything is sent.
    for (n, addr) in &a.links.addresses() {
        if !pl.robots.iter().any(|r| r.number == *n) {
            let theirs: Vec<String> = pl.robots.iter().map(|r| r.number.to_string()).collect();
            return Err(coded(
                exit::USAGE,
                format!(
                    "--robot {n}={addr}: robot {n} is not in plan \"{}\" (its robots: {}); drop it",
                    pl.name,
                    theirs.join(", ")
                ),
            ));
        }
    }
    plan_policy(&a.plan.display().to_string(), &pl)?;
    let mut links = a.links.addresses();
    for r in &pl.robots {
        if !links.iter().any(|(n, _)| *n == r.number) {
            links.push((r.number, a.links.link.default_addr(r.number)));
        }
    }
    let (run_id, resume) = match &a.resume {
        None => (ground::ops::runs::new_run_id(), ops::Resume::default()),
        Some(wanted) => {
            let p =
                archive_path.ok_or_else(|| coded(exit::INVALID, "--resume needs the archive (drop --no-archive)"))?;
            resume_state(p, &pl, (!wanted.is_empty()).then_some(wanted.as_str()))?
        }
    };
    let (mut session, arch) = a.links.open(&links, archive_path)?;
    session.run_id = Some(run_id.clone());
    let mut resume = resume;
    if a.on_board {
        on_board(a, &pl, &mut session, &mut resume)?;
    }
    err_line!(
        "run {run_id}: plan \"{}\"{}",
        pl.name,
        if a.resume.is_some() { " (resumed)" } else { "" }
    );
    let opts = RunOptions {
        step_timeout: Duration::from_secs_f64(a.step_timeout),
        ping_period: (!a.no_ping).then(|| Duration::from_millis(mib::ground_config::GROUND_HEARTBEAT_MS as u64)),
        display: !a.plain && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        stop: Some(interrupt_flag()),
        grace: Duration::from_secs_f64(a.grace.max(0.0)),
        tm_from_boot: false,
    };
    let summary = ops::run_plan(&pl, &mut session, &opts, &resume);
    // The case of a link lost while the plan ran (not one noticed in the final gap
    // retrieval, after the last step).
    let no_answer = session
        .robots
        .values()
        .filter(|s| s.lost.as_ref().is_some_and(|w| summary.link_lost.contains(w)))
        .find_map(|s| s.lost_kind);
    drop(session);
    close_archive(arch)?;
    if a.detach && resume.on_board.as_ref().is_some_and(|o| o.upload) && summary.failed == 0 {
        out(&format!(
            "run {run_id}: plan \"{}\" runs on board; follow it with `ground run --on-board --resume {run_id} {}`",
            pl.name,
            a.plan.display()
        ))?;
        return Ok(exit::OK);
    }
    if a.json {
        out(&serde_json::to_string_pretty(&summary)?)?;
    } else {
        out(summary.text().trim_end())?;
        if let Some(p) = archive_path {
            out(&format!("archive: {}", p.display()))?;
        }
    }
    Ok(if summary.interrupted {
        exit::INTERRUPTED
    } else if let Some(k) = no_answer {
        k.exit_code()
    } else if summary.success() {
        exit::OK
    } else {
        exit::FAILED
    })
}

/// `--on-board`: the plan compiled for the robots (a new run: uploaded and started by
/// `run_plan`), or, with `--resume`, the run's archived step TCs followed on board.
fn on_board(a: &RunArgs, pl: &plan::Plan, session: &mut ops::Session, resume: &mut ops::Resume) -> Result<()> {
    if a.resume.is_some() {
        // The steps not completed are the robots' to run: never sent from here.
        let tcs = resume.in_flight.drain(..).map(|f| (f.step, f.tc)).collect();
        resume.on_board = Some(ops::OnBoard {
            compiled: plan::onboard::Compiled {
                plan_id: 0,
                images: Vec::new(),
                tcs,
            },
            upload: false,
            detach: false,
        });
        return Ok(());
    }
    let compiled = plan::onboard::compile(pl, |r| session.next_seq(r)).map_err(|e| {
        coded(
            exit::INVALID,
            e.iter()
                .map(|l| format!("{}: {l}", a.plan.display()))
                .collect::<Vec<_>>()
                .join("\n"),
        )
    })?;
    resume.on_board = Some(ops::OnBoard {
        compiled,
        upload: true,
        detach: a.detach,
    });
    Ok(())
}

/// The steps of `pl` with a hazardous TC and no `confirm = true`.
pub(crate) fn unconfirmed(pl: &plan::Plan) -> Vec<(&plan::Step, ops::policy::PolicyError)> {
    pl.steps
        .iter()
        .filter_map(|s| {
            let (def, _) = s.action.tc()?;
            ops::policy::check_confirmed(def, s.confirm, "add `confirm = true` to the step")
                .err()
                .map(|e| (s, e))
        })
        .collect()
}

/// Refuses a plan whose hazardous steps are not confirmed (every one listed).
pub(crate) fn plan_policy(file: &str, pl: &plan::Plan) -> Result<()> {
    let refused: Vec<String> = unconfirmed(pl)
        .into_iter()
        .map(|(s, e)| format!("{file}: step \"{}\": {e}", s.id))
        .collect();
    if refused.is_empty() {
        Ok(())
    } else {
        Err(coded(exit::INVALID, refused.join("\n")))
    }
}

/// Sets up Ctrl-C and SIGTERM: the first sets the returned flag (the run stops sending
/// and ends with its summary), a second exits at once with 130.
pub(crate) fn interrupt_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    use std::sync::atomic::{AtomicBool, Ordering};
    let flag = std::sync::Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    let set = ctrlc::set_handler(move || {
        if f.swap(true, Ordering::SeqCst) {
            err_line!("ground: interrupted again: exiting at once (exit 130); steps in flight keep running on board");
            std::process::exit(exit::INTERRUPTED_AGAIN);
        }
        err_line!(
            "ground: interrupted: no new step is sent; waiting for the steps in flight (Ctrl-C again to quit at once)"
        );
    });
    if let Err(e) = set {
        err_line!("ground: warning: no Ctrl-C handling ({e})");
    }
    flag
}

/// What `--resume` continues: the run (latest of this plan, or `wanted`), its completed
/// steps and the TCs whose outcome it does not know.
pub(crate) fn resume_state(path: &Path, pl: &plan::Plan, wanted: Option<&str>) -> Result<(String, ops::Resume)> {
    let loc = path.to_string_lossy();
    let mut st = match archive::Store::open_existing(&loc) {
        Ok(st) => st,
        Err(archive::ArchiveError::NotFound(_)) => {
            return Err(coded(exit::INVALID, format!("--resume: archive {loc} does not exist")));
        }
        Err(e) => return Err(anyhow!("--resume: {e}")),
    };
    let rec = ops::runs::find_run(&mut st, pl, wanted).map_err(|e| match e {
        ops::runs::ResumeError::Archive(e) => anyhow!("--resume: reading the archive: {e}"),
        e => coded(exit::INVALID, format!("--resume: {e}")),
    })?;
    let mut r = ops::Resume::default();
    for (i, s) in pl.steps.iter().enumerate() {
        let (Some((def, args)), Some(tc)) = (s.action.tc(), rec.steps.get(&s.id)) else {
            continue;
        };
        match &tc.outcome {
            ops::runs::Outcome::Completed => r.done.push(i),
            // Failed: it did not complete; it runs again as a new TC (on board: it stays
            // failed, the robot's plan holds there).
            ops::runs::Outcome::Failed(why) => r.failed.push((i, why.clone())),
            ops::runs::Outcome::Accepted | ops::runs::Outcome::NoReport => r.in_flight.push(ops::InFlight {
                step: i,
                tc: pus::BuiltTc {
                    def,
                    args,
                    apid: tc.apid,
                    seq: tc.seq,
                    bytes: tc.raw.clone(),
                },
                accepted: tc.outcome == ops::runs::Outcome::Accepted,
            }),
        }
    }
    // A wait step before a step that completed or was sent is done too.
    for (i, s) in pl.steps.iter().enumerate() {
        let started = |d: &usize| r.done.contains(d) || r.in_flight.iter().any(|f| f.step == *d);
        if s.action.tc().is_none() && pl.dependents(i).iter().any(started) {
            r.done.push(i);
        }
    }
    for f in &r.in_flight {
        let robot = pl.steps[f.step].robot;
        if !r.last_seq.iter().any(|(x, _)| *x == robot) {
            if let Some(seq) = ops::runs::last_tm_seq(&mut st, robot).map_err(|e| anyhow!("--resume: {e}"))? {
                r.last_seq.push((robot, seq));
            }
        }
    }
    err_line!(
        "resuming run {} of plan \"{}\" (first TC {}, last TC {}): {} step(s) completed, {} with an outcome to resolve",
        rec.run_id,
        pl.name,
        fmt_ms(rec.first_ms),
        fmt_ms(rec.last_ms),
        r.done.iter().filter(|&&i| pl.steps[i].action.tc().is_some()).count(),
        r.in_flight.len()
    );
    Ok((rec.run_id, r))
}

#[derive(Args, Debug)]
pub(crate) struct RunArgs {
    plan: PathBuf,
    #[command(flatten)]
    links: Links,
    /// Longest a step may take (seconds) unless the step sets `timeout`.
    #[arg(long, default_value_t = 120.0)]
    step_timeout: f64,
    /// No heartbeat connection tests (and so no link-loss watch).
    #[arg(long)]
    no_ping: bool,
    /// Plain log lines instead of the live display.
    #[arg(long)]
    plain: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Continue a run (the latest run of this plan in the archive, or RUN_ID): its
    /// completed steps are not sent again, a TC whose outcome is unknown is resolved
    /// from the robot's reports and on-board store before anything is sent.
    #[arg(long, value_name = "RUN_ID", num_args = 0..=1, default_missing_value = "")]
    resume: Option<String>,
    /// The robots run the plan themselves: it is compiled to one checksummed image per
    /// robot, uploaded (PLAN_LOAD, PLAN_COMMIT) and started (PLAN_START) once every robot
    /// accepted its image; the run then follows each step's reports as if it had sent them.
    /// With `--resume`, follows a plan already on board (what happened while the ground was
    /// away is read from the robots' stores).
    #[arg(long)]
    on_board: bool,
    /// With `--on-board`: exit once the robots have started (they carry on alone); follow
    /// later with `--on-board --resume`.
    #[arg(long, requires = "on_board")]
    detach: bool,
    /// After a first Ctrl-C, longest wait (seconds) for the steps in flight.
    #[arg(long, default_value_t = ground::ops::INTERRUPT_GRACE.as_secs_f64())]
    grace: f64,
}
