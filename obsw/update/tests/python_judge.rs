//! Outside judges of the update formats, code nobody here wrote:
//! - Python `cryptography` (OpenSSL's Ed25519) writes an image from the layout of
//!   `mib::update` and signs it; our verifier must accept it, and refuse it with one byte
//!   flipped.
//! - Python's `zlib.crc32`, whose `value` argument is inverted on entry as ESP-IDF's ROM
//!   `esp_rom_crc32_le` does, computes the otadata CRCs our records carry.
//!
//! Needs the project's Python environment (`scripts/python-env.sh`, `.venv`).

use std::path::PathBuf;
use std::process::Command;

use mib::update::{target, HEADER_LEN};
use mmic_update::flash::RamNor;
use mmic_update::image::{install, Refusal, UpdateKey};
use mmic_update::otadata;

fn python() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = root.join(".venv/bin/python");
    assert!(py.exists(), "{} missing: run scripts/python-env.sh", py.display());
    py
}

const SIGNER: &str = r#"
import hashlib, struct, sys
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.hazmat.primitives import serialization
key = Ed25519PrivateKey.generate()
payload = bytes((i * 7 + 3) & 0xFF for i in range(5000))
signed = b"MMICIMG1" + struct.pack(">IIB3x", 0x020001, len(payload), int(sys.argv[1])) + hashlib.sha256(payload).digest()
assert len(signed) == 52
image = signed + key.sign(signed) + payload
pub = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
sys.stdout.write(pub.hex() + "\n" + image.hex() + "\n")
"#;

// verifies: UPD-IMG-03
#[test]
fn an_image_signed_by_python_cryptography_is_accepted_and_a_flipped_byte_refused() {
    let out = Command::new(python())
        .args(["-c", SIGNER, &target::HOST.to_string()])
        .output()
        .expect("python runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    let hex = |s: &str| -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    };
    let pk: [u8; 32] = hex(lines.next().unwrap()).try_into().unwrap();
    let image = hex(lines.next().unwrap());
    let key = UpdateKey::from_bytes(&pk).expect("a valid public key");

    let mut slot = Box::new(RamNor::<{ 16 * 1024 }>::new());
    let h = install(&mut &image[..], slot.as_mut(), &key, target::HOST).expect("accepted");
    assert_eq!((h.version, h.length), (0x020001, 5000));
    assert_eq!(&slot.bytes[HEADER_LEN..image.len()], &image[HEADER_LEN..]);

    for (at, want) in [
        (HEADER_LEN + 4321, Refusal::Digest),
        (60, Refusal::Signature),
        (9, Refusal::Signature),
    ] {
        let mut bad = image.clone();
        bad[at] ^= 0x80;
        let mut slot = Box::new(RamNor::<{ 16 * 1024 }>::new());
        assert_eq!(
            install(&mut &bad[..], slot.as_mut(), &key, target::HOST),
            Err(want),
            "byte {at} flipped"
        );
    }
}

// verifies: UPD-OTA-01
#[test]
fn otadata_crcs_match_zlib_with_esp_rom_inversion() {
    let seqs = [1u32, 2, 3, 0x1234_5678, u32::MAX - 1];
    let script = format!("import zlib, struct\nfor s in {seqs:?}: print(zlib.crc32(struct.pack('<I', s), 0xFFFFFFFF))");
    let out = Command::new(python())
        .args(["-c", &script])
        .output()
        .expect("python runs");
    assert!(out.status.success());
    let theirs: Vec<u32> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.parse().unwrap())
        .collect();
    let ours: Vec<u32> = seqs.iter().map(|&s| otadata::crc(s)).collect();
    assert_eq!(ours, theirs);
}
