//! What a platform's file service asks of its store beyond [`crate::FlatStore`]: where it
//! keeps its entity's next transaction sequence number across resets ([`KeepSeq`];
//! `Parts::next_seq`: transaction IDs must not repeat, or the ground takes a new
//! transaction's PDUs for an old one's; read at start-up into `Parts::set_next_seq`, written
//! each time the number changes), and the erases it can do ahead of need ([`EraseAhead`]).
//! Generic, so that a platform's file service names only the store it runs on.

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

/// A store that makes room ahead of need, one step a call, in periods with time to spare.
pub trait EraseAhead {
    /// One step (at most one sector erase); `Ok(false)` when none is left.
    fn erase_ahead(&self) -> Result<bool, StoreError>;
}

/// Free data sectors erased ([`FlashStore::erase_ahead`]), so a transfer's writes erase none.
impl<F: MultiwriteNorFlash> EraseAhead for FlashStore<F> {
    fn erase_ahead(&self) -> Result<bool, StoreError> {
        FlashStore::erase_ahead(self)
    }
}

/// RAM needs no erase.
impl<const N: usize, const CAP: usize> EraseAhead for MemStore<N, CAP> {
    fn erase_ahead(&self) -> Result<bool, StoreError> {
        Ok(false)
    }
}
