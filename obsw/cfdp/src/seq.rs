//! Where a platform keeps its entity's next transaction sequence number across resets
//! (`Parts::next_seq`): transaction IDs must not repeat, or the ground takes a new
//! transaction's PDUs for an old one's. Read at start-up into `Parts::set_next_seq`, written
//! each time the number changes. Generic, so that a platform's file service names only the
//! store it runs on.

use crate::flash::FlashStore;
use crate::store::MemStore;
use crate::StoreError;
use embedded_storage::nor_flash::MultiwriteNorFlash;

/// A store that keeps the next transaction sequence number.
pub trait KeepSeq {
    /// The number last kept; `None` when none was (a new store).
    fn kept_seq(&self) -> Option<u16>;
    /// Keeps `seq`; after a power cut during the call the store holds the number before
    /// or `seq`.
    fn keep_seq(&self, seq: u16) -> Result<(), StoreError>;
}

/// Under its own key of the directory map ([`crate::flash::SEQ_KEY`]).
impl<F: MultiwriteNorFlash> KeepSeq for FlashStore<F> {
    fn kept_seq(&self) -> Option<u16> {
        FlashStore::kept_seq(self)
    }
    fn keep_seq(&self, seq: u16) -> Result<(), StoreError> {
        FlashStore::keep_seq(self, seq)
    }
}

/// A RAM store keeps nothing across a reset, its files included: the number lives in
/// `Parts` as long as the files do.
impl<const N: usize, const CAP: usize> KeepSeq for MemStore<N, CAP> {
    fn kept_seq(&self) -> Option<u16> {
        None
    }
    fn keep_seq(&self, _seq: u16) -> Result<(), StoreError> {
        Ok(())
    }
}
