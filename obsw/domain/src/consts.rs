//! Domain-internal constants that are not (yet) in the MIB: tolerances of the state
//! estimator, bolter motion durations and settling times. They are design values of
//! this crate, documented in `docs/domain.md`; any that the ground needs to see or tune
//! should move to `mib::tunables`.

/// Estimator: largest hip error (cdeg) still consistent with a state (10°).
pub const EST_HIP_TOL_CDEG: i16 = 1000;
/// Estimator: largest arm PWM error (µs) still consistent with a state.
pub const EST_ARM_TOL_US: u16 = 100;
/// Estimator: a side counts as gripped only if its gripper PWM is within this of
/// `servo::GRIP_CLOSED_US` (µs).
pub const EST_GRIP_TOL_US: u16 = 50;
/// Estimator: smallest dot product (milli-g) between a measured gravity vector and a
/// face's expected gravity for the face to be recognised (≈ 37°).
pub const EST_FACE_MIN_DOT_MG: i32 = 800;
/// Estimator: accepted magnitude band (milli-g) of a gravity vector.
pub const EST_G_MIN_MG: i32 = 700;
pub const EST_G_MAX_MG: i32 = 1300;

/// After a primitive, how long the filtered sensors may take to confirm the new state.
pub const STATE_SETTLE_TIMEOUT_MS: u32 = 2000;
/// Hip "done": error within `servo::HIP_DONE_CDEG` for this many consecutive ticks.
pub const HIP_DONE_TICKS: u8 = 20;
/// Largest hip speed command (cdeg/s) the hip controller outputs.
pub const HIP_MAX_CMD_CDEG_S: i16 = 3000;
/// Samples spanned by the hip velocity estimate (smoothing over 100 ms at 10 ms).
pub const HIP_VEL_SPAN: usize = 10;

/// Bolter: multiplexer settling time after selecting a pair.
pub const BOLT_SELECT_MS: u32 = 50;
/// Bolter: retract time after the first push.
pub const BOLT_RETRACT_MS: u32 = 400;
/// Bolter: reverse rotation time after locking.
pub const BOLT_REVERSE_MS: u32 = 500;
/// Bolter: travel time back to the home position.
pub const BOLT_RETURN_MS: u32 = 1200;
/// Bolter (unbolting): shortest reverse rotation before release is judged by current.
pub const BOLT_UNLOCK_MIN_MS: u32 = 300;

/// A–B link: commands waiting behind the one in flight (coalesced per kind, so the
/// queue never overflows: there are fewer command kinds than slots).
pub const LINK_QUEUE_DEPTH: usize = 8;
/// Largest decoded A–B frame payload (bytes).
pub const LINK_MAX_FRAME: usize = 64;
/// Capacity of the bytes one tick may hand to the serial line (115200 Bd carries
/// ~115 bytes per 10 ms control period).
pub const LINK_TX_CAP: usize = 128;
/// Shortest interval between re-sends of B's module modes when its heartbeat shows
/// other modes than A wants.
pub const B_MODES_RESEND_MS: u32 = 200;
