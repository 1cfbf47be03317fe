//! On-board plans (PUS 18, on-board operations procedures): the limits of a plan a robot
//! holds, the layout of its compact checksummed image, the state codes reported in
//! housekeeping and the inter-robot progress announcement. The format is read and written
//! by one crate, `mmic-plan` (obsw/plan), for the ground's compiler and the robot alike;
//! docs/plan-format.md ("On board") explains it for operators.
//!
//! ## Image (big-endian)
//!
//! | off | len | field |
//! |-----|-----|-------|
//! | 0   | 2   | magic [`MAGIC`] |
//! | 2   | 1   | format version [`VERSION`] |
//! | 3   | 1   | robot number the image is for |
//! | 4   | 4   | plan ID: the same in every robot's image of one plan (it names the plan in progress announcements) |
//! | 8   | 1   | step count (1..=[`MAX_STEPS`]) |
//! | 9   | ... | steps |
//! | end-4 | 4 | CRC-32 (ISO-HDLC) of every byte before it |
//!
//! A step: `flags u8` ([`flag`]), `timeout_s u16` (0: [`DEFAULT_STEP_TIMEOUT_S`]),
//! `deps u8` (0..=[`MAX_DEPS`]) then per dependency `robot u8, step u8` (the step, 0-based
//! in that robot's image, must have completed), then for a TC step `len u8` and the
//! complete TC (space packet with its CRC, at most [`MAX_STEP_TC_LEN`] bytes), for a wait
//! step `wait_ms u32`.

/// Magic of a plan image ("PL").
pub const MAGIC: [u8; 2] = *b"PL";
/// Version of the image format.
pub const VERSION: u8 = 1;
/// Length of the image header (magic to step count).
pub const HEADER_LEN: usize = 9;
/// Length of the trailing CRC-32.
pub const CRC_LEN: usize = 4;
/// Most steps one robot's image holds.
pub const MAX_STEPS: usize = 32;
/// Most dependencies of one step.
pub const MAX_DEPS: usize = 4;
/// Largest TC a step carries (the schedule's limit: the same TCs).
pub const MAX_STEP_TC_LEN: usize = crate::config::MAX_SCHEDULED_TC_LEN;
/// Largest step: flags, timeout, dependency count, dependencies, TC length and TC.
pub const MAX_STEP_LEN: usize = 1 + 2 + 1 + 2 * MAX_DEPS + 1 + MAX_STEP_TC_LEN;
/// Largest image the robot holds (RAM on board: one staging buffer and one loaded plan).
pub const MAX_IMAGE_LEN: usize = 1024;
/// Most image bytes one PLAN_LOAD TC carries.
pub const MAX_CHUNK: usize = 200;
/// Timeout of a step whose image says 0 (the plan file's default).
pub const DEFAULT_STEP_TIMEOUT_S: u16 = 120;
/// Longest wait step.
pub const MAX_WAIT_MS: u32 = 86_400_000;
/// A robot running a plan announces its completed steps to the team this often (and at
/// once after each step): a lost announcement is repeated, a late one changes nothing
/// (progress only grows).
pub const PROGRESS_PERIOD_MS: u64 = 500;
/// Most peers whose progress a robot tracks (the team roster's size).
pub const MAX_PEERS: usize = crate::team::ROSTER_MAX;

// Every step fits a chunk-sized slice of the image, and an image fits a few TCs.
const _: () = assert!(MAX_STEP_LEN <= MAX_CHUNK);
const _: () = assert!(MAX_IMAGE_LEN <= u16::MAX as usize && MAX_CHUNK <= u8::MAX as usize);
const _: () = assert!(MAX_STEPS <= u8::MAX as usize);

/// Step flags.
pub mod flag {
    /// The step is a wait (`wait_ms`), not a TC.
    pub const WAIT: u8 = 0x01;
    /// The operator confirmed the step's hazardous TC when the plan was written and
    /// uploaded (`confirm = true`); a hazardous TC without it is refused at PLAN_COMMIT.
    pub const CONFIRMED: u8 = 0x02;
    /// Every flag this version defines (any other bit set: the image is refused).
    pub const ALL: u8 = WAIT | CONFIRMED;
}

crate::named_codes! {
    /// Names of the plan states.
    STATE_NAMES;
    /// Plan states (HK PLAN_STATE, PLAN_STATUS report, PLAN_STATE_CHANGED event).
    pub mod state {
        /// No plan loaded.
        pub const EMPTY: u8 = 0;
        /// A plan is loaded and checked, not started.
        pub const LOADED: u8 = 1;
        /// Running: a step is executing, or the next waits for its dependencies or its time.
        pub const RUNNING: u8 = 2;
        /// Suspended by a failed step, a fault or PLAN_SUSPEND: nothing new starts.
        pub const SUSPENDED: u8 = 3;
        /// Every step completed.
        pub const COMPLETED: u8 = 4;
        /// Aborted by PLAN_ABORT: nothing new starts; load a plan to run again.
        pub const ABORTED: u8 = 5;
    }
}

crate::named_codes! {
    /// Names of the causes.
    CAUSE_NAMES;
    /// Why a plan changed state (PLAN_STATE_CHANGED `cause`).
    pub mod cause {
        /// A control TC (start, suspend, resume, abort, skip, load).
        pub const COMMAND: u8 = 0;
        /// The step's TC was refused or its action failed (the step's PUS 1 failure report
        /// names the code).
        pub const STEP_FAILED: u8 = 1;
        /// The step did not complete within its timeout.
        pub const STEP_TIMEOUT: u8 = 2;
        /// FDIR raised a fault while the plan ran.
        pub const FAULT: u8 = 3;
        /// The last step completed.
        pub const DONE: u8 = 4;
        /// The plan's progress was restored after a restart: the step that was running when
        /// the robot reset has an unknown outcome, so the plan waits for the ground.
        pub const RESTART: u8 = 5;
    }
}

crate::named_codes! {
    /// Names of the image refusal reasons.
    INVALID_NAMES;
    /// Why a plan image was refused (PLAN_INVALID `reason`).
    pub mod invalid {
        /// Wrong magic or format version.
        pub const FORMAT: u8 = 0;
        /// Shorter than its content says, or bytes left after the last step.
        pub const LENGTH: u8 = 1;
        /// A step count of 0 or above `MAX_STEPS`, or more than `MAX_DEPS` dependencies.
        pub const LIMITS: u8 = 2;
        /// Unknown flag bits, a wait beyond `MAX_WAIT_MS`, a TC longer than `MAX_STEP_TC_LEN`.
        pub const STEP: u8 = 3;
        /// A dependency on a later step of this robot, on itself, or on robot 0.
        pub const DEPENDENCY: u8 = 4;
    }
}

/// PUS 18 subservices (TCs and the status report).
pub mod sub {
    pub const LOAD: u8 = 1;
    pub const COMMIT: u8 = 2;
    pub const START: u8 = 3;
    pub const SUSPEND: u8 = 4;
    pub const RESUME: u8 = 5;
    pub const ABORT: u8 = 6;
    pub const SKIP: u8 = 7;
    pub const STATUS_REQUEST: u8 = 8;
    /// TM: the plan status report.
    pub const STATUS: u8 = 9;
}

/// Team subservice of a plan progress announcement between robots (TM[211,7] on the
/// team APID): `plan_id u32, robot u8, done u8` — the sender has completed the first
/// `done` steps of its image of plan `plan_id`. The sender is the authenticated one.
pub const TEAM_SUBSERVICE_PROGRESS: u8 = 7;
/// Length of a progress announcement's application data.
pub const PROGRESS_LEN: usize = 6;

/// Length of the PLAN_STATUS report's source data: plan ID (4), state (1), steps (1),
/// next step (1), steps done (1), waiting on robot (1), waiting on step (1).
pub const STATUS_LEN: usize = 10;
