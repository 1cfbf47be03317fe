//! Frame error control field: CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection,
//! no final XOR), the code 232.0-B-4 §4.1.4.2 and 132.0-B-3 §4.1.6 specify — the project's
//! one CRC-16, `mib::headers::PEC_CRC` (the `crc` crate's `CRC_16_IBM_3740`).

use crc::Crc;
use mib::headers::PEC_CRC;

/// Firmware: the one CRC itself, byte-wise table (512 bytes of flash).
#[cfg(not(feature = "std"))]
const CRC16: Crc<u16> = PEC_CRC;
/// Host (`std`): the same algorithm with slice-by-16 tables (8 KiB), several times faster
/// over a 1024-byte frame.
#[cfg(feature = "std")]
const CRC16: Crc<u16, crc::Table<16>> = Crc::<u16, crc::Table<16>>::new(PEC_CRC.algorithm);

/// The FECF over `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

/// Whether the last two bytes of `frame` are the CRC of the rest. False when shorter than 2.
pub fn check(frame: &[u8]) -> bool {
    let Some(split) = frame.len().checked_sub(2) else {
        return false;
    };
    let (body, fecf) = frame.split_at(split);
    crc16(body) == u16::from_be_bytes([fecf[0], fecf[1]])
}

/// Writes the CRC of all but the last two bytes into the last two bytes. No-op when shorter.
pub fn seal(frame: &mut [u8]) {
    let Some(split) = frame.len().checked_sub(2) else {
        return;
    };
    let c = crc16(&frame[..split]);
    frame[split..].copy_from_slice(&c.to_be_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: LINK-FRAME-03
    #[test]
    fn crc16_ccitt_false_check_value() {
        // The catalogue check value of CRC-16/CCITT-FALSE over "123456789".
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    // verifies: LINK-FRAME-03
    #[test]
    fn cryptolib_frame_crc_is_78cb_not_b401() {
        // NASA CryptoLib v1.3.1 et_dt_validation.c, NIST_DEC_MAC_VALIDATION TEST_0: the frame
        // ends in B401, but the CRC of the preceding 54 bytes is 0x78CB.
        let f = hex::decode(
            "2003003700FF0009D79CF22D504CC793C3FB6C8A0000722ee47da4b77424733546c2d400c4e5\
             E7BB31D506998FCBDA078E66D5680194B401",
        )
        .unwrap();
        assert!(!check(&f));
        assert_eq!(crc16(&f[..f.len() - 2]), 0x78CB);
        let mut g = f.clone();
        seal(&mut g);
        assert!(check(&g));
        assert_eq!(&g[g.len() - 2..], &[0x78, 0xCB]);
        assert!(!check(&[0x12]));
    }
}
