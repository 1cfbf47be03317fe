//! What a robot is made of and how its team stands, as the collector follows them
//! (issues 24 and 25). Pure: no I/O, times passed in.
//!
//! - [`ConfigTracker`]: the module configuration of one robot, from its module report
//!   TM[210,3] (asked for at link-up and after every reboot) and its MODULES
//!   housekeeping (SID 23: CONFIG_HASH, CONFIG_ID, CONFIG_STATUS, MODULES_PRESENT). A
//!   configuration hash that differs from the last one the collector saw — in this run or,
//!   through the archive, in an earlier one — is a [`Change`]: the collector raises the
//!   CONFIG_CHANGED alarm. It keeps the dashboard's [`ModuleView`]: every slot, present or
//!   absent, with its descriptor and whether it is the one an invalid set names or differs
//!   from the set seen before the change.
//! - [`team_view`]: the dashboard's view of a TEAM_STATUS report TM[211,2].

use mib::layout::{CONFIG_ID_NAMES, CONFIG_STATUS_NAMES, MODULE_REASON_NAMES, REPLACEMENT_NAMES, SLOT_NAMES};
use mib::modules::report::{ModuleReport, ReportError, NO_SLOT};
use mib::modules::{ModuleSet, SLOTS};

use crate::pus::TmBody;
use ground_dashboard::{ModuleView, SlotView, TeamView};

/// CONFIG_STATUS codes (`mib::layout::CONFIG_STATUS_NAMES`).
const STATUS_ACCEPTED: i64 = 1;
const STATUS_NOT_ACCEPTED: i64 = 2;
const STATUS_INVALID: i64 = 3;
/// Replacement code of a module report whose set differs from the accepted one.
const REPLACEMENT_CHANGED: u8 = 2;

/// The configuration hash as operators see it.
pub fn hash_text(h: u32) -> String {
    format!("0x{h:08x}")
}

fn name(names: mib::layout::Names, v: i64) -> String {
    names.name(v).map_or_else(|| format!("#{v}"), str::to_string)
}

/// The module HK of one report (SID 23), raw values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModulesHk {
    pub hash: u32,
    pub config_id: i64,
    pub status: i64,
    pub present: u16,
}

impl ModulesHk {
    /// The module parameters of a decoded HK report, when it carries CONFIG_HASH.
    pub fn of(hk: &crate::pus::Hk) -> Option<ModulesHk> {
        use mib::params::pid;
        Some(ModulesHk {
            hash: u32::try_from(hk.raw(pid::CONFIG_HASH)?).ok()?,
            config_id: hk.raw(pid::CONFIG_ID).unwrap_or(0),
            status: hk.raw(pid::CONFIG_STATUS).unwrap_or(0),
            present: hk
                .raw(pid::MODULES_PRESENT)
                .and_then(|p| u16::try_from(p).ok())
                .unwrap_or(0),
        })
    }
}

/// The robot's configuration hash changed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Change {
    pub from: u32,
    pub to: u32,
    /// For the alarm: the hashes, the new configuration and the slots that differ (when
    /// the collector holds both module reports).
    pub message: String,
}

/// What a module report did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReportOutcome {
    /// Sent before discovery finished (hash 0): the boot report follows; ask again.
    NotDiscovered,
    /// A checked report; `Some` when its hash differs from the last one seen.
    Report(Option<Change>),
}

/// One robot's module configuration as the collector follows it.
#[derive(Clone, Debug, Default)]
pub struct ConfigTracker {
    /// Last non-zero hash seen (module report or HK), also across collector restarts.
    last_hash: Option<u32>,
    /// The last checked report and its set.
    report: Option<ModuleReport>,
    /// The set of the report before the hash last changed (what "changed" compares with).
    baseline: Option<ModuleSet>,
    /// The report is to be asked for again (link-up, reboot, discovery events).
    want_report: bool,
    /// The slot the last MODULE_REPLACED event named (first slot differing from the
    /// configuration the ground accepted), while the set is not accepted.
    replaced_slot: Option<u8>,
    /// On-board time of the MODULE_REPLACED event that named it.
    replaced_t_ms: i64,
    view: ModuleView,
}

impl ConfigTracker {
    /// Starts from the last hash the archive holds (`None`: never seen).
    pub fn new(last_hash: Option<u32>) -> ConfigTracker {
        let mut t = ConfigTracker {
            last_hash: last_hash.filter(|h| *h != 0),
            ..Default::default()
        };
        t.view = ModuleView {
            hash: hash_text(t.last_hash.unwrap_or(0)),
            config: "?".into(),
            status: "?".into(),
            replacement: "?".into(),
            reason: "?".into(),
            ..Default::default()
        };
        t.rebuild_slots(None);
        t
    }

    pub fn last_hash(&self) -> Option<u32> {
        self.last_hash
    }

    /// True once a report with the robot's current hash is held (no need to ask).
    pub fn report_current(&self) -> bool {
        !self.want_report && matches!((&self.report, self.last_hash), (Some(r), Some(h)) if r.hash == h)
    }

    /// A MODULE_REPLACED event at on-board time `t_ms` named `slot` (255 or out of range:
    /// only calibration changed): shown `replaced` while the set is not accepted. An older
    /// event than the one applied (a replay from the store) changes nothing.
    pub fn on_replaced(&mut self, slot: i64, t_ms: i64) {
        if t_ms < self.replaced_t_ms {
            return;
        }
        self.replaced_t_ms = t_ms;
        self.replaced_slot = u8::try_from(slot).ok().filter(|s| (*s as usize) < SLOTS.len());
        if let Some(r) = self.report {
            self.rebuild_slots(Some(&r));
        }
    }

    /// The report held may no longer be the robot's (link-up, reboot, a discovery event):
    /// [`Self::report_current`] is false until the next report.
    pub fn forget_report(&mut self) {
        self.want_report = true;
    }

    pub fn view(&self) -> &ModuleView {
        &self.view
    }

    /// A module report's body (TM[210,3]) at on-board time `t_ms`.
    pub fn on_report(&mut self, body: &[u8], t_ms: i64) -> Result<ReportOutcome, ReportError> {
        let not_discovered = mib::modules::config::HASH_NOT_DISCOVERED.to_be_bytes();
        if body.get(..4).is_some_and(|h| h == not_discovered) {
            return Ok(ReportOutcome::NotDiscovered);
        }
        let r = ModuleReport::parse(body)?;
        self.want_report = false;
        if self.report.as_ref().is_some_and(|old| old.hash != r.hash) {
            self.baseline = self.report.map(|old| old.set);
        }
        self.report = Some(r);
        let change = self.seen(r.hash);
        self.view.config = if r.config == 0 {
            "NONE".into()
        } else {
            name(CONFIG_ID_NAMES, i64::from(r.config))
        };
        self.view.replacement = name(REPLACEMENT_NAMES, i64::from(r.replacement));
        self.view.reason = name(MODULE_REASON_NAMES, i64::from(r.reason));
        self.view.reason_slot = (r.reason_slot != NO_SLOT).then(|| name(SLOT_NAMES, i64::from(r.reason_slot)));
        // Until the next HK, the report's own state (the same rule as on board).
        self.view.status = name(
            CONFIG_STATUS_NAMES,
            if r.config == 0 {
                STATUS_INVALID
            } else if r.replacement == REPLACEMENT_CHANGED {
                STATUS_NOT_ACCEPTED
            } else {
                STATUS_ACCEPTED
            },
        );
        self.view.report_t_ms = Some(t_ms);
        self.rebuild_slots(Some(&r));
        Ok(ReportOutcome::Report(change.map(|(from, to)| self.change(from, to))))
    }

    /// The MODULES housekeeping at on-board time `t_ms`; `Some` when its hash differs
    /// from the last one seen (the collector then asks for the new module report).
    pub fn on_hk(&mut self, hk: ModulesHk, t_ms: i64) -> Option<Change> {
        self.view.status = name(CONFIG_STATUS_NAMES, hk.status);
        self.view.hk_t_ms = Some(t_ms);
        if hk.hash == mib::modules::config::HASH_NOT_DISCOVERED {
            return None;
        }
        let change = self.seen(hk.hash);
        if self.report.is_none_or(|r| r.hash != hk.hash) {
            // Not described by a report yet: what the HK says.
            self.view.config = if hk.config_id == 0 {
                "NONE".into()
            } else {
                name(CONFIG_ID_NAMES, hk.config_id)
            };
            // Which modules are present, not which ones: descriptors come with the report.
            for s in self.view.slots.iter_mut() {
                *s = SlotView {
                    present: hk.present & (1 << s.slot) != 0,
                    state: "?".into(),
                    ..slot_base(s.slot)
                };
            }
        }
        change.map(|(from, to)| self.change(from, to))
    }

    /// Records hash `h`; returns (old, new) when it differs from the last one seen.
    fn seen(&mut self, h: u32) -> Option<(u32, u32)> {
        let old = self.last_hash.replace(h);
        self.view.hash = hash_text(h);
        match old {
            Some(o) if o != h => {
                self.view.previous_hash = Some(hash_text(o));
                Some((o, h))
            }
            _ => None,
        }
    }

    fn change(&self, from: u32, to: u32) -> Change {
        let mut message = format!(
            "configuration hash {} -> {} ({})",
            hash_text(from),
            hash_text(to),
            self.view.config
        );
        let differ: Vec<String> = self
            .view
            .slots
            .iter()
            .filter(|s| s.state == "changed" || s.state == "invalid")
            .map(|s| format!("{} {}", s.name, if s.present { "changed" } else { "absent" }))
            .collect();
        if self.report.is_some_and(|r| r.hash == to) && !differ.is_empty() {
            message.push_str(": ");
            message.push_str(&differ.join(", "));
        }
        message.push_str(if self.view.status.is_empty() { "" } else { "; state " });
        message.push_str(&self.view.status);
        Change { from, to, message }
    }

    fn rebuild_slots(&mut self, r: Option<&ModuleReport>) {
        self.view.slots = SLOTS
            .iter()
            .map(|sd| {
                let mut v = slot_base(sd.id);
                let Some(r) = r else {
                    v.state = "?".into();
                    return v;
                };
                let d = r.set.get(sd.id as usize).copied().flatten();
                v.present = d.is_some();
                if let Some(d) = d {
                    v.variant = Some(d.variant);
                    v.revision = Some(d.revision);
                    v.serial = Some(d.serial);
                }
                let differs = self.baseline.as_ref().is_some_and(|b| {
                    let old = b.get(sd.id as usize).copied().flatten();
                    match (old, d) {
                        (Some(o), Some(n)) => (o.variant, o.revision, o.serial) != (n.variant, n.revision, n.serial),
                        (None, None) => false,
                        (Some(_), None) | (None, Some(_)) => true,
                    }
                });
                v.state = if r.config == 0 && r.reason_slot == sd.id {
                    "invalid"
                } else if r.replacement == REPLACEMENT_CHANGED && self.replaced_slot == Some(sd.id) {
                    "replaced"
                } else if differs {
                    "changed"
                } else if v.present {
                    "ok"
                } else {
                    "absent"
                }
                .into();
                v
            })
            .collect();
    }
}

fn slot_base(slot: u8) -> SlotView {
    let sd = SLOTS.get(slot as usize);
    SlotView {
        slot,
        name: name(SLOT_NAMES, i64::from(slot)),
        kind: sd.map_or("unknown", |s| s.ty.name()).to_string(),
        ..Default::default()
    }
}

/// The dashboard's view of a TEAM_STATUS report at on-board time `t_ms`.
pub fn team_view(body: &TmBody, t_ms: i64) -> Option<TeamView> {
    let Some(mib_wire::Tm::TeamStatus(r)) = body.report() else {
        return None;
    };
    Some(TeamView {
        term: r.term,
        role: name(mib::team::TEAM_ROLE_NAMES, i64::from(r.role)),
        leader: (r.leader != 0).then_some(r.leader),
        ground_seen: r.ground_seen != 0,
        lease: r.lease != 0,
        voted_for: (r.voted_for != 0).then_some(r.voted_for),
        roster: r.roster.iter().map(|m| m.robot).collect(),
        auth_steps: r.auth_steps,
        refused: r.refused,
        t_ms,
    })
}

/// Whether an event is one of the team's (0x0301–0x0307 and the team helper's range):
/// the collector then asks for the team status.
pub fn is_team_event(id: u16) -> bool {
    (0x0301..=0x030F).contains(&id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modules::config::config_hash;
    use mib::modules::{default_set, slot};

    fn report(set: ModuleSet, config: u8, replacement: u8) -> Vec<u8> {
        let r = ModuleReport {
            hash: config_hash(&set),
            config,
            reason: 0,
            reason_slot: NO_SLOT,
            replacement,
            set,
        };
        let mut buf = vec![0u8; mib::modules::report::MAX_REPORT_LEN];
        let n = r.emit(&mut buf).unwrap();
        buf.truncate(n);
        buf
    }

    fn locomotion() -> ModuleSet {
        let mut s = default_set(1000);
        s[slot::BOLTER_A as usize] = None;
        s[slot::BOLTER_B as usize] = None;
        s
    }

    // verifies: ALM-MODCFG-01
    #[test]
    fn a_new_hash_is_a_change_with_the_slots_that_differ() {
        let full = default_set(1000);
        let mut t = ConfigTracker::new(None);
        assert!(!t.report_current());
        assert_eq!(t.on_report(&report(full, 1, 0), 10), Ok(ReportOutcome::Report(None)));
        assert!(t.report_current());
        assert_eq!(t.view().config, "FULL");
        assert_eq!(t.view().status, "ACCEPTED");
        assert!(
            t.view().slots.iter().all(|s| s.present && s.state == "ok"),
            "{:?}",
            t.view().slots
        );
        assert_eq!(t.view().slots.len(), SLOTS.len());
        // The same report again: no change.
        assert_eq!(t.on_report(&report(full, 1, 0), 20), Ok(ReportOutcome::Report(None)));
        // Rebooted without bolters: the HK shows the new hash first.
        let loc = locomotion();
        let h = config_hash(&loc);
        let c = t
            .on_hk(
                ModulesHk {
                    hash: h,
                    config_id: 2,
                    status: 1,
                    present: 0x3FFF & !(1 << slot::BOLTER_A) & !(1 << slot::BOLTER_B),
                },
                30,
            )
            .expect("hash changed");
        assert_eq!((c.from, c.to), (config_hash(&full), h));
        assert!(!t.report_current(), "the new report is to be asked for");
        assert_eq!(t.view().config, "LOCOMOTION_ONLY");
        assert!(!t.view().slots[slot::BOLTER_A as usize].present);
        // Until the new report: presence from the HK, no descriptor of the old set.
        let arm = &t.view().slots[slot::ARM_A as usize];
        assert_eq!((arm.present, arm.serial, arm.state.as_str()), (true, None, "?"));
        // The report with that hash is no second change, and names the slots.
        let ReportOutcome::Report(None) = t.on_report(&report(loc, 2, 0), 40).unwrap() else {
            panic!("a second change for the same hash")
        };
        let v = t.view();
        assert_eq!(v.previous_hash.as_deref(), Some(hash_text(config_hash(&full)).as_str()));
        assert_eq!(v.slots[slot::BOLTER_B as usize].state, "changed");
        assert_eq!(v.slots[slot::ARM_A as usize].state, "ok");
        assert_eq!(
            v.slots[slot::ARM_A as usize].serial,
            Some(loc[slot::ARM_A as usize].unwrap().serial)
        );
        // Back to the full robot, this time seen in its report first.
        let ReportOutcome::Report(Some(c)) = t.on_report(&report(full, 1, 2), 50).unwrap() else {
            panic!("no change")
        };
        assert!(c.message.contains("BOLTER_A changed"), "{}", c.message);
        assert!(c.message.contains("NOT_ACCEPTED"), "{}", c.message);
        assert!(t
            .on_hk(
                ModulesHk {
                    hash: config_hash(&full),
                    config_id: 1,
                    status: 2,
                    present: 0x3FFF
                },
                60
            )
            .is_none());
        // MODULE_REPLACED named gripper A: it is the replaced one while not accepted.
        t.on_replaced(i64::from(slot::GRIPPER_A), 65);
        t.on_replaced(i64::from(slot::HIP), 64);
        assert_eq!(t.view().slots[slot::GRIPPER_A as usize].state, "replaced");
        t.on_report(&report(full, 1, 1), 70).unwrap();
        assert_eq!(
            t.view().slots[slot::GRIPPER_A as usize].state,
            "ok",
            "accepted: no longer replaced"
        );
    }

    // verifies: ALM-MODCFG-01
    #[test]
    fn the_last_archived_hash_counts_and_undiscovered_reports_are_no_change() {
        let full = default_set(1000);
        let mut t = ConfigTracker::new(Some(config_hash(&full)));
        assert_eq!(
            t.on_report(&[0, 0, 0, 0, 0, 0, 0xFF, 0, 0, 0, 0], 1),
            Ok(ReportOutcome::NotDiscovered)
        );
        assert!(t
            .on_hk(
                ModulesHk {
                    hash: 0,
                    config_id: 0,
                    status: 0,
                    present: 0
                },
                2
            )
            .is_none());
        assert_eq!(t.view().status, "NOT_DISCOVERED");
        let loc = locomotion();
        assert!(matches!(
            t.on_report(&report(loc, 2, 0), 3),
            Ok(ReportOutcome::Report(Some(_)))
        ));
        // A damaged report is refused, not taken.
        let mut bad = report(full, 1, 0);
        bad[20] ^= 1;
        assert!(t.on_report(&bad, 4).is_err());
        assert_eq!(t.last_hash(), Some(config_hash(&loc)));
    }

    // verifies: ALM-TEAMVIEW-01
    #[test]
    fn team_status_becomes_the_page_view() {
        use mib_wire::tm::{TeamStatus, TeamStatusRoster};
        let body = TmBody::Report(Box::new(mib_wire::Tm::TeamStatus(TeamStatus {
            term: 4,
            role: 2,
            leader: 3,
            ground_seen: 0,
            lease: 1,
            voted_for: 3,
            auth_plan: 0,
            auth_first_step: 0,
            auth_steps: 0,
            auth_left_s: 0,
            refused: 1,
            foreign: 0,
            roster: [1, 2, 3].map(|robot| TeamStatusRoster { robot }).into_iter().collect(),
        })));
        let v = team_view(&body, 99).unwrap();
        assert_eq!(
            (v.term, v.role.as_str(), v.leader, v.ground_seen),
            (4, "LEADER", Some(3), false)
        );
        assert_eq!(v.roster, vec![1, 2, 3]);
        assert!(team_view(
            &TmBody::Report(Box::new(mib_wire::Tm::PingReply(mib_wire::tm::PingReply {}))),
            1
        )
        .is_none());
        assert!(is_team_event(mib::events::eid::LEADER_ELECTED) && !is_team_event(mib::events::eid::BOOT));
    }
}
