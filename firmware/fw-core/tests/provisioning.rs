//! The provisioning step (`tools/provision-keys.sh`, Python's zlib CRC-32) writes the key
//! record the firmware's `fw_core::link_store::parse_keys` accepts, byte for byte.

use fw_core::link_store::{key_record, parse_keys, KEY_RECORD_LEN};
use fw_core::spacelink::Keys;
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};
use std::path::PathBuf;
use std::process::Command;

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tools/provision-keys.sh")
}

fn key_dir(name: &str, tc: &[u8; 32], tm: &[u8; 32]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fw-provision-{}-{name}", std::process::id()));
    let robot = dir.join("robot-3");
    std::fs::create_dir_all(&robot).unwrap();
    std::fs::write(robot.join("tc-spi1.key"), tc).unwrap();
    std::fs::write(robot.join("tm-spi17.key"), tm).unwrap();
    dir
}

// verifies: FW-LINK-03
#[test]
fn provisioning_script_writes_the_record_the_firmware_reads() {
    let dir = key_dir("ok", &TEST_KEY_TC_A, &TEST_KEY_TM_A);
    let out = dir.join("record.bin");
    let st = Command::new("bash")
        .arg(script())
        .arg(&dir)
        .arg("3")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let stdout = String::from_utf8_lossy(&st.stdout);
    // Never prints a key.
    assert!(!stdout.contains("TEST KEY"), "{stdout}");
    let rec: [u8; KEY_RECORD_LEN] = std::fs::read(&out).unwrap().try_into().unwrap();
    let keys = Keys {
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_spi: 17,
        tm_key: TEST_KEY_TM_A,
    };
    assert_eq!(rec, key_record(&keys));
    assert!(parse_keys(&rec) == Some(keys));
    std::fs::remove_dir_all(&dir).unwrap();
}

// verifies: FW-LINK-03
#[test]
fn provisioning_script_refuses_the_same_key_for_both_directions() {
    let dir = key_dir("same", &TEST_KEY_TC_A, &TEST_KEY_TC_A);
    let st = Command::new("bash")
        .arg(script())
        .arg(&dir)
        .arg("3")
        .arg("--out")
        .arg(dir.join("r.bin"))
        .output()
        .unwrap();
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("same key"));
    std::fs::remove_dir_all(&dir).unwrap();
}
