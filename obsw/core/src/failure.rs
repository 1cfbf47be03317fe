//! The one shape of a PUS 1 failure: the wire crate's typed [`mib_wire::Failure`] (a
//! MIB failure code with exactly the data the MIB lists for it, generated from the
//! MIB's field lists). The core builds every refusal and every failed action here, by
//! a constructor named after its code, so no caller packs failure bytes.

use mib::FailureCode;
use mib_wire::Failure as W;
use mmic_domain::controller::{ActionFailure, StartError};

/// Longest failure data of any code (MODE_CHANGE_FAILED: 12 bytes).
pub const MAX_FAILURE_DATA: usize = 12;

/// A failure code with its data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure(pub W);

fn sat16(v: usize) -> u16 {
    v.min(u16::MAX as usize) as u16
}
fn sat32(v: u64) -> u32 {
    v.min(u32::MAX as u64) as u32
}

/// A failure as it was sent: its code and data bytes (16 bytes). The duplicate window
/// keeps one per remembered TC to repeat the report (128 on board A), where the typed
/// [`Failure`] takes 44 bytes on the 32-bit target (its `Unknown` variant's buffer): 4 KB
/// of static RAM.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SentFailure {
    code: u16,
    len: u8,
    data: [u8; MAX_FAILURE_DATA],
}

impl SentFailure {
    pub fn code(&self) -> u16 {
        self.code
    }
    /// The failure data as sent after the code.
    pub fn data(&self) -> &[u8] {
        self.data.get(..self.len as usize).unwrap_or(&[])
    }
}

impl From<&Failure> for SentFailure {
    fn from(f: &Failure) -> Self {
        let d = f.data();
        let mut data = [0u8; MAX_FAILURE_DATA];
        data[..d.len()].copy_from_slice(&d);
        SentFailure {
            code: f.code().code(),
            len: d.len() as u8,
            data,
        }
    }
}

impl Failure {
    pub fn code(&self) -> FailureCode {
        FailureCode::from_code(self.0.code())
    }
    /// The failure data as sent after the code.
    pub fn data(&self) -> heapless::Vec<u8, MAX_FAILURE_DATA> {
        let mut buf = [0u8; MAX_FAILURE_DATA];
        let mut w = mib_wire::Writer::new(&mut buf);
        // Every code of this MIB fits MAX_FAILURE_DATA (tested).
        let n = match self.0.write(&mut w) {
            Ok(()) => w.len(),
            Err(_) => 0,
        };
        heapless::Vec::from_slice(&buf[..n]).unwrap_or_default()
    }
    /// The fault event of an ABORTED_BY_FAULT failure.
    pub fn fault_event(&self) -> Option<u16> {
        match self.0 {
            W::AbortedByFault { event_id } => Some(event_id),
            _ => None,
        }
    }

    pub fn crc_mismatch(crc_received: u16, crc_computed: u16) -> Self {
        Failure(W::CrcMismatch {
            crc_received,
            crc_computed,
        })
    }
    pub fn malformed_packet(received_len: usize, expected_len: usize) -> Self {
        Failure(W::MalformedPacket {
            received_len: sat16(received_len),
            expected_len: sat16(expected_len),
        })
    }
    pub fn wrong_apid(apid: u16) -> Self {
        Failure(W::WrongApid { apid })
    }
    pub fn not_a_pus_tc(version: u8, is_tc: bool, sec_hdr: bool) -> Self {
        Failure(W::NotAPusTc {
            version,
            r#type: is_tc as u8,
            sec_hdr: sec_hdr as u8,
        })
    }
    pub fn unknown_service(service: u8) -> Self {
        Failure(W::UnknownService { service })
    }
    pub fn unknown_subservice(service: u8, subservice: u8) -> Self {
        Failure(W::UnknownSubservice { service, subservice })
    }
    pub fn unknown_function(function: u16) -> Self {
        Failure(W::UnknownFunction { function })
    }
    pub fn bad_arg_length(received_len: usize, expected_len: usize) -> Self {
        Failure(W::BadArgLength {
            received_len: sat16(received_len),
            expected_len: sat16(expected_len),
        })
    }
    pub fn arg_out_of_range(arg_index: u8, value: i32) -> Self {
        Failure(W::ArgOutOfRange { arg_index, value })
    }
    /// `mode` is the robot's current mode (`mib::modes::robot_mode`, fits a u8).
    pub fn not_allowed_in_mode(mode: u32) -> Self {
        Failure(W::NotAllowedInMode {
            mode: mode.min(u8::MAX as u32) as u8,
        })
    }
    pub fn busy(running_function: u16) -> Self {
        Failure(W::Busy { running_function })
    }
    pub fn initial_state_mismatch(believed: u8, computed: u8) -> Self {
        Failure(W::InitialStateMismatch { believed, computed })
    }
    pub fn unreachable_state(from: u8, to: u8) -> Self {
        Failure(W::UnreachableState { from, to })
    }
    pub fn bolt_failed(side: u8, pair: u8, attempts: u8) -> Self {
        Failure(W::BoltFailed { side, pair, attempts })
    }
    pub fn unbolt_failed(side: u8, pair: u8, attempts: u8) -> Self {
        Failure(W::UnboltFailed { side, pair, attempts })
    }
    pub fn aborted_by_fault(event_id: u16) -> Self {
        Failure(W::AbortedByFault { event_id })
    }
    pub fn mode_change_failed(node: u32, mode: u32, reason: FailureCode, event: u16) -> Self {
        Failure(W::ModeChangeFailed {
            node,
            mode,
            reason: reason.code(),
            event,
        })
    }
    pub fn fault_not_cleared(event_id: u16) -> Self {
        Failure(W::FaultNotCleared { event_id })
    }
    pub fn unknown_sid(sid: u16) -> Self {
        Failure(W::UnknownSid { sid })
    }
    pub fn unknown_event(event_id: u16) -> Self {
        Failure(W::UnknownEvent { event_id })
    }
    pub fn unknown_parameter(param_id: u16) -> Self {
        Failure(W::UnknownParameter { param_id })
    }
    pub fn param_out_of_range(param_id: u16, value: i32) -> Self {
        Failure(W::ParamOutOfRange { param_id, value })
    }
    pub fn unknown_monitor(monitor_id: u16) -> Self {
        Failure(W::UnknownMonitor { monitor_id })
    }
    pub fn schedule_full(capacity: usize) -> Self {
        Failure(W::ScheduleFull {
            capacity: sat16(capacity),
        })
    }
    pub fn release_time_passed(release_ms: u64) -> Self {
        Failure(W::ReleaseTimePassed {
            release_ms: sat32(release_ms),
        })
    }
    pub fn scheduled_tc_invalid(inner: FailureCode) -> Self {
        Failure(W::ScheduledTcInvalid {
            inner_code: inner.code(),
        })
    }
    pub fn board_b_no_ack(command: u8, retries: u8) -> Self {
        Failure(W::BoardBNoAck { command, retries })
    }
    pub fn unknown_mode_target(node: u32) -> Self {
        Failure(W::UnknownModeTarget { node })
    }
    pub fn invalid_mode(node: u32, mode: u32) -> Self {
        Failure(W::InvalidMode { node, mode })
    }
    pub fn unknown_action_link(event_id: u16) -> Self {
        Failure(W::UnknownActionLink { event_id })
    }
    pub fn store_disabled() -> Self {
        Failure(W::StoreDisabled)
    }
    pub fn timeout(elapsed_ms: u64) -> Self {
        Failure(W::Timeout {
            elapsed_ms: sat32(elapsed_ms),
        })
    }
    pub fn aborted_by_command(function: u16) -> Self {
        Failure(W::AbortedByCommand { function })
    }
    pub fn both_sides_gripped(grip_a_pwm: u16, grip_b_pwm: u16) -> Self {
        Failure(W::BothSidesGripped { grip_a_pwm, grip_b_pwm })
    }
    pub fn frame_too_long(frame_len: usize, max_len: usize) -> Self {
        Failure(W::FrameTooLong {
            frame_len: sat32(frame_len as u64),
            max_len: sat32(max_len as u64),
        })
    }
    pub fn nested_schedule(activity: u8) -> Self {
        Failure(W::NestedSchedule { activity })
    }
    pub fn config_invalid(reason: u8, slot: u8) -> Self {
        Failure(W::ConfigInvalid { reason, slot })
    }
    pub fn config_not_accepted(hash: u32) -> Self {
        Failure(W::ConfigNotAccepted { hash })
    }
    pub fn config_hash_stale(received: u32, current: u32) -> Self {
        Failure(W::ConfigHashStale { received, current })
    }
    pub fn module_absent(slot: u8) -> Self {
        Failure(W::ModuleAbsent { slot })
    }
    pub fn plan_not_authorised(plan: u16, step: u16) -> Self {
        Failure(W::PlanNotAuthorised { plan, step })
    }
    pub fn plan_forbidden_function(function: u16) -> Self {
        Failure(W::PlanForbiddenFunction { function })
    }
    pub fn plan_hash_mismatch(authorised: u32, uploaded: u32) -> Self {
        Failure(W::PlanHashMismatch { authorised, uploaded })
    }

    /// The failure of an action the domain refused to start. `running` is the function
    /// of the running action (for BUSY), `mode` the robot's mode (for NOT_POWERED).
    pub fn from_start(e: StartError, running: u16, mode: u32) -> Self {
        match e {
            StartError::Busy => Self::busy(running),
            StartError::InitialStateMismatch { believed, computed } => Self::initial_state_mismatch(believed, computed),
            StartError::Unreachable { from, to } => Self::unreachable_state(from, to),
            StartError::NotPowered => Self::not_allowed_in_mode(mode),
            StartError::InvalidArgument { index, value } => Self::arg_out_of_range(index, value),
            StartError::BothSidesGripped { grip_a_pwm, grip_b_pwm } => Self::both_sides_gripped(grip_a_pwm, grip_b_pwm),
        }
    }

    /// The failure of an action that ended without completing.
    pub fn from_action(f: ActionFailure) -> Self {
        match f {
            ActionFailure::AbortedByFault { event } => Self::aborted_by_fault(event),
            ActionFailure::BoltFailed { side, pair, attempts } => Self::bolt_failed(side as u8, pair, attempts),
            ActionFailure::UnboltFailed { side, pair, attempts } => Self::unbolt_failed(side as u8, pair, attempts),
            ActionFailure::BoardBNoAck { command, retries } => Self::board_b_no_ack(command, retries),
            ActionFailure::Timeout { elapsed_ms } => Self::timeout(elapsed_ms as u64),
            ActionFailure::StateMismatch { expected, computed } => Self::initial_state_mismatch(expected, computed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: PUS-1-02
    #[test]
    fn every_constructor_carries_the_data_the_mib_lists_for_its_code() {
        let all = [
            Failure::crc_mismatch(1, 2),
            Failure::malformed_packet(1, 2),
            Failure::wrong_apid(1),
            Failure::not_a_pus_tc(0, true, false),
            Failure::unknown_service(1),
            Failure::unknown_subservice(1, 2),
            Failure::unknown_function(1),
            Failure::bad_arg_length(1, 2),
            Failure::arg_out_of_range(1, -5),
            Failure::not_allowed_in_mode(1),
            Failure::busy(1),
            Failure::initial_state_mismatch(1, 2),
            Failure::unreachable_state(1, 2),
            Failure::bolt_failed(0, 1, 3),
            Failure::unbolt_failed(0, 1, 3),
            Failure::aborted_by_fault(1),
            Failure::mode_change_failed(1, 2, FailureCode::TIMEOUT, 3),
            Failure::fault_not_cleared(1),
            Failure::unknown_sid(1),
            Failure::unknown_event(1),
            Failure::unknown_parameter(1),
            Failure::param_out_of_range(1, 2),
            Failure::unknown_monitor(1),
            Failure::schedule_full(32),
            Failure::release_time_passed(5),
            Failure::scheduled_tc_invalid(FailureCode::CRC_MISMATCH),
            Failure::board_b_no_ack(1, 2),
            Failure::unknown_mode_target(1),
            Failure::invalid_mode(1, 2),
            Failure::unknown_action_link(1),
            Failure::store_disabled(),
            Failure::timeout(1),
            Failure::aborted_by_command(1),
            Failure::both_sides_gripped(1100, 1100),
            Failure::frame_too_long(2000, 1024),
            Failure::nested_schedule(0),
            Failure::config_invalid(11, 11),
            Failure::config_not_accepted(0x0900_3d97),
            Failure::config_hash_stale(1, 0x0900_3d97),
            Failure::module_absent(5),
            Failure::plan_not_authorised(7, 5),
            Failure::plan_forbidden_function(3),
            Failure::plan_hash_mismatch(1, 2),
        ];
        // And the failures the services make themselves.
        let all: Vec<Failure> = all.into_iter().chain(crate::services::tests::own_failures()).collect();
        for f in &all {
            assert_eq!(f.data().len(), f.code().data_len(), "{:?}", f.code());
            assert!(f.data().len() <= MAX_FAILURE_DATA);
            // What the duplicate window keeps repeats exactly what was sent.
            let sent = SentFailure::from(f);
            assert_eq!((sent.code(), sent.data()), (f.code().code(), &f.data()[..]));
        }
        assert!(core::mem::size_of::<SentFailure>() <= 16, "kept 128 times on board A");
        // Every code of the MIB has a constructor.
        for c in FailureCode::ALL {
            assert!(all.iter().any(|f| f.code() == *c), "{c:?} has no constructor");
        }
    }

    // verifies: PUS-1-02
    #[test]
    fn invalid_argument_and_not_powered_carry_real_values() {
        let f = Failure::from_start(StartError::InvalidArgument { index: 1, value: 5 }, 0, 2);
        assert_eq!(
            (f.code(), &f.data()[..]),
            (FailureCode::ARG_OUT_OF_RANGE, &[1u8, 0, 0, 0, 5][..])
        );
        let f = Failure::from_start(StartError::NotPowered, 0, 4);
        assert_eq!(
            (f.code(), &f.data()[..]),
            (FailureCode::NOT_ALLOWED_IN_MODE, &[4u8][..])
        );
    }
}
