//! SDLS (CCSDS 355.0-B-2) with AES-256-GCM authenticated encryption, in the layout Yamcs
//! 5.12.8 uses (`SecurityAssociationAes256Gcm128`, `StandardAuthMask`, `TcFrameFactory`):
//!
//! ```text
//! TC: | primary header 5 | SPI 2 | IV 12 | ciphertext … | MAC 16 | FECF 2 |
//! TM: | primary header 6 | SPI 2 | IV 12 | ciphertext … | MAC 16 | OCF 4 | FECF 2 |
//! ```
//! No segment header on TC (Yamcs adds one only when the VC has a MAP id), no padding, the IV
//! is the anti-replay sequence number (big-endian, 96 bits). The additional authenticated data
//! is the frame from its first byte to the end of the security header, ANDed with Yamcs'
//! default mask: TC `00 00 FC 00 00` + `FF FF` + 12×`00` (VCID and SPI authenticated), TM
//! `00 0E 00 00 00 00` + `FF FF` + 12×`00`. The IV is authenticated as the GCM nonce; the
//! plaintext is authenticated by GCM itself. The OCF and FECF are outside the MAC.
//!
//! Nonces are never reused: a transmit SA reserves IVs in blocks through [`IvStore`] — the
//! high-water mark is stored *before* the first IV of a block is used — and resumes after a
//! restart at the stored high-water mark. A receive SA accepts IVs in (last, last + N] and
//! stores the new `last` before the frame is handed on.

use core::fmt;
use core::ops::Range;

use mib::link::sdls::{HEADER_LEN, IV_LEN, IV_RESERVE_BLOCK, KEY_LEN, MAC_LEN, SPI_LEN};

use crate::farm::FarmRecord;
use crate::gcm::{Gcm, Job, Progress};

/// An AES-256 key.
pub type Key = [u8; KEY_LEN];

/// IVs are 96-bit counters.
pub const IV_MODULUS: u128 = 1 << 96;

/// Yamcs' default TC authentication mask (no segment header), frame start to end of the
/// security header.
pub const TC_AUTH_MASK: [u8; 5 + HEADER_LEN] = [0, 0, 0xFC, 0, 0, 0xFF, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
/// Yamcs' default TM authentication mask (no secondary header).
pub const TM_AUTH_MASK: [u8; 6 + HEADER_LEN] = [0, 0x0E, 0, 0, 0, 0, 0xFF, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];

/// Why a frame failed security processing. Each is counted separately by the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdlsError {
    /// The data field cannot hold a security header and trailer.
    TooShort(usize),
    /// No security association for this SPI in this direction.
    UnknownSpi(u16),
    /// The IV lies outside (last, last + N]: a replay or a frame from far behind/ahead.
    Replay,
    /// GCM tag mismatch: wrong key, altered frame or forged frame.
    BadMac,
    /// The transmit counter reached 2^96 (never in practice; refusing beats reusing).
    CounterExhausted,
    /// The counter store refused to persist; the IV is not used.
    StoreFailed,
}

impl fmt::Display for SdlsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SdlsError::TooShort(n) => write!(f, "SDLS data field of {n} bytes too short"),
            SdlsError::UnknownSpi(s) => write!(f, "unknown SPI {s}"),
            SdlsError::Replay => write!(f, "IV outside the anti-replay window"),
            SdlsError::BadMac => write!(f, "MAC verification failed"),
            SdlsError::CounterExhausted => write!(f, "IV counter exhausted"),
            SdlsError::StoreFailed => write!(f, "IV counter store failed"),
        }
    }
}

impl core::error::Error for SdlsError {}

/// The persistence failed (the host's state file, the board's flash).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreError;

/// Durable storage of the IV counters (and the on-board FARM-1 state), implemented by the
/// host (a state file written in place and synced, `persist::FileIvStore`) or the firmware
/// (a flash area). Every call must return only once the value survives a restart.
pub trait IvStore {
    /// The sender of `spi` may use every IV below `high_water`. On restart it resumes at the
    /// stored value.
    fn reserve_tx(&mut self, spi: u16, high_water: u128) -> Result<(), StoreError>;
    /// The receiver of `spi` accepted `last`; after a restart it accepts only IVs above it.
    fn record_rx(&mut self, spi: u16, last: u128) -> Result<(), StoreError>;
    /// The on-board TC path: the receiver of `spi` accepted `last` and FARM-1 is now
    /// `farm`, both in **one** durable write. The frame is used only after this returned Ok.
    fn record_rx_farm(&mut self, spi: u16, last: u128, farm: FarmRecord) -> Result<(), StoreError>;
    /// FARM-1 changed without an IV (a control frame, which comes in clear).
    fn record_farm(&mut self, farm: FarmRecord) -> Result<(), StoreError>;
}

/// An in-memory [`IvStore`] (tests, simulator). `fail` makes every call fail.
#[derive(Debug, Default, Clone)]
pub struct MemoryIvStore {
    pub tx: heapless::Vec<(u16, u128), 8>,
    pub rx: heapless::Vec<(u16, u128), 8>,
    /// The FARM-1 record last stored.
    pub farm: Option<FarmRecord>,
    pub writes: u32,
    pub fail: bool,
}

impl MemoryIvStore {
    fn put(v: &mut heapless::Vec<(u16, u128), 8>, spi: u16, val: u128) -> Result<(), StoreError> {
        if let Some(e) = v.iter_mut().find(|e| e.0 == spi) {
            e.1 = val;
            return Ok(());
        }
        v.push((spi, val)).map_err(|_| StoreError)
    }

    pub fn tx_high_water(&self, spi: u16) -> Option<u128> {
        self.tx.iter().find(|e| e.0 == spi).map(|e| e.1)
    }

    pub fn rx_last(&self, spi: u16) -> Option<u128> {
        self.rx.iter().find(|e| e.0 == spi).map(|e| e.1)
    }
}

impl IvStore for MemoryIvStore {
    fn reserve_tx(&mut self, spi: u16, high_water: u128) -> Result<(), StoreError> {
        if self.fail {
            return Err(StoreError);
        }
        self.writes += 1;
        Self::put(&mut self.tx, spi, high_water)
    }

    fn record_rx(&mut self, spi: u16, last: u128) -> Result<(), StoreError> {
        if self.fail {
            return Err(StoreError);
        }
        self.writes += 1;
        Self::put(&mut self.rx, spi, last)
    }

    fn record_rx_farm(&mut self, spi: u16, last: u128, farm: FarmRecord) -> Result<(), StoreError> {
        self.record_rx(spi, last)?;
        self.farm = Some(farm);
        Ok(())
    }

    fn record_farm(&mut self, farm: FarmRecord) -> Result<(), StoreError> {
        if self.fail {
            return Err(StoreError);
        }
        self.writes += 1;
        self.farm = Some(farm);
        Ok(())
    }
}

/// The 12 IV bytes of a counter value (big-endian).
pub fn iv_bytes(counter: u128) -> [u8; IV_LEN] {
    let b = counter.to_be_bytes();
    let mut iv = [0u8; IV_LEN];
    iv.copy_from_slice(&b[16 - IV_LEN..]);
    iv
}

/// The counter value of 12 IV bytes.
pub fn iv_value(iv: &[u8; IV_LEN]) -> u128 {
    let mut b = [0u8; 16];
    b[16 - IV_LEN..].copy_from_slice(iv);
    u128::from_be_bytes(b)
}

fn aad<const N: usize>(header: &[u8], mask: &[u8; N]) -> [u8; N] {
    let mut a = [0u8; N];
    for ((a, h), m) in a.iter_mut().zip(header).zip(mask) {
        *a = h & m;
    }
    a
}

/// A transmit security association: the robot's TM SA, the ground's TC SA.
pub struct TxSa {
    spi: u16,
    cipher: Gcm,
    next: u128,
    reserved: u128,
}

impl fmt::Debug for TxSa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never the key.
        f.debug_struct("TxSa")
            .field("spi", &self.spi)
            .field("next", &self.next)
            .finish()
    }
}

impl TxSa {
    /// A transmit SA resuming at `high_water`, the value last stored by
    /// [`IvStore::reserve_tx`] for this SPI (0 for a new key). The first use reserves a
    /// fresh block, so IVs handed out before a restart are never handed out again.
    pub fn resume(spi: u16, key: &Key, high_water: u128) -> TxSa {
        TxSa {
            spi,
            cipher: Gcm::new(key),
            next: high_water,
            reserved: high_water,
        }
    }

    pub fn spi(&self) -> u16 {
        self.spi
    }

    /// The IV the next frame will carry.
    pub fn next_iv(&self) -> u128 {
        self.next
    }

    fn take_iv(&mut self, store: &mut impl IvStore) -> Result<u128, SdlsError> {
        if self.next >= IV_MODULUS {
            return Err(SdlsError::CounterExhausted);
        }
        if self.next >= self.reserved {
            let hw = (self.next + u128::from(IV_RESERVE_BLOCK)).min(IV_MODULUS);
            store.reserve_tx(self.spi, hw).map_err(|_| SdlsError::StoreFailed)?;
            self.reserved = hw;
        }
        let iv = self.next;
        self.next += 1;
        Ok(iv)
    }

    /// Starts protecting a frame in place. `frame[..hdr_end]` is the frame header (already
    /// written), `frame[hdr_end..hdr_end + 14]` receives the security header (the IV is
    /// taken now), `frame[hdr_end + 14..mac_start]` is the plaintext,
    /// `frame[mac_start..mac_start + 16]` receives the MAC when [`TxSa::seal`] finishes.
    /// `mask` is the authentication mask over header + security header.
    fn begin<const M: usize>(
        &mut self,
        store: &mut impl IvStore,
        frame: &mut [u8],
        hdr_end: usize,
        mac_start: usize,
        mask: &[u8; M],
    ) -> Result<Sealing, SdlsError> {
        if mac_start < hdr_end + HEADER_LEN || mac_start + MAC_LEN > frame.len() || hdr_end + HEADER_LEN != M {
            return Err(SdlsError::TooShort(mac_start.saturating_sub(hdr_end)));
        }
        let iv = self.take_iv(store)?;
        let ivb = iv_bytes(iv);
        frame[hdr_end..hdr_end + SPI_LEN].copy_from_slice(&self.spi.to_be_bytes());
        frame[hdr_end + SPI_LEN..hdr_end + HEADER_LEN].copy_from_slice(&ivb);
        let a = aad(&frame[..M], mask);
        let data = hdr_end + HEADER_LEN..mac_start;
        Ok(Sealing {
            job: self.cipher.begin_encrypt(&ivb, &a, data.len()),
            spi: self.spi,
            data,
            len: frame.len(),
        })
    }

    /// Continues [`TxSa::begin_tm`]'s encryption of `frame` by at most `work` GCM work
    /// blocks ([`crate::gcm`]); true once the MAC is written. The SA must be the one that
    /// began it ([`Sealing::spi`]).
    pub fn seal(&self, s: &mut Sealing, frame: &mut [u8], work: usize) -> bool {
        if frame.len() != s.len || s.spi != self.spi {
            return false;
        }
        match s.job.step(&self.cipher, &mut frame[s.data.clone()], work) {
            Progress::Sealed(tag) => {
                let m = s.data.end;
                frame[m..m + MAC_LEN].copy_from_slice(&tag);
                true
            }
            Progress::Pending | Progress::Opened | Progress::Refused => false,
        }
    }

    fn apply<const M: usize>(
        &mut self,
        store: &mut impl IvStore,
        frame: &mut [u8],
        hdr_end: usize,
        mac_start: usize,
        mask: &[u8; M],
    ) -> Result<(), SdlsError> {
        let mut s = self.begin(store, frame, hdr_end, mac_start, mask)?;
        while !self.seal(&mut s, frame, usize::MAX) {}
        Ok(())
    }

    /// Protects a TC frame in place: `frame` is the whole frame (header written, data field
    /// = security header space + plaintext + MAC space, FECF space); the FECF is not written.
    pub fn apply_tc(&mut self, store: &mut impl IvStore, frame: &mut [u8]) -> Result<(), SdlsError> {
        let hl = mib::link::tc_frame::HEADER_LEN;
        let Some(mac_start) = frame.len().checked_sub(MAC_LEN + mib::link::tc_frame::FECF_LEN) else {
            return Err(SdlsError::TooShort(frame.len()));
        };
        self.apply(store, frame, hl, mac_start, &TC_AUTH_MASK)
    }

    /// Protects a TM frame in place (data field = security header + packet zone + MAC); OCF
    /// and FECF are written afterwards by the caller.
    pub fn apply_tm(&mut self, store: &mut impl IvStore, frame: &mut [u8]) -> Result<(), SdlsError> {
        use mib::link::tm_frame::{FECF_LEN, HEADER_LEN as TH, OCF_LEN};
        let Some(mac_start) = frame.len().checked_sub(MAC_LEN + OCF_LEN + FECF_LEN) else {
            return Err(SdlsError::TooShort(frame.len()));
        };
        self.apply(store, frame, TH, mac_start, &TM_AUTH_MASK)
    }

    /// Starts protecting a TM frame in place (as [`TxSa::apply_tm`], the IV taken now); the
    /// encryption runs in [`TxSa::seal`] steps.
    pub fn begin_tm(&mut self, store: &mut impl IvStore, frame: &mut [u8]) -> Result<Sealing, SdlsError> {
        use mib::link::tm_frame::{FECF_LEN, HEADER_LEN as TH, OCF_LEN};
        let Some(mac_start) = frame.len().checked_sub(MAC_LEN + OCF_LEN + FECF_LEN) else {
            return Err(SdlsError::TooShort(frame.len()));
        };
        self.begin(store, frame, TH, mac_start, &TM_AUTH_MASK)
    }
}

/// A frame being protected in steps ([`TxSa::begin_tm`], [`TxSa::seal`]).
#[derive(Clone, Debug)]
pub struct Sealing {
    job: Job,
    spi: u16,
    /// The plaintext's range; the MAC follows it.
    data: Range<usize>,
    /// The frame's length.
    len: usize,
}

impl Sealing {
    /// The SPI of the SA that began it.
    pub fn spi(&self) -> u16 {
        self.spi
    }
}

/// A TC frame being verified and decrypted in steps ([`RxSas::open_tc`], [`RxSas::open`]).
#[derive(Clone, Debug)]
pub struct Opening {
    job: Job,
    spi: u16,
    iv: u128,
    data: Range<usize>,
    len: usize,
}

/// A receive security association: the robot's TC SA, the ground's TM SA.
pub struct RxSa {
    spi: u16,
    cipher: Gcm,
    last: u128,
    window: u64,
}

impl fmt::Debug for RxSa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RxSa")
            .field("spi", &self.spi)
            .field("last", &self.last)
            .finish()
    }
}

impl RxSa {
    /// A receive SA for a key never used: accepts IVs 0..N (Yamcs starts its counter at 0).
    pub fn new(spi: u16, key: &Key, window: u64) -> RxSa {
        RxSa {
            spi,
            cipher: Gcm::new(key),
            last: IV_MODULUS - 1,
            window,
        }
    }

    /// A receive SA resuming after the last accepted IV (the value stored by
    /// [`IvStore::record_rx`]).
    pub fn resume(spi: u16, key: &Key, window: u64, last: u128) -> RxSa {
        RxSa {
            spi,
            cipher: Gcm::new(key),
            last: last % IV_MODULUS,
            window,
        }
    }

    pub fn spi(&self) -> u16 {
        self.spi
    }

    pub fn last(&self) -> u128 {
        self.last
    }

    /// Whether `iv` lies in (last, last + N], modulo 2^96.
    pub fn in_window(&self, iv: u128) -> bool {
        let d = (iv + IV_MODULUS - self.last) % IV_MODULUS;
        d >= 1 && d <= u128::from(self.window)
    }

    /// Window check, then the start of MAC check and decryption in place (steps:
    /// [`RxSas::open`]); `last` does not move (see [`RxSas::commit`]).
    fn begin<const M: usize>(
        &self,
        frame: &[u8],
        hdr_end: usize,
        mac_start: usize,
        mask: &[u8; M],
    ) -> Result<Opening, SdlsError> {
        let mut ivb = [0u8; IV_LEN];
        ivb.copy_from_slice(&frame[hdr_end + SPI_LEN..hdr_end + HEADER_LEN]);
        let iv = iv_value(&ivb);
        // Cheap check first: a replay flood costs no AES. `last` moves only after the MAC.
        if !self.in_window(iv) {
            return Err(SdlsError::Replay);
        }
        let a = aad(&frame[..M], mask);
        let mut tag = [0u8; MAC_LEN];
        tag.copy_from_slice(&frame[mac_start..mac_start + MAC_LEN]);
        let data = hdr_end + HEADER_LEN..mac_start;
        Ok(Opening {
            job: self.cipher.begin_decrypt(&ivb, &a, data.len(), &tag),
            spi: self.spi,
            iv,
            data,
            len: frame.len(),
        })
    }
}

/// An authentic frame whose IV is not yet recorded: [`RxSas::verify_tc`]'s result. Its IV
/// becomes the SA's `last` with [`RxSas::commit`], once the store has it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Verified {
    pub spi: u16,
    pub iv: u128,
    /// The plaintext's range in the frame.
    pub data: Range<usize>,
}

/// The receive SAs of one direction (two for key change without downtime).
#[derive(Debug)]
pub struct RxSas<const N: usize> {
    sas: heapless::Vec<RxSa, N>,
}

impl<const N: usize> Default for RxSas<N> {
    fn default() -> Self {
        RxSas {
            sas: heapless::Vec::new(),
        }
    }
}

impl<const N: usize> RxSas<N> {
    /// Adds or replaces the SA of its SPI; hands it back when full (workspace rule: a failed
    /// push returns the item, however large).
    #[allow(clippy::result_large_err)]
    pub fn insert(&mut self, sa: RxSa) -> Result<(), RxSa> {
        if let Some(s) = self.sas.iter_mut().find(|s| s.spi == sa.spi) {
            *s = sa;
            return Ok(());
        }
        self.sas.push(sa)
    }

    /// Removes the SA of `spi` (key retired); true when there was one.
    pub fn remove(&mut self, spi: u16) -> bool {
        let before = self.sas.len();
        self.sas.retain(|s| s.spi != spi);
        self.sas.len() != before
    }

    pub fn get(&self, spi: u16) -> Option<&RxSa> {
        self.sas.iter().find(|s| s.spi == spi)
    }

    /// Number of SAs.
    pub fn len(&self) -> usize {
        self.sas.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sas.is_empty()
    }

    fn find(&self, frame: &[u8], hdr_end: usize) -> Result<&RxSa, SdlsError> {
        let spi = u16::from_be_bytes([frame[hdr_end], frame[hdr_end + 1]]);
        self.get(spi).ok_or(SdlsError::UnknownSpi(spi))
    }

    /// Continues an opening over `frame` by at most `work` GCM work blocks
    /// ([`crate::gcm`]): `None` while pending, then the authentic frame (decrypted in
    /// place) or why not. The ciphertext is decrypted only after its MAC matched.
    pub fn open(&self, o: &mut Opening, frame: &mut [u8], work: usize) -> Option<Result<Verified, SdlsError>> {
        let Some(sa) = self.get(o.spi) else {
            // The SA went away meanwhile (key retired).
            return Some(Err(SdlsError::UnknownSpi(o.spi)));
        };
        if frame.len() != o.len {
            return Some(Err(SdlsError::BadMac));
        }
        match o.job.step(&sa.cipher, &mut frame[o.data.clone()], work) {
            Progress::Pending => None,
            Progress::Opened => Some(Ok(Verified {
                spi: o.spi,
                iv: o.iv,
                data: o.data.clone(),
            })),
            Progress::Refused | Progress::Sealed(_) => Some(Err(SdlsError::BadMac)),
        }
    }

    fn open_all(&self, mut o: Opening, frame: &mut [u8]) -> Result<Verified, SdlsError> {
        loop {
            if let Some(r) = self.open(&mut o, frame, usize::MAX) {
                return r;
            }
        }
    }

    /// The start of [`RxSas::verify_tc`] (SDLS data field size, SPI, anti-replay window):
    /// the MAC check and decryption then run in [`RxSas::open`] steps.
    pub fn open_tc(&self, frame: &[u8]) -> Result<Opening, SdlsError> {
        use mib::link::tc_frame::{FECF_LEN, HEADER_LEN as H};
        let data_len = frame.len().saturating_sub(H + FECF_LEN);
        if data_len < HEADER_LEN + MAC_LEN {
            return Err(SdlsError::TooShort(data_len));
        }
        let mac_start = frame.len() - FECF_LEN - MAC_LEN;
        self.find(frame, H)?.begin(frame, H, mac_start, &TC_AUTH_MASK)
    }

    /// Verifies and decrypts a TC frame in place (`frame` = whole frame, FECF included and
    /// already checked, header lengths already checked), recording the IV with
    /// [`IvStore::record_rx`]. Returns the plaintext's range.
    pub fn process_tc(&mut self, store: &mut impl IvStore, frame: &mut [u8]) -> Result<Range<usize>, SdlsError> {
        let v = self.verify_tc(frame)?;
        store.record_rx(v.spi, v.iv).map_err(|_| SdlsError::StoreFailed)?;
        self.commit(&v);
        Ok(v.data)
    }

    /// Verifies and decrypts a TC frame in place without recording its IV: the caller
    /// stores it (with FARM-1's state, [`IvStore::record_rx_farm`]) and then calls
    /// [`RxSas::commit`]. Until then the SA's window is unchanged.
    pub fn verify_tc(&mut self, frame: &mut [u8]) -> Result<Verified, SdlsError> {
        let o = self.open_tc(frame)?;
        self.open_all(o, frame)
    }

    /// The verified frame's IV becomes its SA's `last` (after the store has it).
    pub fn commit(&mut self, v: &Verified) {
        if let Some(sa) = self.sas.iter_mut().find(|s| s.spi == v.spi) {
            sa.last = v.iv;
        }
    }

    /// Verifies and decrypts a TM frame in place (`frame` = the whole fixed-length frame).
    pub fn process_tm(&mut self, store: &mut impl IvStore, frame: &mut [u8]) -> Result<Range<usize>, SdlsError> {
        use mib::link::tm_frame::{FECF_LEN, HEADER_LEN as H, OCF_LEN};
        let data_len = frame.len().saturating_sub(H + OCF_LEN + FECF_LEN);
        if data_len < HEADER_LEN + MAC_LEN {
            return Err(SdlsError::TooShort(data_len));
        }
        let mac_start = frame.len() - FECF_LEN - OCF_LEN - MAC_LEN;
        let o = self.find(frame, H)?.begin(frame, H, mac_start, &TM_AUTH_MASK)?;
        let v = self.open_all(o, frame)?;
        store.record_rx(v.spi, v.iv).map_err(|_| SdlsError::StoreFailed)?;
        self.commit(&v);
        Ok(v.data)
    }
}

/// Builds an SDLS-protected TC frame carrying `payload` into `buf`: header, security header,
/// ciphertext, MAC, FECF. Returns its length. The ground's uplink (and the tests) use this.
/// `header.data_len` is ignored (computed from the payload).
pub fn build_tc(
    sa: &mut TxSa,
    store: &mut impl IvStore,
    header: crate::tc::TcRepr,
    payload: &[u8],
    buf: &mut [u8],
) -> Result<usize, SdlsError> {
    use crate::tc::{TcFrame, TcRepr};
    let data_len = HEADER_LEN + payload.len() + MAC_LEN;
    let repr = TcRepr { data_len, ..header };
    let n = repr.buffer_len();
    if payload.is_empty() || n > mib::link::tc_frame::MAX_LEN || n > buf.len() {
        return Err(SdlsError::TooShort(payload.len()));
    }
    let frame = &mut buf[..n];
    repr.emit(&mut TcFrame::new_unchecked(&mut *frame));
    let p = mib::link::tc_frame::HEADER_LEN + HEADER_LEN;
    frame[p..p + payload.len()].copy_from_slice(payload);
    sa.apply_tc(store, frame)?;
    crate::fecf::seal(frame);
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tc::FrameType;
    use crate::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B};
    use aes_gcm::aead::generic_array::typenum::U8;
    use aes_gcm::aead::AeadInPlace;
    use aes_gcm::aes::Aes256;
    use aes_gcm::{Aes256Gcm, AesGcm, KeyInit, Nonce, Tag};

    fn h(s: &str) -> Vec<u8> {
        hex::decode(s.replace([' ', '\n'], "")).unwrap()
    }

    fn gcm(key: &str, iv: &str, pt: &str, aad: &str) -> (Vec<u8>, Vec<u8>) {
        let c = Aes256Gcm::new_from_slice(&h(key)).unwrap();
        let mut buf = h(pt);
        let tag = c
            .encrypt_in_place_detached(Nonce::from_slice(&h(iv)), &h(aad), &mut buf)
            .unwrap();
        (buf, tag.to_vec())
    }

    const K0: &str = "0000000000000000000000000000000000000000000000000000000000000000";
    const K15: &str = "feffe9928665731c6d6a8f9467308308feffe9928665731c6d6a8f9467308308";
    const P15: &str = "d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a72\
                       1c3c0c95956809532fcf0e2449a6b525b16aedf5aa0de657ba637b391aafd255";
    const P16: &str = "d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a72\
                       1c3c0c95956809532fcf0e2449a6b525b16aedf5aa0de657ba637b39";
    const A16: &str = "feedfacedeadbeeffeedfacedeadbeefabaddad2";

    // verifies: LINK-SDLS-01
    #[test]
    fn nist_gcm_test_cases_13_to_16_aes256_96bit_iv() {
        // McGrew & Viega, "The Galois/Counter Mode of Operation", test cases 13-16.
        let (c, t) = gcm(K0, "000000000000000000000000", "", "");
        assert!(c.is_empty());
        assert_eq!(t, h("530f8afbc74536b9a963b4f1c4cb738b"));
        let (c, t) = gcm(K0, "000000000000000000000000", "00000000000000000000000000000000", "");
        assert_eq!(c, h("cea7403d4d606b6e074ec5d3baf39d18"));
        assert_eq!(t, h("d0d1c8a799996bf0265b98b5d48ab919"));
        let (c, t) = gcm(K15, "cafebabefacedbaddecaf888", P15, "");
        assert_eq!(
            c,
            h("522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa\
               8cb08e48590dbb3da7b08b1056828838c5f61e6393ba7a0abcc9f662898015ad")
        );
        assert_eq!(t, h("b094dac5d93471bdec1a502270e3cc6c"));
        let (c, t) = gcm(K15, "cafebabefacedbaddecaf888", P16, A16);
        assert_eq!(
            c,
            h("522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa\
               8cb08e48590dbb3da7b08b1056828838c5f61e6393ba7a0abcc9f662")
        );
        assert_eq!(t, h("76fc6ece0f4e1768cddf8853bb2d551b"));
        // Decrypting with a flipped tag bit fails.
        let cph = Aes256Gcm::new_from_slice(&h(K15)).unwrap();
        let mut ct = c.clone();
        let mut bad = t.clone();
        bad[0] ^= 1;
        assert!(cph
            .decrypt_in_place_detached(
                Nonce::from_slice(&h("cafebabefacedbaddecaf888")),
                &h(A16),
                &mut ct,
                Tag::from_slice(&bad)
            )
            .is_err());
    }

    // verifies: LINK-SDLS-01
    #[test]
    fn nist_gcm_test_case_17_aes256_64bit_iv() {
        // Test case 17: the 64-bit IV (not used by SDLS; checks the GHASH-derived J0 path).
        let c = AesGcm::<Aes256, U8>::new_from_slice(&h(K15)).unwrap();
        let mut buf = h(P16);
        let tag = c
            .encrypt_in_place_detached(
                aes_gcm::Nonce::<U8>::from_slice(&h("cafebabefacedbad")),
                &h(A16),
                &mut buf,
            )
            .unwrap();
        assert_eq!(
            buf,
            h("c3762df1ca787d32ae47c13bf19844cbaf1ae14d0b976afac52ff7d79bba9de0\
               feb582d33934a4f0954cc2363bc73f7862ac430e64abe499f47c9b1f")
        );
        assert_eq!(tag.to_vec(), h("3a337dbf46a792c45e454913fe2ea8f2"));
    }

    // verifies: LINK-SDLS-02
    #[test]
    fn cryptolib_v1_3_1_auth_only_tc_frame_mac() {
        // NASA CryptoLib v1.3.1 test/unit/et_dt_validation.c, NIST_DEC_MAC_VALIDATION
        // AES_GCM_256_IV_96_PT_128_TEST_0: SA 9, authentication only, ABM all ones.
        // | 2003003700 | FF seg hdr | 0009 SPI | IV 12 | 0000 ARSN | PT 16 | MAC 16 | FECF |
        let frame = h(
            "2003003700FF0009D79CF22D504CC793C3FB6C8A0000722ee47da4b77424733546c2d400c4e5\
                       E7BB31D506998FCBDA078E66D5680194B401",
        );
        let key = h("78dc4e0aaf52d935c3c01eea57428f00ca1fd475f5da86a49c8dd73d68c8e223");
        assert_eq!(frame.len(), 56);
        let iv = &frame[8..20];
        let mac = &frame[38..54];
        // GCM with empty plaintext, the frame up to the MAC as AAD.
        let (c, t) = gcm(&hex::encode(&key), &hex::encode(iv), "", &hex::encode(&frame[..38]));
        assert!(c.is_empty());
        assert_eq!(t, mac);
        assert_eq!(t, h("E7BB31D506998FCBDA078E66D5680194"));
        // The frame's CRC bytes are wrong (B401); CRC-16/CCITT-FALSE gives 78CB.
        assert_eq!(crate::fecf::crc16(&frame[..54]), 0x78CB);
        // One flipped bit in the authenticated part changes the MAC.
        let mut f2 = frame.clone();
        f2[30] ^= 1;
        let (_, t2) = gcm(&hex::encode(&key), &hex::encode(iv), "", &hex::encode(&f2[..38]));
        assert_ne!(t2, mac);
    }

    fn hdr(frame_type: FrameType, scid: u16) -> crate::tc::TcRepr {
        crate::tc::TcRepr {
            frame_type,
            scid,
            vcid: 0,
            seq: 0,
            data_len: 0,
        }
    }

    fn pair() -> (TxSa, RxSas<2>, MemoryIvStore, MemoryIvStore) {
        let tx = TxSa::resume(1, &TEST_KEY_TC_A, 0);
        let mut rx = RxSas::default();
        rx.insert(RxSa::new(1, &TEST_KEY_TC_A, 64)).unwrap();
        (tx, rx, MemoryIvStore::default(), MemoryIvStore::default())
    }

    fn frame(tx: &mut TxSa, st: &mut MemoryIvStore, payload: &[u8]) -> Vec<u8> {
        let mut buf = [0u8; 1024];
        let n = build_tc(tx, st, hdr(FrameType::Ad, 0x0AB), payload, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    // verifies: LINK-SDLS-03
    #[test]
    fn tc_layout_is_yamcs_layout() {
        let (mut tx, _, mut st, _) = pair();
        let f = frame(&mut tx, &mut st, b"hello");
        assert_eq!(f.len(), 5 + 14 + 5 + 16 + 2);
        assert_eq!(&f[5..7], &[0, 1]);
        assert_eq!(&f[7..19], &[0u8; 12]); // first IV is 0, as Yamcs'
        assert_ne!(&f[19..24], b"hello"); // encrypted
                                          // Independently recompute: AAD = masked header ‖ SPI ‖ zero IV.
        let mut aad = [0u8; 19];
        aad[2] = f[2] & 0xFC;
        aad[5] = 0;
        aad[6] = 1;
        let (c, t) = gcm(
            &hex::encode(TEST_KEY_TC_A),
            &hex::encode(&f[7..19]),
            &hex::encode(b"hello"),
            &hex::encode(aad),
        );
        assert_eq!(&f[19..24], &c[..]);
        assert_eq!(&f[24..40], &t[..]);
        assert!(crate::fecf::check(&f));
        let f2 = frame(&mut tx, &mut st, b"x");
        assert_eq!(iv_value(f2[7..19].try_into().unwrap()), 1);
    }

    // verifies: LINK-SDLS-03, LINK-SDLS-04
    #[test]
    fn tc_round_trip_and_rejections() {
        let (mut tx, mut rx, mut st, mut rst) = pair();
        let f0 = frame(&mut tx, &mut st, b"packet-0");
        let mut g = f0.clone();
        let r = rx.process_tc(&mut rst, &mut g).unwrap();
        assert_eq!(&g[r], b"packet-0");
        assert_eq!(rst.rx_last(1), Some(0));
        // Replay of the same captured frame.
        let mut g = f0.clone();
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::Replay));
        // A flipped ciphertext bit: bad MAC, last unchanged.
        let f1 = frame(&mut tx, &mut st, b"packet-1");
        let mut g = f1.clone();
        g[20] ^= 4;
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::BadMac));
        // The flipped VCID is authenticated (mask FC), the SCID is not (mask 00).
        let mut g = f1.clone();
        g[2] ^= 0x04;
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::BadMac));
        let mut g = f1.clone();
        g[1] ^= 0x01;
        assert!(rx.process_tc(&mut rst, &mut g).is_ok());
        // Wrong key.
        let mut wrong = TxSa::resume(1, &TEST_KEY_TC_B, 10);
        let mut g = frame(&mut wrong, &mut st, b"evil");
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::BadMac));
        // Unknown SPI.
        let mut other = TxSa::resume(9, &TEST_KEY_TC_A, 5);
        let mut g = frame(&mut other, &mut st, b"evil");
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::UnknownSpi(9)));
        // Too short to hold the security header and trailer.
        let mut g = vec![0u8; 5 + 29 + 2];
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::TooShort(29)));
        // A store failure refuses the frame and leaves `last`.
        let f2 = frame(&mut tx, &mut st, b"p2");
        rst.fail = true;
        let mut g = f2.clone();
        assert_eq!(rx.process_tc(&mut rst, &mut g), Err(SdlsError::StoreFailed));
        rst.fail = false;
        let mut g = f2.clone();
        assert!(rx.process_tc(&mut rst, &mut g).is_ok());
    }

    // verifies: LINK-SDLS-04
    #[test]
    fn anti_replay_window_is_last_exclusive_to_last_plus_n() {
        let mut rx = RxSa::resume(1, &TEST_KEY_TC_A, 64, 100);
        assert!(!rx.in_window(100));
        assert!(rx.in_window(101));
        assert!(rx.in_window(164));
        assert!(!rx.in_window(165));
        assert!(!rx.in_window(99));
        // Wrap at 2^96.
        rx.last = IV_MODULUS - 2;
        assert!(rx.in_window(IV_MODULUS - 1));
        assert!(rx.in_window(0));
        assert!(rx.in_window(62));
        assert!(!rx.in_window(63));
        // A fresh SA accepts 0..64.
        let fresh = RxSa::new(1, &TEST_KEY_TC_A, 64);
        assert!(fresh.in_window(0) && fresh.in_window(63) && !fresh.in_window(64));
    }

    // verifies: LINK-SDLS-05, LINK-SDLS-04
    #[test]
    fn receiver_with_mission_window_accepts_the_senders_restart_jump() {
        use mib::link::sdls::ANTI_REPLAY_WINDOW;
        let (mut st, mut rst) = (MemoryIvStore::default(), MemoryIvStore::default());
        let mut rx: RxSas<2> = RxSas::default();
        rx.insert(RxSa::new(1, &TEST_KEY_TC_A, ANTI_REPLAY_WINDOW)).unwrap();
        let mut tx = TxSa::resume(1, &TEST_KEY_TC_A, 0);
        let mut f = frame(&mut tx, &mut st, b"before");
        assert!(rx.process_tc(&mut rst, &mut f).is_ok());
        // The sender restarts: it resumes a whole block ahead.
        let mut tx = TxSa::resume(1, &TEST_KEY_TC_A, st.tx_high_water(1).unwrap());
        let mut f = frame(&mut tx, &mut st, b"after");
        assert_eq!(iv_value(f[7..19].try_into().unwrap()), 1024);
        assert!(rx.process_tc(&mut rst, &mut f).is_ok());
        // The receiver restarts too: it resumes at its stored `last`.
        let mut rx2: RxSas<2> = RxSas::default();
        rx2.insert(RxSa::resume(
            1,
            &TEST_KEY_TC_A,
            ANTI_REPLAY_WINDOW,
            rst.rx_last(1).unwrap(),
        ))
        .unwrap();
        let mut again = f.clone();
        assert_eq!(rx2.process_tc(&mut rst, &mut again), Err(SdlsError::Replay));
    }

    // verifies: LINK-SDLS-05
    #[test]
    fn tx_counter_reserved_before_use_and_never_reused_after_restart() {
        let mut st = MemoryIvStore::default();
        let mut tx = TxSa::resume(17, &TEST_KEY_TC_A, 0);
        let mut seen = std::collections::HashSet::new();
        let mut buf = [0u8; 64];
        for _ in 0..1500 {
            build_tc(&mut tx, &mut st, hdr(FrameType::Bd, 1), b"abc", &mut buf).unwrap();
            let iv = iv_value(buf[7..19].try_into().unwrap());
            // The stored high-water mark covers every IV handed out.
            assert!(iv < st.tx_high_water(17).unwrap());
            assert!(seen.insert(iv));
        }
        assert_eq!(st.writes, 2); // two blocks of 1024 for 1500 frames
                                  // "Restart": resume from the stored high-water mark.
        let hw = st.tx_high_water(17).unwrap();
        let mut tx2 = TxSa::resume(17, &TEST_KEY_TC_A, hw);
        for _ in 0..10 {
            build_tc(&mut tx2, &mut st, hdr(FrameType::Bd, 1), b"abc", &mut buf).unwrap();
            assert!(seen.insert(iv_value(buf[7..19].try_into().unwrap())));
        }
        // A store failure: no frame, no IV consumed.
        let mut st_fail = MemoryIvStore {
            fail: true,
            ..Default::default()
        };
        let mut tx3 = TxSa::resume(17, &TEST_KEY_TC_A, 5000);
        assert_eq!(
            build_tc(&mut tx3, &mut st_fail, hdr(FrameType::Bd, 1), b"abc", &mut buf),
            Err(SdlsError::StoreFailed)
        );
        assert_eq!(tx3.next_iv(), 5000);
        // Exhaustion refuses instead of wrapping.
        let mut tx4 = TxSa::resume(17, &TEST_KEY_TC_A, IV_MODULUS);
        assert_eq!(
            build_tc(&mut tx4, &mut st, hdr(FrameType::Bd, 1), b"abc", &mut buf),
            Err(SdlsError::CounterExhausted)
        );
    }
}
