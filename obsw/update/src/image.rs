//! The signed image (layout in `mib::update`): a header with the software version, the
//! payload length, the target, the SHA-256 of the payload and an Ed25519 signature of all
//! that by the ground's update key, then the payload.
//!
//! [`install`] copies an image from any byte source (the file store) into a slot and
//! verifies what the slot then holds; [`verify_slot`] checks a slot again (before an
//! activation). The signature is checked before the slot is erased: an image that is not
//! the ground's never touches the flash.

use ed25519_dalek::{Signature, VerifyingKey};
use mib::update::{field, DIGEST_LEN, HEADER_LEN, MAGIC, PUBLIC_KEY_LEN, SIGNATURE_LEN, SIGNED_LEN};
use sha2::{Digest, Sha256};

use crate::flash::Flash;

/// An image header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// 0x00MMmmpp (`mib::update::version`).
    pub version: u32,
    /// Payload bytes after the header.
    pub length: u32,
    pub target: u8,
    pub digest: [u8; DIGEST_LEN],
    pub signature: [u8; SIGNATURE_LEN],
}

/// Why an image is refused; the codes are `mib::update::refusal`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    NoFile,
    Truncated { header_says: u32, file_has: u32 },
    NotAnImage,
    WrongTarget(u8),
    TooLarge { length: u32, slot: u32 },
    Digest,
    Signature,
    Flash,
    NoKey,
}

impl Refusal {
    /// The MIB's reason code.
    pub const fn code(self) -> u8 {
        use mib::update::refusal as r;
        match self {
            Refusal::NoFile => r::NO_FILE,
            Refusal::Truncated { .. } => r::TRUNCATED,
            Refusal::NotAnImage => r::NOT_AN_IMAGE,
            Refusal::WrongTarget(_) => r::WRONG_TARGET,
            Refusal::TooLarge { .. } => r::TOO_LARGE,
            Refusal::Digest => r::DIGEST,
            Refusal::Signature => r::SIGNATURE,
            Refusal::Flash => r::FLASH,
            Refusal::NoKey => r::NO_KEY,
        }
    }
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Refusal::NoFile => f.write_str("no such file in the store"),
            Refusal::Truncated { header_says, file_has } => {
                write!(
                    f,
                    "truncated: the header says {header_says} bytes, the file has {file_has}"
                )
            }
            Refusal::NotAnImage => f.write_str("not a signed image (magic or reserved bytes)"),
            Refusal::WrongTarget(t) => write!(f, "an image for target {t}"),
            Refusal::TooLarge { length, slot } => write!(f, "{length} bytes do not fit the {slot}-byte slot"),
            Refusal::Digest => f.write_str("the payload's SHA-256 is not the header's"),
            Refusal::Signature => f.write_str("the signature is not the ground update key's"),
            Refusal::Flash => f.write_str("the slot could not be written or read"),
            Refusal::NoKey => f.write_str("no update key on board"),
        }
    }
}

impl core::error::Error for Refusal {}

impl Header {
    /// Parses a header; only the magic and the reserved bytes are checked here.
    pub fn parse(b: &[u8; HEADER_LEN]) -> Result<Self, Refusal> {
        if b[..MAGIC.len()] != MAGIC || b[field::RESERVED..field::DIGEST] != [0, 0, 0] {
            return Err(Refusal::NotAnImage);
        }
        let u = |o: usize| u32::from_be_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let mut digest = [0; DIGEST_LEN];
        digest.copy_from_slice(&b[field::DIGEST..field::DIGEST + DIGEST_LEN]);
        let mut signature = [0; SIGNATURE_LEN];
        signature.copy_from_slice(&b[field::SIGNATURE..]);
        Ok(Header {
            version: u(field::VERSION),
            length: u(field::LENGTH),
            target: b[field::TARGET],
            digest,
            signature,
        })
    }

    /// The bytes the signature covers.
    pub fn signed_bytes(&self) -> [u8; SIGNED_LEN] {
        let mut b = [0; SIGNED_LEN];
        b[..MAGIC.len()].copy_from_slice(&MAGIC);
        b[field::VERSION..field::LENGTH].copy_from_slice(&self.version.to_be_bytes());
        b[field::LENGTH..field::TARGET].copy_from_slice(&self.length.to_be_bytes());
        b[field::TARGET] = self.target;
        b[field::DIGEST..].copy_from_slice(&self.digest);
        b
    }

    pub fn emit(&self) -> [u8; HEADER_LEN] {
        let mut b = [0; HEADER_LEN];
        b[..SIGNED_LEN].copy_from_slice(&self.signed_bytes());
        b[field::SIGNATURE..].copy_from_slice(&self.signature);
        b
    }

    /// Checks the signature against the update key.
    pub fn check_signature(&self, key: &UpdateKey) -> Result<(), Refusal> {
        let sig = Signature::from_bytes(&self.signature);
        key.0
            .verify_strict(&self.signed_bytes(), &sig)
            .map_err(|_| Refusal::Signature)
    }
}

/// The ground's update public key (Ed25519).
#[derive(Clone, Copy, Debug)]
pub struct UpdateKey(VerifyingKey);

impl UpdateKey {
    /// `None` for bytes that are not a valid Ed25519 public key.
    pub fn from_bytes(b: &[u8; PUBLIC_KEY_LEN]) -> Option<Self> {
        VerifyingKey::from_bytes(b).ok().filter(|k| !k.is_weak()).map(UpdateKey)
    }
}

/// A source could not be read (the file went away, an I/O error).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadError;

/// Where an image is read from (the file store's file).
pub trait Source {
    fn len(&self) -> u32;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), ReadError>;
}

impl Source for &[u8] {
    fn len(&self) -> u32 {
        <[u8]>::len(self).try_into().unwrap_or(u32::MAX)
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), ReadError> {
        let s = self
            .get(offset as usize..)
            .and_then(|s| s.get(..buf.len()))
            .ok_or(ReadError)?;
        buf.copy_from_slice(s);
        Ok(())
    }
}

/// Bytes copied per step.
const CHUNK: usize = 256;

/// Reads and checks the header of `src`: format, target, length against the source and the
/// slot, signature. Nothing is written.
pub fn check_header(src: &mut dyn Source, key: &UpdateKey, target: u8, slot_bytes: u32) -> Result<Header, Refusal> {
    let have = src.len();
    if (have as usize) < HEADER_LEN {
        return Err(Refusal::Truncated {
            header_says: 0,
            file_has: have,
        });
    }
    let mut hb = [0; HEADER_LEN];
    src.read(0, &mut hb).map_err(|_| Refusal::NoFile)?;
    let h = Header::parse(&hb)?;
    if h.target != target {
        return Err(Refusal::WrongTarget(h.target));
    }
    let total = u64::from(h.length) + HEADER_LEN as u64;
    if total != u64::from(have) {
        return Err(Refusal::Truncated {
            header_says: h.length,
            file_has: have.saturating_sub(HEADER_LEN as u32),
        });
    }
    if total > u64::from(slot_bytes) {
        return Err(Refusal::TooLarge {
            length: h.length,
            slot: slot_bytes,
        });
    }
    h.check_signature(key)?;
    Ok(h)
}

/// Copies the image of `src` into `slot` (erasing what it needs first) and verifies what
/// the slot holds: header, signature and the SHA-256 of the payload read back.
pub fn install(src: &mut dyn Source, slot: &mut dyn Flash, key: &UpdateKey, target: u8) -> Result<Header, Refusal> {
    let h = check_header(src, key, target, slot.capacity())?;
    let total = HEADER_LEN as u32 + h.length;
    let es = slot.erase_size().max(1);
    let erase_to = total.div_ceil(es).saturating_mul(es).min(slot.capacity());
    slot.erase(0, erase_to).map_err(|_| Refusal::Flash)?;
    let ws = slot.write_size().max(1) as usize;
    let mut buf = [0u8; CHUNK];
    let mut at = 0u32;
    while at < total {
        let n = (total - at).min(CHUNK as u32) as usize;
        src.read(at, &mut buf[..n]).map_err(|_| Refusal::NoFile)?;
        // The last write is padded to the write unit with erased bytes.
        let padded = n.div_ceil(ws) * ws;
        buf[n..padded].fill(0xFF);
        slot.write(at, &buf[..padded]).map_err(|_| Refusal::Flash)?;
        at += n as u32;
    }
    verify_slot(slot, key, target)
}

/// Verifies the image a slot holds: its header, signature and payload digest.
pub fn verify_slot(slot: &mut dyn Flash, key: &UpdateKey, target: u8) -> Result<Header, Refusal> {
    let mut hb = [0; HEADER_LEN];
    slot.read(0, &mut hb).map_err(|_| Refusal::Flash)?;
    let h = Header::parse(&hb)?;
    if h.target != target {
        return Err(Refusal::WrongTarget(h.target));
    }
    let total = u64::from(h.length) + HEADER_LEN as u64;
    if total > u64::from(slot.capacity()) {
        return Err(Refusal::TooLarge {
            length: h.length,
            slot: slot.capacity(),
        });
    }
    h.check_signature(key)?;
    let mut sha = Sha256::new();
    let mut buf = [0u8; CHUNK];
    let mut at = HEADER_LEN as u32;
    let end = total as u32;
    while at < end {
        let n = (end - at).min(CHUNK as u32) as usize;
        slot.read(at, &mut buf[..n]).map_err(|_| Refusal::Flash)?;
        sha.update(&buf[..n]);
        at += n as u32;
    }
    if sha.finalize().as_slice() != h.digest {
        return Err(Refusal::Digest);
    }
    Ok(h)
}

/// Activates slot `n` (`otadata::activate`) only when it holds, verified now (header,
/// signature, digest), the image named by `digest`: what boots is what was verified. A
/// refusal leaves the otadata as it was.
pub fn activate_verified(
    otadata: &mut dyn Flash,
    slot: &mut dyn Flash,
    n: u8,
    key: &UpdateKey,
    target: u8,
    digest: &[u8; DIGEST_LEN],
) -> Result<Header, Refusal> {
    let h = verify_slot(slot, key, target)?;
    if h.digest != *digest {
        return Err(Refusal::Digest);
    }
    crate::otadata::activate(otadata, n).map_err(|_| Refusal::Flash)?;
    Ok(h)
}

/// Signs `payload` as an image (the ground's signer, and tests): the header with its
/// signature by `secret` (an Ed25519 secret key, RFC 8032's 32-byte seed).
pub fn sign(secret: &[u8; 32], version: u32, target: u8, payload: &[u8]) -> Option<[u8; HEADER_LEN]> {
    use ed25519_dalek::Signer;
    let key = ed25519_dalek::SigningKey::from_bytes(secret);
    let mut h = Header {
        version,
        length: u32::try_from(payload.len()).ok()?,
        target,
        digest: Sha256::digest(payload).into(),
        signature: [0; SIGNATURE_LEN],
    };
    h.signature = key.sign(&h.signed_bytes()).to_bytes();
    Some(h.emit())
}

/// The public key of an Ed25519 secret key.
pub fn public_key(secret: &[u8; 32]) -> [u8; PUBLIC_KEY_LEN] {
    ed25519_dalek::SigningKey::from_bytes(secret).verifying_key().to_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flash::RamNor;
    use mib::update::target;

    const SECRET: [u8; 32] = [7; 32];

    fn image(payload: &[u8]) -> ([u8; 8192], usize) {
        let h = sign(&SECRET, 0x010203, target::BOARD_A, payload).unwrap();
        let mut b = [0u8; 8192];
        b[..HEADER_LEN].copy_from_slice(&h);
        b[HEADER_LEN..HEADER_LEN + payload.len()].copy_from_slice(payload);
        (b, HEADER_LEN + payload.len())
    }

    fn key() -> UpdateKey {
        UpdateKey::from_bytes(&public_key(&SECRET)).unwrap()
    }

    // verifies: UPD-IMG-01
    #[test]
    fn a_signed_image_installs_and_verifies_in_its_slot() {
        let payload: [u8; 1000] = core::array::from_fn(|i| i as u8);
        let (b, n) = image(&payload);
        let mut slot = RamNor::<16384>::new();
        let h = install(&mut &b[..n], &mut slot, &key(), target::BOARD_A).unwrap();
        assert_eq!((h.version, h.length), (0x010203, 1000));
        assert_eq!(&slot.bytes[HEADER_LEN..n], &payload[..]);
        assert_eq!(verify_slot(&mut slot, &key(), target::BOARD_A), Ok(h));
    }

    // verifies: UPD-IMG-02
    #[test]
    fn any_changed_byte_truncation_or_wrong_key_is_refused() {
        let payload = [0x5Au8; 300];
        let (b, n) = image(&payload);
        for i in 0..n {
            let mut bad = b;
            bad[i] ^= 0x01;
            let mut slot = RamNor::<8192>::new();
            let r = install(&mut &bad[..n], &mut slot, &key(), target::BOARD_A);
            assert!(r.is_err(), "byte {i} flipped was accepted");
            if i >= HEADER_LEN {
                assert_eq!(r, Err(Refusal::Digest), "payload byte {i}");
            }
        }
        let mut slot = RamNor::<8192>::new();
        assert!(matches!(
            install(&mut &b[..n - 1], &mut slot, &key(), target::BOARD_A),
            Err(Refusal::Truncated { .. })
        ));
        assert!(matches!(
            install(&mut &b[..10], &mut slot, &key(), target::BOARD_A),
            Err(Refusal::Truncated { .. })
        ));
        assert_eq!(
            install(&mut &b[..n], &mut slot, &key(), target::HOST),
            Err(Refusal::WrongTarget(2))
        );
        let other = UpdateKey::from_bytes(&public_key(&[9; 32])).unwrap();
        assert_eq!(
            install(&mut &b[..n], &mut slot, &other, target::BOARD_A),
            Err(Refusal::Signature)
        );
        // A refused signature never erased the slot.
        assert!(slot.bytes.iter().all(|&x| x == 0xFF));
        let mut small = RamNor::<4096>::new();
        let (big, bn) = image(&[1u8; 3990]);
        assert!(matches!(
            install(&mut &big[..bn], &mut small, &key(), target::BOARD_A),
            Err(Refusal::TooLarge { .. })
        ));
    }

    // verifies: UPD-SVC-01
    #[test]
    fn only_the_verified_image_named_is_activated() {
        use crate::otadata;
        let (b, n) = image(&[4u8; 700]);
        let mut slot = RamNor::<8192>::new();
        let mut ota = RamNor::<8192>::new();
        let h = install(&mut &b[..n], &mut slot, &key(), target::BOARD_A).unwrap();
        let other = [0u8; DIGEST_LEN];
        let k = key();
        let a = target::BOARD_A;
        assert_eq!(
            activate_verified(&mut ota, &mut slot, 1, &k, a, &other),
            Err(Refusal::Digest)
        );
        assert!(ota.bytes.iter().all(|&x| x == 0xFF), "a refusal writes no otadata");
        let mut erased = RamNor::<8192>::new();
        assert_eq!(
            activate_verified(&mut ota, &mut erased, 1, &k, a, &h.digest),
            Err(Refusal::NotAnImage)
        );
        let mut changed = slot.clone();
        changed.bytes[HEADER_LEN + 1] = 0;
        assert_eq!(
            activate_verified(&mut ota, &mut changed, 1, &k, a, &h.digest),
            Err(Refusal::Digest)
        );
        assert!(ota.bytes.iter().all(|&x| x == 0xFF));
        assert_eq!(activate_verified(&mut ota, &mut slot, 1, &k, a, &h.digest), Ok(h));
        assert_eq!(otadata::boot(&mut ota).unwrap().slot, 1);
    }

    // verifies: UPD-IMG-02
    #[test]
    fn a_slot_changed_after_install_fails_verification() {
        let (b, n) = image(&[3u8; 500]);
        let mut slot = RamNor::<8192>::new();
        install(&mut &b[..n], &mut slot, &key(), target::BOARD_A).unwrap();
        slot.bytes[HEADER_LEN + 10] &= 0xF0;
        assert_eq!(verify_slot(&mut slot, &key(), target::BOARD_A), Err(Refusal::Digest));
    }
}
