//! PUS 11 time-based scheduling: TCs uploaded with a release time (TC[11,4]) run on
//! board when their time comes, through the same path as uplinked TCs.

use mib::config;
use mib::params::{pid, NotSupplied, Source, Supplied};
use mib::tc::{sched_cuc, service};
use mib::FailureCode;

use crate::accept::{accept, Tc, PRIMARY_LEN};
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::{unknown, Ctx};
use crate::services::{Component, Contract};
use crate::time::OnboardTime;
use crate::tm::{TmSink, TmStore};

/// The two forms of TC[11,4] (`mib::tc::sched_cuc`): the MIB's own (N, CDS release
/// times with their P-field) and Yamcs' (sub-schedule ID, N, CUC release times with an
/// implicit P-field).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    Cds,
    Cuc,
}

impl Form {
    /// Length of an activity's release time.
    fn time_len(self) -> usize {
        match self {
            Form::Cds => config::TIMESTAMP_LEN,
            Form::Cuc => sched_cuc::TIME_LEN,
        }
    }

    /// On-board time (ms since boot) of a release time of this form, or `None` if it is
    /// malformed or before boot.
    fn release_at(self, stamp: &[u8], time: &OnboardTime) -> Option<u64> {
        match self {
            Form::Cds => time.from_cds(stamp),
            Form::Cuc => cuc_unix_ms(stamp)?.checked_sub(time.epoch_unix_ms),
        }
    }
}

/// Unix ms of a Yamcs CUC release time (`sched_cuc`: seconds since 1970 counting leap
/// seconds, 16-bit binary fraction). Yamcs truncates its ms to the fraction, so rounding
/// the fraction up gives its ms back exactly.
fn cuc_unix_ms(stamp: &[u8]) -> Option<u64> {
    let (c, f) = (sched_cuc::COARSE_LEN, sched_cuc::FINE_LEN);
    if stamp.len() != c + f {
        return None;
    }
    let coarse = stamp[..c].iter().fold(0u64, |a, b| (a << 8) | *b as u64);
    let fine = stamp[c..].iter().fold(0u64, |a, b| (a << 8) | *b as u64);
    let den = 1u64 << (8 * f);
    let ms = (fine * 1000).div_ceil(den);
    (coarse * 1000 + ms).checked_sub(sched_cuc::TAI_MINUS_UTC_S * 1000)
}

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
    Insert {
        form: Form,
        count: u8,
        activities: &'a [u8],
    },
}

impl<'a> Request<'a> {
    pub fn parse(tc: &Tc<'a>, ctx: &Ctx) -> Result<Self, Failure> {
        Ok(match tc.subservice {
            1 => Request::Enable,
            2 => Request::Disable,
            3 => Request::Reset,
            4 => {
                let (form, count, activities) = insert_form(tc)?;
                check_activities(form, count, activities, ctx)?;
                Request::Insert {
                    form,
                    count,
                    activities,
                }
            }
            _ => return Err(unknown(tc)),
        })
    }
}

/// Which form a TC[11,4] has, its N and its activities. The MIB's first argument is N in
/// the CDS form and the sub-schedule ID in Yamcs' form; the second octet tells them apart.
fn insert_form<'a>(tc: &Tc<'a>) -> Result<(Form, u8, &'a [u8]), Failure> {
    let first = mib_wire::args::SchedInsert::of(&tc.args).count;
    match tc.rest.split_first() {
        Some((&mark, _)) if mark == sched_cuc::CDS_FORM_MARK => Ok((Form::Cds, first, tc.rest)),
        Some((&n, activities)) => {
            if first != sched_cuc::SUB_SCHEDULE_ID {
                return Err(Failure::arg_out_of_range(0, first as i32));
            }
            if n == 0 || n as usize > config::SCHEDULE_CAPACITY {
                return Err(Failure::arg_out_of_range(1, n as i32));
            }
            Ok((Form::Cuc, n, activities))
        }
        None => Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET)),
    }
}

/// Walks the activities of a TC[11,4]: per activity a release time of the form and a
/// complete TC for this robot.
fn check_activities(form: Form, count: u8, mut rest: &[u8], ctx: &Ctx) -> Result<(), Failure> {
    if count as usize > ctx.sched_free {
        return Err(Failure::schedule_full(config::SCHEDULE_CAPACITY));
    }
    for i in 0..count {
        let Some((release, inner, tail)) = split_activity(form, rest) else {
            return Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET));
        };
        let Some(at) = form.release_at(release, &ctx.time) else {
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

/// Splits one TC[11,4] activity: the form's release time, then a TC whose length comes
/// from its own primary header.
fn split_activity(form: Form, data: &[u8]) -> Option<(&[u8], &[u8], &[u8])> {
    let t = form.time_len();
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

/// A scheduled TC's bytes.
pub type ScheduledTc = heapless::Vec<u8, { config::MAX_SCHEDULED_TC_LEN }>;

struct Scheduled {
    release: u64,
    tc: ScheduledTc,
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
    /// The parameters the MIB names the schedule the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(match id {
            pid::SCHED_COUNT => self.len() as i64,
            pid::SCHED_ENABLED => i64::from(self.enabled),
            _ => return Err(NotSupplied(id)),
        }))
    }
}

impl Default for Schedule {
    fn default() -> Self {
        Self::new()
    }
}

/// Applies a request; an insert takes release times in the on-board time (the
/// downlink's, the one every report is stamped with). Released TCs go back through the
/// TC path (`Obsw::release_schedule`).
impl Component for Schedule {
    const CONTRACT: Contract = Contract::new("scheduling", Some(service::SCHEDULING), &[Source::Scheduler]);
    type Request<'a> = Request<'a>;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        _now: u64,
        r: Request<'_>,
        dl: &mut Downlink<S>,
        _sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        self.request(r, &dl.tmw.time)
    }
}

impl Schedule {
    /// Applies a request, the same for every sink and store the obsw is built with, so
    /// kept out of line (one copy on board A).
    #[inline(never)]
    fn request(&mut self, r: Request<'_>, time: &OnboardTime) -> Result<(), Failure> {
        match r {
            Request::Enable => self.enabled = true,
            Request::Disable => self.enabled = false,
            Request::Reset => self.items.clear(),
            Request::Insert {
                form,
                count,
                activities,
            } => {
                let mut rest = activities;
                for _ in 0..count {
                    // Every activity was checked at acceptance.
                    let Some((release, inner, tail)) = split_activity(form, rest) else {
                        return Err(Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET));
                    };
                    let at = form.release_at(release, time).ok_or(Failure::release_time_passed(0))?;
                    let mut tc = heapless::Vec::new();
                    tc.extend_from_slice(inner)
                        .map_err(|_| Failure::scheduled_tc_invalid(FailureCode::MALFORMED_PACKET))?;
                    self.items
                        .push(Scheduled { release: at, tc })
                        .map_err(|_| Failure::schedule_full(config::SCHEDULE_CAPACITY))?;
                    rest = tail;
                }
            }
        }
        Ok(())
    }
}

impl Schedule {
    /// The next scheduled TC whose release time has come, taken off the schedule (the
    /// obsw runs it through the TC path); `None` when none is due or the schedule is
    /// disabled.
    pub fn take_released(&mut self, now: u64) -> Option<ScheduledTc> {
        if !self.enabled {
            return None;
        }
        let i = self.items.iter().position(|s| s.release <= now)?;
        Some(self.items.swap_remove(i).tc)
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

    /// TC[11,4] application data exactly as Yamcs 5.12.8's `PusCommandPostprocessor`
    /// builds it (`buildScheduledTc`): sub-schedule ID, N = 1, CUC (coarse = Yamcs
    /// instant / 1000, fine = (instant % 1000) * 65536 / 1000), the TC.
    fn yamcs_insert(o: &crate::obsw::tests::TestObsw, sub: u8, at: u64, inner: &[u8]) -> Vec<u8> {
        let mut app = vec![sub, 1u8];
        app.extend_from_slice(&yamcs_cuc(o.dl.tmw.time.epoch_unix_ms + at));
        app.extend_from_slice(inner);
        app
    }

    fn yamcs_cuc(unix_ms: u64) -> [u8; 6] {
        let instant = unix_ms + mib::tc::sched_cuc::TAI_MINUS_UTC_S * 1000;
        let coarse = (instant / 1000) as u32;
        let fine = ((instant % 1000) * 65536 / 1000) as u16;
        let mut out = [0u8; 6];
        out[..4].copy_from_slice(&coarse.to_be_bytes());
        out[4..].copy_from_slice(&fine.to_be_bytes());
        out
    }

    // verifies: YAMCS-SCHED-01
    #[test]
    fn every_ms_of_a_yamcs_cuc_release_time_decodes_to_itself() {
        let base = 1_790_000_000_000u64;
        for ms in 0..2000 {
            assert_eq!(super::cuc_unix_ms(&yamcs_cuc(base + ms)), Some(base + ms), "{ms}");
        }
        assert_eq!(super::cuc_unix_ms(&yamcs_cuc(base)[..5]), None, "short stamp");
        assert_eq!(super::cuc_unix_ms(&[0; 6]), None, "before the epoch");
    }

    // verifies: YAMCS-SCHED-01
    #[test]
    fn a_ping_scheduled_in_yamcs_form_runs_at_its_release_time_to_the_ms() {
        let mut o = obsw();
        let app = yamcs_insert(&o, 1, 1_234, &tc_bytes(APID, 77, 17, 1, &[]));
        let pkts = send(&mut o, 10, 1, 11, 4, &app);
        assert_eq!(of(&pkts, 1, 7).len(), 1, "TC[11,4] completed");
        assert_eq!(o.sched.len(), 1);
        assert_eq!(o.sched.next_release(), Some(1_234));
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.release_schedule(1_233, &mut sink);
        assert!(sink.is_empty());
        o.release_schedule(1_234, &mut sink);
        assert_eq!(of(&sink, 17, 2).len(), 1);
    }

    // verifies: YAMCS-SCHED-01
    #[test]
    fn yamcs_form_refuses_another_sub_schedule_a_bad_n_a_short_time_and_the_past() {
        let mut o = obsw();
        let ping = tc_bytes(APID, 77, 17, 1, &[]);
        let app = yamcs_insert(&o, 2, 500, &ping);
        let pkts = send(&mut o, 10, 1, 11, 4, &app);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::ARG_OUT_OF_RANGE.code(), vec![0, 0, 0, 0, 2])
        );
        let mut app = yamcs_insert(&o, 1, 500, &ping);
        app[1] = 33;
        let pkts = send(&mut o, 10, 2, 11, 4, &app);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::ARG_OUT_OF_RANGE.code(), vec![1, 0, 0, 0, 33])
        );
        let app = yamcs_insert(&o, 1, 500, &ping);
        let pkts = send(&mut o, 10, 3, 11, 4, &app[..6]);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (
                FailureCode::SCHEDULED_TC_INVALID.code(),
                FailureCode::MALFORMED_PACKET.code().to_be_bytes().to_vec()
            )
        );
        let app = yamcs_insert(&o, 1, 400, &ping);
        let pkts = send(&mut o, 1000, 4, 11, 4, &app);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::RELEASE_TIME_PASSED.code(), 400u32.to_be_bytes().to_vec())
        );
        assert_eq!(o.sched.len(), 0, "nothing inserted");
    }
}
