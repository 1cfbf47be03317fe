//! `ground run --on-board`: the plan's images uploaded (PLAN_LOAD chunks, PLAN_COMMIT),
//! then started on every robot (PLAN_START) only once every robot has committed its
//! image: a refusal anywhere means nothing moves. Each control TC is sent and awaited
//! through the session like any other TC (resends, reports); the reports of the plan's
//! own steps that arrive meanwhile are handed back for the executor.

use std::time::{Duration, Instant};

use crate::plan::onboard::Compiled;
use crate::pus::BuiltTc;

use super::{failure_words, Session, Update};

/// Longest wait for one control TC's completion.
const CONTROL_WAIT: Duration = Duration::from_secs(30);
/// How often a control TC's missing reports are asked of the on-board store (the MIB's
/// gap-check periods, as `ground send` does).
const GAP_CHECK_PERIOD: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_MS as u64);
const GAP_CHECK_PERIOD_FRAMES: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_FRAMES_MS as u64);

/// What was done for the plan on board.
#[derive(Clone, Debug)]
pub struct OnBoard {
    pub compiled: Compiled,
    /// Upload and start (false: a `--resume` of a plan already running on board).
    pub upload: bool,
    /// Stop following once every robot has started (the robots carry on alone).
    pub detach: bool,
}

/// Sends `def(args) + tail` to `robot` and waits for its completion; the other updates
/// are kept in `early`.
fn control(
    session: &mut Session,
    robot: u8,
    name: &str,
    args: &[i64],
    tail: &[u8],
    early: &mut Vec<Update>,
) -> Result<BuiltTc, String> {
    let def = mib::tc::by_name(name).ok_or_else(|| format!("{name} is not a TC of the MIB"))?;
    let tc = session
        .send_with_tail(robot, def, args, tail, Some("on-board plan".into()))
        .map_err(|e| format!("robot {robot}: {name}: {e}"))?;
    let rid = tc.request_id();
    let t0 = Instant::now();
    let mut accepted = false;
    let mut last_gap_check = Instant::now();
    while t0.elapsed() < CONTROL_WAIT {
        // An accepted TC is not resent: its completion report lost on the way is a TM gap,
        // asked of the on-board store (over frames also once a CLCW acknowledged the TC's
        // frame: it reached the robot, its acceptance may be the report lost).
        let (period, delivered) = if session.over_frames() {
            (GAP_CHECK_PERIOD_FRAMES, session.delivered(robot, &tc))
        } else {
            (GAP_CHECK_PERIOD, false)
        };
        if (accepted || delivered) && last_gap_check.elapsed() >= period && session.may_retrieve(robot) {
            last_gap_check = Instant::now();
            session.request_reports_of(robot, &tc, 1);
        }
        // The whole batch is looked at before the outcome is returned: the updates after
        // it (a step's completion replayed from the store with the control TC's own) are
        // kept for the executor, never dropped.
        let mut outcome = None;
        for u in session.poll(Duration::from_millis(50)) {
            match &u {
                Update::Verification { v, .. } if v.request == rid && outcome.is_none() => {
                    if !v.success {
                        outcome = Some(Err(format!("robot {robot}: {name} refused: {}", failure_words(v))));
                    } else if v.stage == crate::pus::Stage::Completion {
                        outcome = Some(Ok(tc.clone()));
                    } else if v.stage == crate::pus::Stage::Acceptance && !accepted {
                        accepted = true;
                        last_gap_check = Instant::now();
                    }
                }
                Update::GaveUp { robot: r, tc: n, .. }
                    if *r == robot && *n == def.name && !session.is_pending(&tc) && outcome.is_none() =>
                {
                    outcome = Some(Err(format!("robot {robot}: {name}: no answer")));
                }
                _ => early.push(u),
            }
        }
        if let Some(o) = outcome {
            return o;
        }
    }
    Err(format!(
        "robot {robot}: {name}: no completion within {} s",
        CONTROL_WAIT.as_secs()
    ))
}

/// Uploads and commits every image, then starts every robot. Returns the updates seen
/// meanwhile, and the first refusal or TC without an outcome, which names the robots
/// whose PLAN_START had completed before it (none when the upload failed).
pub fn upload_and_start(session: &mut Session, c: &Compiled) -> (Vec<Update>, Result<(), String>) {
    let mut early = Vec::new();
    let mut started: Vec<String> = Vec::new();
    let r = (|| {
        for img in &c.images {
            for (k, chunk) in img.bytes.chunks(mib::plan::MAX_CHUNK).enumerate() {
                let offset = (k * mib::plan::MAX_CHUNK) as i64;
                control(
                    session,
                    img.robot,
                    "PLAN_LOAD",
                    &[offset, chunk.len() as i64],
                    chunk,
                    &mut early,
                )?;
            }
            control(
                session,
                img.robot,
                "PLAN_COMMIT",
                &[img.bytes.len() as i64, i64::from(img.crc())],
                &[],
                &mut early,
            )?;
        }
        for img in &c.images {
            control(
                session,
                img.robot,
                "PLAN_START",
                &[i64::from(c.plan_id)],
                &[],
                &mut early,
            )?;
            started.push(img.robot.to_string());
        }
        Ok(())
    })();
    let r = r.map_err(|why: String| {
        if started.is_empty() {
            format!("{why}; nothing was started")
        } else {
            format!(
                "{why}; robot {} had started its plan (ground plan status|abort --robot N)",
                started.join(", ")
            )
        }
    });
    (early, r)
}
