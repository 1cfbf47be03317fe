//! One NOR flash shared by the flash layouts that live on it: board A's key and counter
//! area (`link_store`) and the PUS 15 store (`obsw_core::flash_store`) sit in partitions
//! of the same chip, driven by one driver. The sharing is the store's own
//! [`obsw_core::flash_store::Shared`] (blocking and async NOR traits), named here for the
//! boards.

pub use obsw_core::flash_store::{Shared as SharedFlash, SharedError};
