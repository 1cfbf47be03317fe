//! MMIC-I on-board software core.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
