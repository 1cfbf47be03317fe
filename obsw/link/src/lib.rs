//! MMIC-I space link: CCSDS TC (232.0-B-4) and TM (132.0-B-3) transfer frames, COP-1
//! (232.1-B-2) and SDLS (355.0-B-2). `no_std`, no heap, time passed in.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
