//! AES-256-GCM (NIST SP 800-38D, 96-bit IV, 128-bit tag) in steps, from RustCrypto's
//! primitives (`aes`, `ctr` 32-bit big-endian counter, `ghash`, `subtle`): the same cipher
//! `aes-gcm` composes from them, cut so that one frame's work can be spread over control
//! periods. A [`Job`] holds the GHASH state and how far it got; each [`Job::step`] does at
//! most a given number of **work blocks** (one 16-byte block through AES or through GHASH
//! counts one), so the caller bounds the work per period.
//!
//! Decryption verifies before it decrypts: a first pass hashes the ciphertext and compares
//! the tag (constant time), only then does a second pass decrypt. A forged frame costs one
//! GHASH pass and never yields plaintext. Encryption runs CTR and GHASH block by block.
//! Run to completion ([`Gcm::encrypt`], [`Gcm::decrypt`]) it is what the host uses; the
//! tests check every result against `aes-gcm`.

use aes::cipher::{BlockEncrypt, InnerIvInit, KeyInit, StreamCipherCore};
use aes::Aes256;
use ghash::universal_hash::UniversalHash;
use ghash::GHash;
use subtle::ConstantTimeEq;

/// GCM's block (the AES block and the GHASH block).
pub const BLOCK: usize = 16;
/// The nonce (the SDLS IV).
pub type Nonce = [u8; 12];
/// The authentication tag.
pub type Tag = [u8; 16];

/// An AES-256-GCM key: the AES key schedule and the GHASH key H = E(K, 0).
#[derive(Clone)]
pub struct Gcm {
    aes: Aes256,
    ghash: GHash,
}

/// The tag did not match: the data is not authentic (and was not decrypted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BadTag;

/// Where a [`Job`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pass {
    /// CTR and GHASH, block by block (encryption).
    Encrypt,
    /// GHASH over the ciphertext, then the tag check (decryption, first pass).
    Verify,
    /// CTR over the verified ciphertext (decryption, second pass).
    Decrypt,
    Done,
}

/// What a [`Job::step`] achieved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// More steps needed.
    Pending,
    /// Encrypted in place; the tag.
    Sealed(Tag),
    /// Verified and decrypted in place.
    Opened,
    /// The tag did not match; the buffer is still the ciphertext.
    Refused,
}

/// One encryption or decryption of `len` bytes, in steps over the same buffer.
#[derive(Clone)]
pub struct Job {
    nonce: Nonce,
    ghash: GHash,
    aad_len: usize,
    len: usize,
    /// Bytes of the current pass done (a multiple of [`BLOCK`] until the pass ends).
    done: usize,
    pass: Pass,
    /// The tag a decryption must match.
    expected: Tag,
}

impl core::fmt::Debug for Job {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // Never the GHASH state.
        f.debug_struct("Job")
            .field("len", &self.len)
            .field("done", &self.done)
            .field("pass", &self.pass)
            .finish()
    }
}

impl Gcm {
    pub fn new(key: &[u8; 32]) -> Gcm {
        let aes = Aes256::new(key.into());
        let mut h = ghash::Block::default();
        aes.encrypt_block(&mut h);
        Gcm {
            aes,
            ghash: GHash::new(&h),
        }
    }

    /// An encryption of `len` bytes under `nonce`, authenticating `aad` (hashed now).
    pub fn begin_encrypt(&self, nonce: &Nonce, aad: &[u8], len: usize) -> Job {
        self.begin(nonce, aad, len, Pass::Encrypt, [0; 16])
    }

    /// A decryption of `len` bytes under `nonce` that must match `tag`.
    pub fn begin_decrypt(&self, nonce: &Nonce, aad: &[u8], len: usize, tag: &Tag) -> Job {
        self.begin(nonce, aad, len, Pass::Verify, *tag)
    }

    fn begin(&self, nonce: &Nonce, aad: &[u8], len: usize, pass: Pass, expected: Tag) -> Job {
        let mut ghash = self.ghash.clone();
        ghash.update_padded(aad);
        Job {
            nonce: *nonce,
            ghash,
            aad_len: aad.len(),
            len,
            done: 0,
            pass,
            expected,
        }
    }

    /// Encrypts `buf` in place at once; the tag.
    pub fn encrypt(&self, nonce: &Nonce, aad: &[u8], buf: &mut [u8]) -> Tag {
        let mut job = self.begin_encrypt(nonce, aad, buf.len());
        loop {
            if let Progress::Sealed(t) = job.step(self, buf, usize::MAX) {
                return t;
            }
        }
    }

    /// Verifies and decrypts `buf` in place at once (left unchanged when not authentic).
    pub fn decrypt(&self, nonce: &Nonce, aad: &[u8], buf: &mut [u8], tag: &Tag) -> Result<(), BadTag> {
        let mut job = self.begin_decrypt(nonce, aad, buf.len(), tag);
        loop {
            match job.step(self, buf, usize::MAX) {
                Progress::Pending => {}
                Progress::Opened => return Ok(()),
                Progress::Refused | Progress::Sealed(_) => return Err(BadTag),
            }
        }
    }

    /// XORs the key stream of blocks `first..` into `data` (the data's counter blocks start
    /// at J0 + 1, and J0 = nonce ‖ 1).
    fn ctr(&self, nonce: &Nonce, first: usize, data: &mut [u8]) {
        let mut block = ghash::Block::default();
        block[..12].copy_from_slice(nonce);
        // The 32-bit counter wraps as GCM's inc32 does (a frame is far below 2^32 blocks).
        block[12..].copy_from_slice(&(first as u32).wrapping_add(2).to_be_bytes());
        ctr::CtrCore::<&Aes256, ctr::flavors::Ctr32BE>::inner_iv_init(&self.aes, &block)
            .apply_keystream_partial(data.into());
    }

    /// E(K, J0): the tag's mask.
    fn tag_mask(&self, nonce: &Nonce) -> ghash::Block {
        let mut j0 = ghash::Block::default();
        j0[..12].copy_from_slice(nonce);
        j0[15] = 1;
        self.aes.encrypt_block(&mut j0);
        j0
    }
}

impl Job {
    /// Advances the job over `buf` (the same `len` bytes at every step) by at most `work`
    /// work blocks (at least one block of progress per call when `work` is 0). A
    /// decryption whose MAC verified goes on decrypting with the work left.
    pub fn step(&mut self, gcm: &Gcm, buf: &mut [u8], work: usize) -> Progress {
        if buf.len() != self.len {
            // A wrong buffer never yields a tag or plaintext.
            self.pass = Pass::Done;
            return Progress::Refused;
        }
        let mut left = work;
        let mut first = true;
        loop {
            let per_block = match self.pass {
                Pass::Encrypt => 2,
                Pass::Verify | Pass::Decrypt => 1,
                Pass::Done => return Progress::Refused,
            };
            let mut blocks = left / per_block;
            if first {
                blocks = blocks.max(1);
                first = false;
            }
            if blocks == 0 && self.len > 0 {
                return Progress::Pending;
            }
            let end = self.done.saturating_add(blocks.saturating_mul(BLOCK)).min(self.len);
            let chunk = &mut buf[self.done..end];
            let index = self.done / BLOCK;
            match self.pass {
                Pass::Encrypt => {
                    gcm.ctr(&self.nonce, index, chunk);
                    self.ghash.update_padded(chunk);
                }
                Pass::Verify => self.ghash.update_padded(chunk),
                Pass::Decrypt => gcm.ctr(&self.nonce, index, chunk),
                Pass::Done => {}
            }
            left = left.saturating_sub(chunk.len().div_ceil(BLOCK) * per_block);
            self.done = end;
            if end < self.len {
                return Progress::Pending;
            }
            match self.pass {
                Pass::Encrypt => {
                    self.pass = Pass::Done;
                    return Progress::Sealed(self.tag(gcm));
                }
                Pass::Verify => {
                    let tag = self.tag(gcm);
                    if !bool::from(tag.ct_eq(&self.expected)) {
                        self.pass = Pass::Done;
                        return Progress::Refused;
                    }
                    self.done = 0;
                    if self.len == 0 {
                        self.pass = Pass::Done;
                        return Progress::Opened;
                    }
                    self.pass = Pass::Decrypt;
                }
                Pass::Decrypt => {
                    self.pass = Pass::Done;
                    return Progress::Opened;
                }
                Pass::Done => return Progress::Refused,
            }
        }
    }

    /// GHASH's lengths block, the final GHASH and the mask.
    fn tag(&mut self, gcm: &Gcm) -> Tag {
        let mut block = ghash::Block::default();
        block[..8].copy_from_slice(&((self.aad_len as u64) * 8).to_be_bytes());
        block[8..].copy_from_slice(&((self.len as u64) * 8).to_be_bytes());
        self.ghash.update(&[block]);
        let mut tag = self.ghash.clone().finalize();
        for (t, m) in tag.iter_mut().zip(gcm.tag_mask(&self.nonce)) {
            *t ^= m;
        }
        tag.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aes_gcm::aead::AeadInPlace;
    use aes_gcm::Aes256Gcm;
    use proptest::prelude::*;

    fn reference(key: &[u8; 32], nonce: &Nonce, aad: &[u8], pt: &[u8]) -> (Vec<u8>, Tag) {
        let mut buf = pt.to_vec();
        let tag = Aes256Gcm::new(key.into())
            .encrypt_in_place_detached(nonce.into(), aad, &mut buf)
            .unwrap();
        (buf, tag.into())
    }

    /// Runs `job` in steps of `work` until it ends; the number of steps.
    fn run(gcm: &Gcm, job: &mut Job, buf: &mut [u8], work: usize) -> (Progress, usize) {
        let mut steps = 0;
        loop {
            steps += 1;
            let p = job.step(gcm, buf, work);
            if p != Progress::Pending {
                return (p, steps);
            }
        }
    }

    proptest! {
        // verifies: LINK-SDLS-06
        #[test]
        fn stepwise_gcm_equals_aes_gcm_for_any_step_size(
            key in any::<[u8; 32]>(),
            nonce in any::<[u8; 12]>(),
            aad in proptest::collection::vec(any::<u8>(), 0..40),
            pt in proptest::collection::vec(any::<u8>(), 0..1100),
            work in 0usize..200,
            flip in any::<usize>(),
        ) {
            let gcm = Gcm::new(&key);
            let (ct, tag) = reference(&key, &nonce, &aad, &pt);
            let mut buf = pt.clone();
            let mut job = gcm.begin_encrypt(&nonce, &aad, buf.len());
            let (p, steps) = run(&gcm, &mut job, &mut buf, work);
            prop_assert_eq!(p, Progress::Sealed(tag));
            prop_assert_eq!(&buf, &ct);
            // Each step did at most `work` blocks of work (at least one block).
            let blocks = pt.len().div_ceil(BLOCK);
            prop_assert!(steps <= blocks.max(1).div_ceil((work / 2).max(1)).max(1));
            // Decryption in steps: the plaintext back.
            let mut job = gcm.begin_decrypt(&nonce, &aad, buf.len(), &tag);
            prop_assert_eq!(run(&gcm, &mut job, &mut buf, work).0, Progress::Opened);
            prop_assert_eq!(&buf, &pt);
            // A flipped bit anywhere (ciphertext or tag): refused, the buffer untouched.
            let mut bad = ct.clone();
            let mut bad_tag = tag;
            let bit = flip % ((bad.len() + 16) * 8);
            if bit / 8 < bad.len() { bad[bit / 8] ^= 1 << (bit % 8) } else { bad_tag[bit / 8 - bad.len()] ^= 1 << (bit % 8) }
            let mut job = gcm.begin_decrypt(&nonce, &aad, bad.len(), &bad_tag);
            let before = bad.clone();
            prop_assert_eq!(run(&gcm, &mut job, &mut bad, work).0, Progress::Refused);
            prop_assert_eq!(bad, before);
        }
    }

    // verifies: LINK-SDLS-06
    #[test]
    fn one_shot_gcm_is_mcgrew_viega_test_case_16() {
        let h = |s: &str| hex::decode(s).unwrap();
        let key: [u8; 32] = h("feffe9928665731c6d6a8f9467308308feffe9928665731c6d6a8f9467308308")
            .try_into()
            .unwrap();
        let nonce: Nonce = h("cafebabefacedbaddecaf888").try_into().unwrap();
        let aad = h("feedfacedeadbeeffeedfacedeadbeefabaddad2");
        let mut buf = h("d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a721c3c0c95956809532fcf0e2449a6b525b16aedf5aa0de657ba637b39");
        let tag = Gcm::new(&key).encrypt(&nonce, &aad, &mut buf);
        assert_eq!(tag.to_vec(), h("76fc6ece0f4e1768cddf8853bb2d551b"));
        assert_eq!(
            buf,
            h("522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa8cb08e48590dbb3da7b08b1056828838c5f61e6393ba7a0abcc9f662")
        );
        assert_eq!(Gcm::new(&key).decrypt(&nonce, &aad, &mut buf, &tag), Ok(()));
        let mut wrong = tag;
        wrong[15] ^= 0x80;
        assert_eq!(Gcm::new(&key).decrypt(&nonce, &aad, &mut buf, &wrong), Err(BadTag));
    }
}
