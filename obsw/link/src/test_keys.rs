//! TEST KEYS — published in the repository, so worthless for security. For tests, the
//! simulator and the demo only; flight and operations load keys from files (host) or a
//! provisioning step (firmware). Their names say what they are.

use crate::sdls::Key;

/// Uplink (TC) test key for SPI 1.
pub const TEST_KEY_TC_A: Key = *b"MMIC-I TEST KEY tc spi 1 NOT SEC";
/// Uplink (TC) test key for SPI 2 (the second key for key change).
pub const TEST_KEY_TC_B: Key = *b"MMIC-I TEST KEY tc spi 2 NOT SEC";
/// Downlink (TM) test key for SPI 17.
pub const TEST_KEY_TM_A: Key = *b"MMIC-I TEST KEY tm spi17 NOT SEC";
/// Downlink (TM) test key for SPI 18.
pub const TEST_KEY_TM_B: Key = *b"MMIC-I TEST KEY tm spi18 NOT SEC";
