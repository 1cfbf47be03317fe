//! MMIC-I robot domain (no_std, no heap, no I/O).
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
