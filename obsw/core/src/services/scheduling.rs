//! PUS 11 time-based scheduling: TCs uploaded with a release time (TC[11,4]) run on
//! board when their time comes, through the same path as uplinked TCs.

use mib::config;
use mib::tc::service;
use mib::FailureCode;

use crate::accept::{accept, Tc, PRIMARY_LEN};
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::{unknown, Ctx};
use crate::tm::{TmSink, TmStore};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request<'a> {
    /// TC[11,1]
    Enable,
    /// TC[11,2]
    Disable,
    /// TC[11,3]: delete every scheduled TC.
    Reset,
    /// TC[11,4]: `count` activities, each checked at acceptance (release time in the
    /// future, a valid TC for this robot that fits a schedule entry).
    Insert { count: u8, activities: &'a [u8] },
}

impl<'a> Request<'a> {
    pub fn parse(tc: &Tc<'a>, ctx: &Ctx) -> Result<Self, Failure> {
        Ok(match tc.subservice {
            1 => Request::Enable,
            2 => Request::Disable,
            3 => Request::Reset,
            4 => {
                let count = tc.args[0] as u8;
                check_activities(count, tc.rest, ctx)?;
                Request::Insert {
                    count,
                    activities: tc.rest,
                }
            }
            _ => return Err(unknown(tc)),
        })
    }
}

/// Walks the activities of a TC[11,4]: per activity a CDS short release time and a
/// complete TC for this robot.
fn check_activities(count: u8, mut rest: &[u8], ctx: &Ctx) -> Result<(), Failure> {
    if count as usize > ctx.sched_free {
        return Err(Failure::schedule_full(config::SCHEDULE_CAPACITY));
    }
    for i in 0..count {
        let Some((release, inner, tail)) = split_activity(rest) else {
            return Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET));
        };
        let Some(at) = ctx.time.from_cds(release) else {
            return Err(Failure::release_time_passed(0));
        };
        if at <= ctx.now {
            return Err(Failure::release_time_passed(at));
        }
        if inner.len() > config::MAX_SCHEDULED_TC_LEN {
            return Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET));
        }
        match accept(inner, ctx.apid) {
            Err(r) => return Err(Failure::scheduled_tc_invalid(r.code())),
            // Schedules do not nest: a released TC[11,4] would insert activities that
            // were never checked against the schedule as it is then.
            Ok(t) if t.service == service::SCHEDULING && t.subservice == 4 => {
                return Err(Failure::nested_schedule(i));
            }
            Ok(_) => {}
        }
        rest = tail;
    }
    if !rest.is_empty() {
        return Err(Failure::scheduled_tc_invalid(FailureCode::BAD_ARG_LENGTH));
    }
    Ok(())
}

/// Splits one TC[11,4] activity: 7-byte CDS release time, then a TC whose length comes
/// from its own primary header.
fn split_activity(data: &[u8]) -> Option<(&[u8], &[u8], &[u8])> {
    let t = config::TIMESTAMP_LEN;
    if data.len() < t + PRIMARY_LEN {
        return None;
    }
    let (release, rest) = data.split_at(t);
    let len = PRIMARY_LEN + u16::from_be_bytes([rest[4], rest[5]]) as usize + 1;
    if rest.len() < len {
        return None;
    }
    let (tc, tail) = rest.split_at(len);
    Some((release, tc, tail))
}

struct Scheduled {
    release: u64,
    tc: heapless::Vec<u8, { config::MAX_SCHEDULED_TC_LEN }>,
}

/// The time-based schedule.
pub struct Schedule {
    items: heapless::Vec<Scheduled, { config::SCHEDULE_CAPACITY }>,
    pub enabled: bool,
}

impl Schedule {
    pub fn new() -> Self {
        Schedule {
            items: heapless::Vec::new(),
            enabled: true,
        }
    }
    pub fn len(&self) -> usize {
        self.items.len()
    }
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
    pub fn free(&self) -> usize {
        config::SCHEDULE_CAPACITY - self.items.len()
    }
    /// The earliest release time, if releases are enabled.
    pub fn next_release(&self) -> Option<u64> {
        self.enabled
            .then(|| self.items.iter().map(|s| s.release).min())
            .flatten()
    }
}

impl Default for Schedule {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: TmStore> Obsw<S> {
    pub(crate) fn scheduling_request(&mut self, r: Request) -> Result<(), Failure> {
        match r {
            Request::Enable => self.sched.enabled = true,
            Request::Disable => self.sched.enabled = false,
            Request::Reset => self.sched.items.clear(),
            Request::Insert { count, activities } => {
                let mut rest = activities;
                for _ in 0..count {
                    // Every activity was checked at acceptance.
                    let Some((release, inner, tail)) = split_activity(rest) else {
                        return Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET));
                    };
                    let at = self
                        .dl
                        .tmw
                        .time
                        .from_cds(release)
                        .ok_or(Failure::release_time_passed(0))?;
                    let mut tc = heapless::Vec::new();
                    tc.extend_from_slice(inner)
                        .map_err(|_| Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET))?;
                    self.sched
                        .items
                        .push(Scheduled { release: at, tc })
                        .map_err(|_| Failure::schedule_full(config::SCHEDULE_CAPACITY))?;
                    rest = tail;
                }
            }
        }
        Ok(())
    }

    /// Runs every scheduled TC whose release time has come.
    pub(crate) fn release_schedule(&mut self, now: u64, sink: &mut impl TmSink) {
        if !self.sched.enabled {
            return;
        }
        while let Some(i) = self.sched.items.iter().position(|s| s.release <= now) {
            let s = self.sched.items.swap_remove(i);
            self.handle_onboard_tc(now, &s.tc, sink);
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::accept::tests::tc_bytes;
    use crate::obsw::tests::{failure, obsw, of, send, APID};
    use mib::FailureCode;

    fn insert(o: &crate::obsw::tests::TestObsw, at: u64, inner: &[u8]) -> Vec<u8> {
        let mut app = vec![1u8];
        app.extend_from_slice(&o.dl.tmw.time.cds(at));
        app.extend_from_slice(inner);
        app
    }

    // verifies: PUS-11-01
    #[test]
    fn a_scheduled_ping_runs_at_its_release_time() {
        let mut o = obsw();
        let app = insert(&o, 500, &tc_bytes(APID, 77, 17, 1, &[]));
        send(&mut o, 10, 1, 11, 4, &app);
        assert_eq!(o.sched.len(), 1);
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.release_schedule(499, &mut sink);
        assert!(sink.is_empty());
        o.release_schedule(500, &mut sink);
        assert_eq!(of(&sink, 17, 2).len(), 1);
    }

    // verifies: PUS-11-02
    #[test]
    fn a_schedule_inside_a_schedule_is_refused_with_the_activity_index() {
        let mut o = obsw();
        let inner_ping = tc_bytes(APID, 70, 17, 1, &[]);
        let nested = tc_bytes(APID, 71, 11, 4, &insert(&o, 900, &inner_ping));
        let mut app = vec![2u8];
        for inner in [&inner_ping, &nested] {
            app.extend_from_slice(&o.dl.tmw.time.cds(500));
            app.extend_from_slice(inner);
        }
        let pkts = send(&mut o, 10, 1, 11, 4, &app);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::NESTED_SCHEDULE.code(), vec![1])
        );
        assert_eq!(o.sched.len(), 0, "nothing inserted");
    }

    // verifies: PUS-11-02
    #[test]
    fn a_release_time_in_the_past_is_refused_with_it() {
        let mut o = obsw();
        send(&mut o, 1000, 1, 17, 1, &[]);
        let app = insert(&o, 400, &tc_bytes(APID, 77, 17, 1, &[]));
        let pkts = send(&mut o, 1000, 2, 11, 4, &app);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::RELEASE_TIME_PASSED.code(), 400u32.to_be_bytes().to_vec())
        );
    }
}
