//! Software update in flight: the signed image's layout, the otadata record of ESP-IDF's
//! bootloader, the update service's subservices and the codes it reports. The layouts are
//! read and written by one crate, `mmic-update` (obsw/update), for the ground's signer, the
//! host's boot launcher and the robot alike; docs/update.md explains them for operators.
//!
//! ## Signed image (big-endian)
//!
//! | off | len | field |
//! |-----|-----|-------|
//! | 0   | 8   | magic [`MAGIC`] |
//! | 8   | 4   | software version ([`version`]: major.minor.patch in bytes 1..=3) |
//! | 12  | 4   | payload length in bytes (what follows the header) |
//! | 16  | 1   | target the payload runs on ([`target`]) |
//! | 17  | 3   | zero |
//! | 20  | 32  | SHA-256 of the payload |
//! | 52  | 64  | Ed25519 signature (RFC 8032, pure) of bytes 0..52 by the ground's update key |
//! | 116 | ... | payload |
//!
//! The signature covers the digest, the digest covers the payload: a changed byte anywhere
//! is refused before the image may be activated.

/// Magic of a signed image.
pub const MAGIC: [u8; 8] = *b"MMICIMG1";
/// Bytes the signature covers (magic to digest).
pub const SIGNED_LEN: usize = 52;
/// Length of the SHA-256 digest of the payload.
pub const DIGEST_LEN: usize = 32;
/// Length of an Ed25519 signature.
pub const SIGNATURE_LEN: usize = 64;
/// Length of an Ed25519 public key.
pub const PUBLIC_KEY_LEN: usize = 32;
/// Length of the header (signed bytes and the signature).
pub const HEADER_LEN: usize = SIGNED_LEN + SIGNATURE_LEN;
/// Byte offsets of the header's fields.
pub mod field {
    pub const VERSION: usize = 8;
    pub const LENGTH: usize = 12;
    pub const TARGET: usize = 16;
    pub const RESERVED: usize = 17;
    pub const DIGEST: usize = 20;
    pub const SIGNATURE: usize = super::SIGNED_LEN;
}
const _: () = assert!(field::DIGEST + DIGEST_LEN == SIGNED_LEN);

/// What an image runs on: an image for another target is refused at install.
pub mod target {
    /// The host obsw binary (x86-64 Linux) started by the boot launcher `obsw-boot`.
    pub const HOST: u8 = 1;
    /// Board A's ESP32-C3 application image (ESP-IDF app format).
    pub const BOARD_A: u8 = 2;
}

/// Software version as carried in the image header and in housekeeping: 0x00MMmmpp.
pub mod version {
    /// `major.minor.patch` as the u32 of the header (`None` when a part exceeds 255).
    pub const fn pack(major: u32, minor: u32, patch: u32) -> Option<u32> {
        if major > 255 || minor > 255 || patch > 255 {
            return None;
        }
        Some(major << 16 | minor << 8 | patch)
    }
}

/// ESP-IDF's otadata (`esp_ota_select_entry_t`, two copies, one per 4 KiB sector of the
/// `otadata` partition): which application slot the second-stage bootloader starts.
pub mod ota {
    /// Length of one record.
    pub const ENTRY_LEN: usize = 32;
    /// Offset of the second record's sector in the partition.
    pub const SECOND_SECTOR: u32 = crate::memory::FLASH_SECTOR;
    /// Size of the otadata partition (the host's otadata file has this size).
    pub const PARTITION_BYTES: u32 = crate::memory::OTADATA.size;
    /// Number of application slots the records choose between.
    pub const SLOTS: u32 = crate::memory::APP_SLOTS.len() as u32;

    /// `ota_state` values (`esp_ota_img_states_t`).
    pub mod state {
        /// Activated, not yet started: the bootloader makes it PENDING_VERIFY at its boot.
        pub const NEW: u32 = 0x0;
        /// Started once, not confirmed: found so at a boot, it is ABORTED and the other slot boots.
        pub const PENDING_VERIFY: u32 = 0x1;
        /// Confirmed by the image after its self-test.
        pub const VALID: u32 = 0x2;
        /// Declared unusable by the image itself; never booted.
        pub const INVALID: u32 = 0x3;
        /// Never confirmed; never booted again.
        pub const ABORTED: u32 = 0x4;
        /// Written without rollback (what espflash and a bare `set_boot_partition` leave).
        pub const UNDEFINED: u32 = 0xFFFF_FFFF;
    }
}

/// The update service's subservices (service `crate::tc::service::UPDATE`); its status is
/// housekeeping structure UPDATE.
pub mod sub {
    /// Copy a file of the file store into the inactive slot and verify it.
    pub const INSTALL: u8 = 1;
    /// Make the verified image in the inactive slot the one that boots, then reset.
    pub const ACTIVATE: u8 = 2;
    /// Confirm the running image (what its self-test does on its own).
    pub const CONFIRM: u8 = 3;
}

crate::named_codes! {
    /// Names of the outcome codes.
    OUTCOME_NAMES;
    /// The outcome of the last update, as housekeeping UPDATE_OUTCOME reports it.
    pub mod outcome {
        /// No update since the slots were written on the ground.
        pub const NONE: u8 = 0;
        /// An image was installed and verified in the inactive slot.
        pub const INSTALLED: u8 = 1;
        /// An install was refused (signature, digest, length, target, file).
        pub const REFUSED: u8 = 2;
        /// The running image was activated and has not yet confirmed.
        pub const PENDING: u8 = 3;
        /// The running image was activated and confirmed after its self-test.
        pub const CONFIRMED: u8 = 4;
        /// The image activated last never confirmed: the boot went back to this one.
        pub const ROLLED_BACK: u8 = 5;
    }
}

crate::named_codes! {
    /// Names of the refusal reasons.
    REFUSAL_NAMES;
    /// Why an install was refused (failure UPDATE_IMAGE_REFUSED, event UPDATE_REFUSED).
    pub mod refusal {
        /// The file is not in the store or cannot be read.
        pub const NO_FILE: u8 = 1;
        /// Shorter than its header, or its header's length differs from the file's.
        pub const TRUNCATED: u8 = 2;
        /// Not an image of this format (magic, reserved bytes).
        pub const NOT_AN_IMAGE: u8 = 3;
        /// An image for another target.
        pub const WRONG_TARGET: u8 = 4;
        /// Larger than the slot.
        pub const TOO_LARGE: u8 = 5;
        /// The payload's SHA-256 is not the header's.
        pub const DIGEST: u8 = 6;
        /// The header's Ed25519 signature is not the ground update key's.
        pub const SIGNATURE: u8 = 7;
        /// The slot could not be written or read back.
        pub const FLASH: u8 = 8;
        /// The robot holds no update key: nothing can be verified, nothing is installed.
        pub const NO_KEY: u8 = 9;
    }
}

/// Longest file name an install names (the file store's limit).
pub const MAX_FILE_NAME: usize = crate::cfdp::MAX_NAME_LEN;

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: UPD-IMG-01
    #[test]
    fn header_fields_follow_each_other() {
        assert_eq!(field::VERSION + 4, field::LENGTH);
        assert_eq!(field::LENGTH + 4, field::TARGET);
        assert_eq!(field::RESERVED + 3, field::DIGEST);
        assert_eq!(HEADER_LEN, 116);
        assert_eq!(version::pack(1, 2, 3), Some(0x010203));
        assert_eq!(version::pack(256, 0, 0), None);
    }
}
