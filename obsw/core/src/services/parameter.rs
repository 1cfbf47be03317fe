//! PUS 20 on-board parameter management: report and set the domain's tunables
//! (`mib::tunables`), range-checked at acceptance.

use mib::tc::service;
use mib::tunables::TunableDef;
use mib_wire::tm;
use mmic_domain::controller::Controller;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[20,1]: answered with TM[20,2].
    Report(&'static TunableDef),
    /// TC[20,3]: value within the tunable's range.
    Set(&'static TunableDef, i32),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args::{ParamReport, ParamSet};
        let tunable = |id: u16| mib::tunables::by_id(id).ok_or(Failure::unknown_parameter(id));
        Ok(match tc.subservice {
            1 => Request::Report(tunable(ParamReport::of(&tc.args).param_id)?),
            3 => {
                let x = ParamSet::of(&tc.args);
                let t = tunable(x.param_id)?;
                let v = i64::from(x.value);
                if v < t.min as i64 || v > t.max as i64 {
                    return Err(Failure::param_out_of_range(t.id, v as i32));
                }
                Request::Set(t, v as i32)
            }
            _ => return Err(unknown(tc)),
        })
    }
}

/// The tunables are the domain controller's state: PUS 20 sets and reports them there.
impl Component for Controller {
    const CONTRACT: Contract = Contract::new("parameter", Some(service::PARAMETER), &[]);
    type Request<'a> = Request;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        let t = match r {
            Request::Report(t) => t,
            Request::Set(t, v) => {
                self.set_tunable(t.id, v)
                    .map_err(|_| Failure::param_out_of_range(t.id, v))?;
                t
            }
        };
        let v = self.tunable(t.id).ok_or(Failure::unknown_parameter(t.id))?;
        let r = tm::ParamValue {
            param_id: t.id,
            value: v,
        };
        dl.emit_tm(now, &r, sink);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, kind, obsw, of, send};
    use mib::tunables::TUNABLES;
    use mib::FailureCode;

    // verifies: PUS-20-01
    #[test]
    fn set_reports_the_new_value_and_out_of_range_is_refused_with_id_and_value() {
        let mut o = obsw();
        let t = TUNABLES[0];
        let mut app = t.id.to_be_bytes().to_vec();
        app.extend_from_slice(&t.max.to_be_bytes());
        let pkts = send(&mut o, 1, 1, 20, 3, &app);
        assert_eq!(&kind(&of(&pkts, 20, 2)[0]).2[2..], &t.max.to_be_bytes());
        if t.max < i32::MAX {
            let mut app = t.id.to_be_bytes().to_vec();
            app.extend_from_slice(&(t.max + 1).to_be_bytes());
            let pkts = send(&mut o, 2, 2, 20, 3, &app);
            let mut data = t.id.to_be_bytes().to_vec();
            data.extend_from_slice(&(t.max + 1).to_be_bytes());
            assert_eq!(
                failure(&of(&pkts, 1, 2)[0]),
                (FailureCode::PARAM_OUT_OF_RANGE.code(), data)
            );
        }
    }
}
