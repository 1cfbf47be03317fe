//! The file service's telemetry (`docs/files.md`, "Housekeeping and events"): the codes
//! its events carry. Its counters are housekeeping structure `FILES` (`crate::hk`, source
//! `Files` in `crate::params`), its events the `FILE_*` rows of `crate::events`; the
//! protocol's own numbers (APID, sizes, timers) are in `crate::cfdp`.

crate::named_codes! {
    /// Names of the directions.
    DIRECTION_NAMES;
    /// Which way a transaction's file (or request) travels, seen from the robot.
    pub mod direction {
        /// The ground's entity started it: a put up, or a request (get, listing, remove,
        /// rename) in a metadata PDU without a file.
        pub const RECEIVED: u8 = 0;
        /// The robot's entity started it: the file of a get, a listing.
        pub const SENT: u8 = 1;
    }
}

crate::named_codes! {
    /// Names of the transfer classes.
    CLASS_NAMES;
    /// CFDP transfer class (727.0-B-5 § 2.3).
    pub mod class {
        /// Unacknowledged: nothing sent again; the checksum decides.
        pub const CLASS_1: u8 = 1;
        /// Acknowledged: NAKs for what is missing, EOF and Finished acknowledged.
        pub const CLASS_2: u8 = 2;
    }
}

crate::named_codes! {
    /// Names of the condition codes.
    CONDITION_NAMES;
    /// CFDP condition codes (727.0-B-5 § 5.2.2, table 5-5): how a transaction ended.
    pub mod condition {
        pub const NO_ERROR: u8 = 0;
        /// The peer never acknowledged an EOF or Finished PDU within `ACK_LIMIT` timer periods.
        pub const POSITIVE_ACK_LIMIT_REACHED: u8 = 1;
        pub const KEEP_ALIVE_LIMIT_REACHED: u8 = 2;
        pub const INVALID_TRANSMISSION_MODE: u8 = 3;
        /// A filestore request or a file write was refused (name, space, medium).
        pub const FILESTORE_REJECTION: u8 = 4;
        /// The file's checksum is not the sender's: the file was not kept.
        pub const FILE_CHECKSUM_FAILURE: u8 = 5;
        pub const FILE_SIZE_ERROR: u8 = 6;
        /// Segments still missing after `NAK_LIMIT` NAK periods.
        pub const NAK_LIMIT_REACHED: u8 = 7;
        /// Nothing heard of the transaction for `INACTIVITY_MS`: abandoned.
        pub const INACTIVITY_DETECTED: u8 = 8;
        pub const INVALID_FILE_STRUCTURE: u8 = 9;
        /// Class 1: the file stayed incomplete for `CHECK_LIMIT` check periods after its EOF.
        pub const CHECK_LIMIT_REACHED: u8 = 10;
        pub const UNSUPPORTED_CHECKSUM_TYPE: u8 = 11;
        pub const SUSPEND_REQUEST_RECEIVED: u8 = 14;
        /// Cancelled (by the peer, or as a fault's response).
        pub const CANCEL_REQUEST_RECEIVED: u8 = 15;
    }
}
