//! What a run reports at its end.

use mib::headers::SeqCount;
use serde::Serialize;

/// Fastener pairs by the attempt that locked them (paper statistics).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct BoltStats {
    pub first: u32,
    pub second: u32,
    pub third: u32,
    pub later: u32,
    pub failed: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct StepOutcome {
    pub id: String,
    pub robot: u8,
    pub action: String,
    pub result: String,
    pub reason: Option<String>,
    pub seconds: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct LinkSummary {
    pub robot: u8,
    pub quality: Option<f64>,
    pub exchanges: usize,
    pub tm: u64,
    pub corrupt: u64,
    /// TM packets received twice (same APID and sequence count), acted on once.
    pub duplicates: u64,
    /// Sequence counts never received (inclusive ranges).
    pub tm_missing: Vec<(u16, u16)>,
    /// Sequence counts that arrived after later ones (late or replayed).
    pub tm_late: u64,
    /// Why the link was lost, if it was.
    pub lost: Option<String>,
    /// Packet resends by the ground (bare-packet links; always 0 over frames).
    pub resends: u32,
    /// What COP-1 did, over frames.
    pub frames: Option<crate::link::FrameStats>,
}

#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub plan: String,
    /// The run's ID (archived with every TC it sent); `--resume` continues it.
    pub run_id: Option<String>,
    /// The operator interrupted the run (Ctrl-C or SIGTERM).
    pub interrupted: bool,
    /// Steps still running on board when the run ended (after an interruption).
    pub in_flight: usize,
    pub steps: Vec<StepOutcome>,
    pub done: usize,
    pub failed: usize,
    pub blocked: usize,
    /// Steps completed in an earlier run (`--resume`), not sent again.
    pub resumed: usize,
    pub bolts: BoltStats,
    pub unbolted_pairs: u32,
    pub faults: Vec<String>,
    pub link_lost: Vec<String>,
    pub links: Vec<LinkSummary>,
    /// Completeness of each robot's TM at the end (after gap retrieval).
    pub tm: Vec<TmCompleteness>,
    pub seconds: f64,
}

impl RunSummary {
    fn lost_lines(&self) -> Vec<String> {
        self.link_lost.clone()
    }
    pub fn success(&self) -> bool {
        self.failed == 0 && self.blocked == 0 && self.link_lost.is_empty() && !self.interrupted
    }
    /// Human-readable summary.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        if let Some(r) = &self.run_id {
            let _ = writeln!(s, "run {r}");
        }
        let _ = writeln!(
            s,
            "plan {}: {} of {} steps done, {} failed, {} blocked, in {:.1} s",
            self.plan,
            self.done,
            self.steps.len(),
            self.failed,
            self.blocked,
            self.seconds
        );
        if self.interrupted {
            let _ = writeln!(
                s,
                "INTERRUPTED: no new step was sent after the interruption; {} step(s) still running on board{}",
                self.in_flight,
                self.run_id.as_ref().map_or(String::new(), |r| format!(
                    "; continue with `ground run PLAN --resume {r}`"
                ))
            );
        }
        for o in &self.steps {
            let _ = writeln!(
                s,
                "  {:<8} {:<22} robot {:<3} {:<34} {}",
                o.result,
                o.id,
                o.robot,
                o.action,
                o.reason
                    .clone()
                    .unwrap_or_else(|| o.seconds.map_or(String::new(), |t| format!("{t:.1} s")))
            );
        }
        let b = &self.bolts;
        let _ = writeln!(
            s,
            "bolts per attempt: 1st {}, 2nd {}, 3rd {}, later {}, failed {}; pairs unbolted {}",
            b.first, b.second, b.third, b.later, b.failed, self.unbolted_pairs
        );
        if self.faults.is_empty() {
            let _ = writeln!(s, "faults: none");
        } else {
            let _ = writeln!(s, "faults:");
            for f in &self.faults {
                let _ = writeln!(s, "  {f}");
            }
        }
        if self.resumed > 0 {
            let _ = writeln!(s, "resumed: {} steps completed in an earlier run", self.resumed);
        }
        for l in &self.lost_lines() {
            let _ = writeln!(s, "LINK LOST: {l}");
        }
        for l in &self.links {
            let _ = writeln!(
                s,
                "link robot {}: quality {} over {} exchanges, {} TM ({} duplicates dropped, {} late), {} corrupt, {} resends",
                l.robot,
                l.quality.map_or("-".into(), |q| format!("{:.0}%", q * 100.0)),
                l.exchanges,
                l.tm,
                l.duplicates,
                l.tm_late,
                l.corrupt,
                l.resends
            );
            if let Some(f) = &l.frames {
                let _ = writeln!(
                    s,
                    "frames robot {}: {} TC packets, {} acknowledged by CLCW, {} AD frames ({} COP-1 retransmissions), {} initialisations, {} alerts, {} TM frames refused",
                    l.robot,
                    f.packets,
                    f.acknowledged,
                    f.ad_frames,
                    f.retransmissions,
                    f.initialisations,
                    f.alerts,
                    f.tm_refused
                );
            }
        }
        for c in &self.tm {
            let _ = writeln!(s, "{}", c.line());
        }
        s
    }
}

/// The state of a robot's TM at the end of a run.
#[derive(Clone, Debug, Serialize)]
pub struct TmCompleteness {
    pub robot: u8,
    /// Every sequence count from this one (the start marker's first report) ...
    pub from: Option<u16>,
    /// ... up to this one (the end marker's report) was checked.
    pub upto: Option<u16>,
    /// Missing counts overwritten in the on-board store (unrecoverable).
    pub overwritten: Vec<(u16, u16)>,
    /// Missing counts still not received after the retrieval rounds.
    pub not_received: Vec<(u16, u16)>,
    /// Store retrievals sent at the end of the run.
    pub retrievals: u32,
}

impl TmCompleteness {
    pub fn complete(&self) -> bool {
        self.upto.is_some() && self.overwritten.is_empty() && self.not_received.is_empty()
    }
    /// One line for the summary.
    pub fn line(&self) -> String {
        let count = |v: &[(u16, u16)]| -> u32 {
            v.iter()
                .map(|(a, b)| u32::from(SeqCount::new(*b).since(SeqCount::new(*a))) + 1)
                .sum()
        };
        let list = |v: &[(u16, u16)]| -> String {
            let mut l: Vec<String> = v
                .iter()
                .take(8)
                .map(|(a, b)| if a == b { format!("{a}") } else { format!("{a}-{b}") })
                .collect();
            if v.len() > 8 {
                l.push("...".into());
            }
            l.join(", ")
        };
        match self.upto {
            None => format!("TM robot {}: completeness unknown (no end marker answered)", self.robot),
            Some(u) if self.complete() => format!(
                "TM robot {}: complete from seq {} up to seq {u} ({} store retrievals at the end)",
                self.robot,
                self.from.map_or("?".into(), |f| f.to_string()),
                self.retrievals
            ),
            Some(u) => format!(
                "TM robot {}: up to seq {u}: {} packets unrecoverable (overwritten on board: {}), {} not received after {} retrievals ({})",
                self.robot,
                count(&self.overwritten),
                list(&self.overwritten),
                count(&self.not_received),
                self.retrievals,
                list(&self.not_received)
            ),
        }
    }
}
