//! Software update of an MMIC-I robot, the same code for the ground's signer, the host's
//! boot launcher and obsw, and board A:
//!
//! - [`otadata`]: ESP-IDF's OTA data — two 32-byte records in two flash sectors, the
//!   choice of the slot that boots, the rollback of an image that never confirms — as
//!   ESP-IDF's second-stage bootloader and `esp_ota_ops` read and write them, so that the
//!   real bootloader and this crate agree on every record either writes.
//! - [`image`]: the signed image (`mib::update`): header, SHA-256 of the payload, Ed25519
//!   signature by the ground's update key; [`image::install`] copies an image into a slot
//!   and verifies what the slot then holds.
//! - [`flash`]: the NOR flash both work on (`embedded-storage`'s `NorFlash`, behind an
//!   object-safe trait so that a service can hold any platform's flash).
//!
//! no_std, no heap; every input is checked, nothing panics on input.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]

pub mod flash;
#[cfg(feature = "std")]
pub mod host;
pub mod image;
pub mod otadata;

pub use flash::{Flash, FlashError};
