//! The one shape of a PUS 1 failure: a MIB failure code and its failure data, laid out
//! exactly as `mib::failure` lists it for that code. Every refusal and every failed
//! action of the core is built here, by a constructor named after its code, so no
//! caller packs failure bytes by hand.

use mib::FailureCode;
use mmic_domain::controller::{ActionFailure, StartError};

/// Longest failure data of any code (MODE_CHANGE_FAILED: 12 bytes).
pub const MAX_FAILURE_DATA: usize = 12;

/// A failure code with its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Failure {
    code: FailureCode,
    data: [u8; MAX_FAILURE_DATA],
    len: u8,
}

/// Big-endian fields of a failure's data, in MIB order.
#[derive(Clone, Copy)]
enum F {
    U8(u8),
    U16(u16),
    U32(u32),
    I32(i32),
}

impl Failure {
    fn new(code: FailureCode, fields: &[F]) -> Self {
        let mut data = [0u8; MAX_FAILURE_DATA];
        let mut n = 0;
        for f in fields {
            let (b, l): ([u8; 4], usize) = match *f {
                F::U8(v) => ([v, 0, 0, 0], 1),
                F::U16(v) => {
                    let x = v.to_be_bytes();
                    ([x[0], x[1], 0, 0], 2)
                }
                F::U32(v) => (v.to_be_bytes(), 4),
                F::I32(v) => (v.to_be_bytes(), 4),
            };
            // Every constructor below stays within MAX_FAILURE_DATA (tested).
            let end = (n + l).min(MAX_FAILURE_DATA);
            data[n..end].copy_from_slice(&b[..end - n]);
            n = end;
        }
        Failure {
            code,
            data,
            len: n as u8,
        }
    }

    pub fn code(&self) -> FailureCode {
        self.code
    }
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }
    /// The fault event of an ABORTED_BY_FAULT failure.
    pub fn fault_event(&self) -> Option<u16> {
        (self.code == FailureCode::ABORTED_BY_FAULT).then(|| u16::from_be_bytes([self.data[0], self.data[1]]))
    }

    pub fn crc_mismatch(received: u16, computed: u16) -> Self {
        Self::new(FailureCode::CRC_MISMATCH, &[F::U16(received), F::U16(computed)])
    }
    pub fn malformed_packet(received_len: usize, expected_len: usize) -> Self {
        Self::new(
            FailureCode::MALFORMED_PACKET,
            &[F::U16(sat16(received_len)), F::U16(sat16(expected_len))],
        )
    }
    pub fn wrong_apid(apid: u16) -> Self {
        Self::new(FailureCode::WRONG_APID, &[F::U16(apid)])
    }
    pub fn not_a_pus_tc(version: u8, is_tc: bool, sec_hdr: bool) -> Self {
        Self::new(
            FailureCode::NOT_A_PUS_TC,
            &[F::U8(version), F::U8(is_tc as u8), F::U8(sec_hdr as u8)],
        )
    }
    pub fn unknown_service(service: u8) -> Self {
        Self::new(FailureCode::UNKNOWN_SERVICE, &[F::U8(service)])
    }
    pub fn unknown_subservice(service: u8, subservice: u8) -> Self {
        Self::new(FailureCode::UNKNOWN_SUBSERVICE, &[F::U8(service), F::U8(subservice)])
    }
    pub fn unknown_function(function: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_FUNCTION, &[F::U16(function)])
    }
    pub fn bad_arg_length(received_len: usize, expected_len: usize) -> Self {
        Self::new(
            FailureCode::BAD_ARG_LENGTH,
            &[F::U16(sat16(received_len)), F::U16(sat16(expected_len))],
        )
    }
    pub fn arg_out_of_range(arg_index: u8, value: i32) -> Self {
        Self::new(FailureCode::ARG_OUT_OF_RANGE, &[F::U8(arg_index), F::I32(value)])
    }
    /// `mode` is the robot's current mode (`mib::modes::robot_mode`, fits a u8).
    pub fn not_allowed_in_mode(mode: u32) -> Self {
        Self::new(
            FailureCode::NOT_ALLOWED_IN_MODE,
            &[F::U8(mode.min(u8::MAX as u32) as u8)],
        )
    }
    pub fn busy(running_function: u16) -> Self {
        Self::new(FailureCode::BUSY, &[F::U16(running_function)])
    }
    pub fn initial_state_mismatch(believed: u8, computed: u8) -> Self {
        Self::new(FailureCode::INITIAL_STATE_MISMATCH, &[F::U8(believed), F::U8(computed)])
    }
    pub fn unreachable_state(from: u8, to: u8) -> Self {
        Self::new(FailureCode::UNREACHABLE_STATE, &[F::U8(from), F::U8(to)])
    }
    pub fn bolt_failed(side: u8, pair: u8, attempts: u8) -> Self {
        Self::new(FailureCode::BOLT_FAILED, &[F::U8(side), F::U8(pair), F::U8(attempts)])
    }
    pub fn unbolt_failed(side: u8, pair: u8, attempts: u8) -> Self {
        Self::new(FailureCode::UNBOLT_FAILED, &[F::U8(side), F::U8(pair), F::U8(attempts)])
    }
    pub fn aborted_by_fault(event_id: u16) -> Self {
        Self::new(FailureCode::ABORTED_BY_FAULT, &[F::U16(event_id)])
    }
    pub fn mode_change_failed(node: u32, mode: u32, reason: FailureCode, event: u16) -> Self {
        Self::new(
            FailureCode::MODE_CHANGE_FAILED,
            &[F::U32(node), F::U32(mode), F::U16(reason.code()), F::U16(event)],
        )
    }
    pub fn fault_not_cleared(event_id: u16) -> Self {
        Self::new(FailureCode::FAULT_NOT_CLEARED, &[F::U16(event_id)])
    }
    pub fn unknown_sid(sid: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_SID, &[F::U16(sid)])
    }
    pub fn unknown_event(event_id: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_EVENT, &[F::U16(event_id)])
    }
    pub fn unknown_parameter(param_id: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_PARAMETER, &[F::U16(param_id)])
    }
    pub fn param_out_of_range(param_id: u16, value: i32) -> Self {
        Self::new(FailureCode::PARAM_OUT_OF_RANGE, &[F::U16(param_id), F::I32(value)])
    }
    pub fn unknown_monitor(monitor_id: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_MONITOR, &[F::U16(monitor_id)])
    }
    pub fn schedule_full(capacity: usize) -> Self {
        Self::new(FailureCode::SCHEDULE_FULL, &[F::U16(sat16(capacity))])
    }
    pub fn release_time_passed(release_ms: u64) -> Self {
        Self::new(
            FailureCode::RELEASE_TIME_PASSED,
            &[F::U32(release_ms.min(u32::MAX as u64) as u32)],
        )
    }
    pub fn scheduled_tc_invalid(inner: FailureCode) -> Self {
        Self::new(FailureCode::SCHEDULED_TC_INVALID, &[F::U16(inner.code())])
    }
    pub fn board_b_no_ack(command: u8, retries: u8) -> Self {
        Self::new(FailureCode::BOARD_B_NO_ACK, &[F::U8(command), F::U8(retries)])
    }
    pub fn unknown_mode_target(node: u32) -> Self {
        Self::new(FailureCode::UNKNOWN_MODE_TARGET, &[F::U32(node)])
    }
    pub fn invalid_mode(node: u32, mode: u32) -> Self {
        Self::new(FailureCode::INVALID_MODE, &[F::U32(node), F::U32(mode)])
    }
    pub fn unknown_action_link(event_id: u16) -> Self {
        Self::new(FailureCode::UNKNOWN_ACTION_LINK, &[F::U16(event_id)])
    }
    pub fn store_disabled() -> Self {
        Self::new(FailureCode::STORE_DISABLED, &[])
    }
    pub fn timeout(elapsed_ms: u64) -> Self {
        Self::new(FailureCode::TIMEOUT, &[F::U32(elapsed_ms.min(u32::MAX as u64) as u32)])
    }
    pub fn aborted_by_command(function: u16) -> Self {
        Self::new(FailureCode::ABORTED_BY_COMMAND, &[F::U16(function)])
    }

    pub fn both_sides_gripped(grip_a_pwm: u16, grip_b_pwm: u16) -> Self {
        Self::new(
            FailureCode::BOTH_SIDES_GRIPPED,
            &[F::U16(grip_a_pwm), F::U16(grip_b_pwm)],
        )
    }
    pub fn frame_too_long(frame_len: usize, max_len: usize) -> Self {
        let sat = |v: usize| v.min(u32::MAX as usize) as u32;
        Self::new(
            FailureCode::FRAME_TOO_LONG,
            &[F::U32(sat(frame_len)), F::U32(sat(max_len))],
        )
    }
    pub fn nested_schedule(activity: u8) -> Self {
        Self::new(FailureCode::NESTED_SCHEDULE, &[F::U8(activity)])
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

fn sat16(v: usize) -> u16 {
    v.min(u16::MAX as usize) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

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
        ];
        for f in all {
            assert_eq!(f.data().len(), f.code().data_len(), "{:?}", f.code());
        }
        // Every code of the MIB has a constructor.
        for c in FailureCode::ALL {
            assert!(all.iter().any(|f| f.code() == *c), "{c:?} has no constructor");
        }
    }

    #[test]
    fn invalid_argument_and_not_powered_carry_real_values() {
        let f = Failure::from_start(StartError::InvalidArgument { index: 1, value: 5 }, 0, 2);
        assert_eq!(
            (f.code(), f.data()),
            (FailureCode::ARG_OUT_OF_RANGE, &[1u8, 0, 0, 0, 5][..])
        );
        let f = Failure::from_start(StartError::NotPowered, 0, 4);
        assert_eq!((f.code(), f.data()), (FailureCode::NOT_ALLOWED_IN_MODE, &[4u8][..]));
    }
}
