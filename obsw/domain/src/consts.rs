//! Design values of the domain, re-exported under the names this crate uses. They live
//! in the MIB (`mib::robot::{estimator, hip, bolter}`, `mib::config`), like every other
//! number of the system.

pub use mib::config::{
    AB_LINK_MAX_FRAME as LINK_MAX_FRAME, AB_LINK_QUEUE_DEPTH as LINK_QUEUE_DEPTH, AB_LINK_TX_CAP as LINK_TX_CAP,
    B_MODES_RESEND_MS,
};
pub use mib::robot::bolter::{
    RETRACT_MS as BOLT_RETRACT_MS, RETURN_MS as BOLT_RETURN_MS, REVERSE_MS as BOLT_REVERSE_MS,
    SELECT_MS as BOLT_SELECT_MS, UNLOCK_MIN_MS as BOLT_UNLOCK_MIN_MS,
};
pub use mib::robot::estimator::{
    ARM_TOL_US as EST_ARM_TOL_US, FACE_MIN_DOT_MG as EST_FACE_MIN_DOT_MG, GRIP_TOL_US as EST_GRIP_TOL_US,
    G_MAX_MG as EST_G_MAX_MG, G_MIN_MG as EST_G_MIN_MG, HIP_TOL_CDEG as EST_HIP_TOL_CDEG, STATE_SETTLE_TIMEOUT_MS,
};
pub use mib::robot::hip::{
    DONE_TICKS as HIP_DONE_TICKS, MAX_CMD_CDEG_S as HIP_MAX_CMD_CDEG_S, VEL_SPAN as HIP_VEL_SPAN,
};
